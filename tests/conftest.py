"""Test configuration: hypothesis profiles.

"ci" (default) draws 200 examples per property from a fixed seed, so a CI run is reproducible; "explore"
draws 1000 fresh random examples (HYPOTHESIS_PROFILE=explore) and "dev" 30 (quick runs).
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
