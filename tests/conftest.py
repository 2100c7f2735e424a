"""Test configuration: hypothesis profiles and the ``slow`` marker.

"ci" (default) draws 200 examples per property from a fixed seed, so a CI run is reproducible; "explore"
draws 1000 fresh random examples (HYPOTHESIS_PROFILE=explore) and "dev" 30 (quick runs).

``slow``: the executed notebooks (``--nbmake``), the modules of :data:`SLOW_MODULES` and every test marked
``@pytest.mark.slow``; a contributor's quick run leaves them out: ``python -m pytest -m "not slow"``
(README, "Run the tests"). CI runs everything.
"""

import os
import sys
from pathlib import Path

from hypothesis import HealthCheck, settings

sys.path.insert(0, str(Path(__file__).parent))  # make tests/strategies.py importable

settings.register_profile("ci", max_examples=200, deadline=None, derandomize=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("explore", max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("dev", max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


#: Test modules (paths under tests/) whose tests are ``slow`` as a whole: measured as the longest in a full run
#: on 2 cores (``python -m pytest --durations=40``).
SLOW_MODULES = (
    "test_fuzz.py",
)


def pytest_collection_modifyitems(config, items):
    import pytest

    tests = Path(__file__).parent
    for item in items:
        path = Path(str(item.fspath))
        if path.suffix == ".ipynb":
            item.add_marker(pytest.mark.slow)
            continue
        try:
            relative = path.relative_to(tests).as_posix()
        except ValueError:
            continue
        if relative in SLOW_MODULES:
            item.add_marker(pytest.mark.slow)
