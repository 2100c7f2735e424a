"""Unreachable views against the brute force of bruteforce.py (issue 31): the search misses no valid
configuration between its samples.

The oracle does not use the views' search: the pose IK over a fine (distance, roll) grid and a local
maximisation of the exact clearance. Its own test: it finds the reachable views feasible (it can fail).
The long run is ``python benchmarks/bruteforce_views.py`` (numbers in docs/views.md).
"""

import bruteforce
import numpy as np
import pytest

import carmkin
from carmkin.patient import ParametricPatient
from carmkin.robot.validity import check
from carmkin.views import View, plan_view, polish, reach_map
from carmkin.views.plan import world_for

MARGIN = carmkin.DEFAULT_MARGIN
#: Views the 0.5°-sampled search called unreachable although a configuration keeps the margin (found by
#: benchmarks/bruteforce_views.py before the polish): (preset, target (m), primary, secondary (deg)).
MISSED = [
    ("siremobile-iso-c3d", (0.0, 0.0, 0.0), 63.0, -45.0),
    ("siremobile-iso-c3d", (0.0, 0.0, 0.0), 85.0, -40.0),
    ("siremobile-iso-c3d-motorized-table", (0.0, 0.0, 0.0), 85.0, -40.0),
]


def _setup(preset):
    system = carmkin.load_preset(preset)
    patient = ParametricPatient.on_table(system)
    return system, patient, world_for(system, patient)


@pytest.mark.parametrize("preset, target, primary, secondary", MISSED)
def test_the_views_missed_between_samples_are_reachable(preset, target, primary, secondary):
    system, patient, world = _setup(preset)
    window, polish.WINDOW = polish.WINDOW, -1.0
    try:  # the sampled search alone calls it unreachable (the test can fail)
        assert not reach_map(system, target, [primary], [secondary], patient, margin=MARGIN).reachable[0, 0]
    finally:
        polish.WINDOW = window
    m = reach_map(system, target, [primary], [secondary], patient, margin=MARGIN)
    assert m.reachable[0, 0], m.reason[0, 0]
    q = m.q[0, 0]
    report = check(system, q, patient.obstacles(), margin=MARGIN)
    assert report.reachable, str(report)  # joints in range, nothing closer than the margin
    assert m.clearance[0, 0] >= MARGIN
    T = system.fk(q)
    assert np.allclose(T[:3, 2], m.directions[0, 0], atol=1e-9)  # the beam along the view ...
    along = np.asarray(target) - T[:3, 3]
    assert np.linalg.norm(np.cross(along, T[:3, 2])) < 1e-9  # ... through the target
    plan = plan_view(system, View.from_angles(primary, secondary, target, patient), patient, margin=MARGIN)
    assert plan.success and plan.clearance >= MARGIN


def test_the_oracle_finds_reachable_views_feasible():
    """The oracle can say "feasible": on reachable cells (one on the singular family, primary −90°) it finds a
    configuration that keeps the margin, confirmed by validity.check."""
    system, patient, world = _setup("siremobile-iso-c3d")
    m = reach_map(system, np.zeros(3), [-90, -50, 30], [-35, 40], patient, margin=MARGIN)
    assert m.reachable[0, 0] and m.reachable[1, 0]
    for i, j in [(0, 0), (1, 0), (2, 0)]:
        if not m.reachable[i, j]:
            continue
        verdict = bruteforce.brute(system, world, np.zeros(3), m.directions[i, j], MARGIN)
        assert verdict.q is not None, (m.primary_deg[i], m.secondary_deg[j])
        assert check(system, verdict.q, patient.obstacles(), margin=MARGIN).reachable


@pytest.mark.slow
def test_no_unreachable_view_is_feasible_by_brute_force():
    """16 unreachable views of two presets, spread over each map's unreachable cells: none has a configuration
    the oracle finds (8 a preset: 20 took 6 min of the suite on a loaded machine; the long run is
    ``python benchmarks/bruteforce_views.py``)."""
    views = []
    for preset, target, step in (("siremobile-iso-c3d", (0.0, 0.0, 0.0), 5),
                                 ("siremobile-iso-c3d-motorized-table", (0.0, 0.0, 0.0), 10)):
        system, patient, world = _setup(preset)
        m = reach_map(system, target, np.arange(-90, 91, step), np.arange(-45, 46, step), patient, margin=MARGIN)
        cells = list(zip(*np.nonzero(~m.reachable)))
        pick = np.linspace(0, len(cells) - 1, min(8, len(cells))).astype(int)
        views += [(system, world, target, m.directions[cells[k]], (preset, m.primary_deg[cells[k][0]],
                                                                   m.secondary_deg[cells[k][1]])) for k in pick]
    assert len(views) == 16
    feasible = [name for system, world, target, d, name in views
                if bruteforce.brute(system, world, np.asarray(target), d, MARGIN).q is not None]
    assert feasible == []
