"""Test configuration: hypothesis profiles, the ``slow`` marker and CI's rerun of what skipped.

"ci" (default) draws 200 examples per property from a fixed seed, so a CI run is reproducible; "explore"
draws 1000 fresh random examples (HYPOTHESIS_PROFILE=explore) and "dev" 30 (quick runs).

``slow``: the executed notebooks (``--nbmake``), the tests of :data:`SLOW` and every test marked
``@pytest.mark.slow``; a contributor's quick run leaves them out: ``python -m pytest -m "not slow"``
(README, "Run the tests"). CI runs everything.

CI runs the README's command with the test extra alone first, then installs every extra and runs again only what
skipped the first time (``.ci/run``): ``CARMKIN_RECORD_SKIPPED=FILE`` writes the node ids of the tests and
modules that skip to FILE; ``CARMKIN_RUN_ONLY=FILE`` keeps only the tests FILE names (a module's id keeps all
its tests) and deselects the rest.
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


#: Tests (node ids under tests/, or a prefix of them: a whole module) that are ``slow``: every test over 5 s in a
#: full run on 2 shared cores (``python -m pytest --durations=80``, 2026-11-27: 546 s in all, these ~330 s).
SLOW = (
    "views/test_maps.py::",
    "views/test_bruteforce.py::test_no_unreachable_view_is_feasible_by_brute_force",
    "calibration/test_outliers_and_sigma.py::test_reported_sigma_cover_95_percent_with_default_points_on_a_helix_phantom",
    "world/test_swept.py::test_certified_minimum_bounds_dense_samples_from_below",
    "views/test_plan_view.py::test_every_view_of_a_collision_free_configuration_is_planned",
    "test_singularity.py::test_pinocchio_det_equals_eq_4_7",
    "test_singularity.py::test_regular_configurations_have_rank_6",
    "test_singularity.py::test_distance_is_the_joint_move_that_reaches_the_set",
    "model/test_kinematics.py::test_expanded_closed_form_equals_the_dh_product_and_pinocchio",
    "reposition/test_pose_degenerate.py::test_acceptance_degenerate_boards_right_or_refused",
    # issue 37: dense exact checks of planned motions (each 5-60 s)
    "motion/test_certificate.py::",
    "motion/test_motion_plan.py::test_every_family_plans_between_random_clear_configurations",
    "motion/test_motion_plan.py::test_a_blocked_line_is_planned_around_and_certified",
    "motion/test_biplane_motion.py::test_a_standard_pair",
)


def _notebook_hooks():
    """docs/hooks/notebooks.py, which reads what a notebook needs from its metadata (``carmkin.needs``)."""
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "docs" / "hooks" / "notebooks.py"
    spec = importlib.util.spec_from_file_location("docs_hooks_notebooks", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def pytest_collection_modifyitems(config, items):
    import pytest

    if os.environ.get("CARMKIN_RUN_ONLY"):
        _keep_only_listed(config, items)

    tests = Path(__file__).parent
    hooks = None
    for item in items:
        path = Path(str(item.fspath))
        if path.suffix == ".ipynb":  # an executed notebook (--nbmake)
            item.add_marker(pytest.mark.slow)
            hooks = hooks or _notebook_hooks()
            reason = hooks.missing_extra(path)  # a notebook that cannot run without an extra skips, saying why
            if reason:
                item.add_marker(pytest.mark.skip(reason=f"{path.name} {reason}"))
            continue
        try:
            node = path.relative_to(tests).as_posix() + "::" + item.nodeid.partition("::")[2]
        except ValueError:
            continue
        if node.startswith(SLOW):
            item.add_marker(pytest.mark.slow)


# --- CI's second run: only what skipped in the first ---------------------------------------------------------
_skipped: list[str] = []


def _record_skip(report) -> None:
    if os.environ.get("CARMKIN_RECORD_SKIPPED") and report.skipped and not hasattr(report, "wasxfail"):
        _skipped.append(report.nodeid)


def pytest_collectreport(report):
    _record_skip(report)  # a module that skips as a whole (a module-level importorskip)


def pytest_runtest_logreport(report):
    _record_skip(report)


def pytest_sessionfinish(session):
    target = os.environ.get("CARMKIN_RECORD_SKIPPED")
    if target:
        Path(target).write_text("".join(f"{node}\n" for node in dict.fromkeys(_skipped)))


def _keep_only_listed(config, items) -> None:
    listed = Path(os.environ["CARMKIN_RUN_ONLY"]).read_text().split("\n")
    listed = {node for node in listed if node}
    modules = tuple(node + "::" for node in listed)  # a module's id keeps all its tests
    keep = [item.nodeid in listed or item.nodeid.startswith(modules) for item in items]
    config.hook.pytest_deselected(items=[item for item, kept in zip(items, keep) if not kept])
    items[:] = [item for item, kept in zip(items, keep) if kept]
