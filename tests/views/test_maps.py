"""Acceptance of the reachability maps (issue 20): every reachable cell checked by independent routes (FK,
a fresh collision scene), unreachable cells brute-forced, plan_view agreeing cell by cell."""

import math

import numpy as np
import pytest
from view_systems import TARGET

from carmkin import analytic_ik
from carmkin.interop.dicom import pose_from_xa_angles
from carmkin.robot import validity
from carmkin.world import World
from carmkin.views import DEFAULT_MARGIN, View, plan_view

#: Beam residuals (m, rad) of an answer: every answer here comes from a closed form.
AXIS_TOLERANCE = 1e-9
#: Exact clearances agree to this (m): coal's GJK on the same pair.
CLEARANCE_TOLERANCE = 1e-9


def test_every_reachable_cell_is_right(maps):
    checked = 0
    for name, (system, patient, m) in maps.items():
        scene = World(system, patient.obstacles())
        for i, j in zip(*np.nonzero(m.reachable)):
            q, d = m.q[i, j], m.directions[i, j]
            assert all(r.contains(v) for r, v in zip(system.joint_ranges, q)), (name, q)
            T = system.fk(q)
            w = np.asarray(TARGET) - T[:3, 3]
            assert np.linalg.norm(T[:3, 2] - d) < AXIS_TOLERANCE
            assert np.linalg.norm(w - (w @ d) * d) < AXIS_TOLERANCE
            fresh = World(system, patient.obstacles()) if checked % 50 == 0 else scene
            report = validity.check(system, q, margin=DEFAULT_MARGIN, world=fresh)
            assert not report.collisions, (name, report.collisions[:2])
            assert abs(report.min_distance - m.clearance[i, j]) < CLEARANCE_TOLERANCE
            checked += 1
    print(f"\n{checked} reachable cells checked (limits, beam axis ≤ {AXIS_TOLERANCE}, exact clearance ≥ margin)")
    assert checked > 200


def _brute_force_valid(system, patient, direction, scene, rolls_deg, distances) -> bool:
    """Any roll (the given steps) and distance with a configuration in range and clear of the margin? The
    6-DOF pose IK (both branches) on every pose; the collision check on every configuration in range."""
    z = np.asarray(direction)
    x0 = np.cross(z, np.eye(3)[int(np.argmin(np.abs(z)))])
    x0 /= np.linalg.norm(x0)
    y0 = np.cross(z, x0)
    poses = []
    for r in np.radians(rolls_deg):
        x = math.cos(r) * x0 + math.sin(r) * y0
        for s in distances:
            T = np.eye(4)
            T[:3, :3] = np.column_stack((x, np.cross(z, x), z))
            T[:3, 3] = np.asarray(TARGET) - s * z
            poses.append(T)
    result = analytic_ik.solve_batch(system, np.array(poses))
    Q = np.asarray(result.solutions).reshape(-1, system.nq)
    inside = np.all(np.isfinite(Q), axis=1)
    inside[inside] = np.all([rg.contains(Q[inside, k]) for k, rg in enumerate(system.joint_ranges)], axis=0)
    return any(scene.distances(q=q).min() >= DEFAULT_MARGIN for q in Q[inside])


def _held_table(system):
    """The 6-joint system of a motorized one whose table joints are held at mid-range (table motion = I)."""
    import dataclasses

    mid = 0.5 * (system.lower + system.upper)
    assert np.allclose(system.table_motion(system.split(mid)[1]), np.eye(4), atol=1e-15)
    return system.replace(table=dataclasses.replace(system.table, joints=()))


class _HeldScene:
    """The motorized scene, answering for 6-joint configurations (the table joints at mid-range, 0 here)."""

    def __init__(self, scene, nq):
        self.scene, self.nq = scene, nq

    def distances(self, q):
        full = np.zeros(self.nq)
        full[0], full[self.nq - 5:] = q[0], q[1:]
        return self.scene.distances(q=full)


def test_unreachable_cells_along_the_table_axis_by_the_qp(maps):
    """Beams exactly along the table axis (secondary ±90°) make every pose singular for the pose IK (its
    numerical fallback takes ~17 ms a pose, 2.5 min a cell at 1° rolls), so these cells get another solver:
    the prepared QP, every joint free, from the reference and 3 random seeds, with the source on the beam
    every 10 cm; no answer it finds is valid and clear by a fresh scene."""
    from carmkin import qp_ik
    from carmkin.qp.options import SearchOptions

    checked = 0
    for name, (system, patient, m) in maps.items():
        scene = World(system, patient.obstacles())
        solver = qp_ik.prepare(system, patient.obstacles(), qp_ik.QPIKOptions(safety_margin=DEFAULT_MARGIN),
                               search=SearchOptions(random_seeds=3))
        cells = [(i, k) for i, k in zip(*np.nonzero(~m.reachable)) if abs(m.secondary_deg[k]) == 90]
        for i, k in cells[:: max(1, len(cells) // 6)]:
            d = m.directions[i, k]
            for s in np.arange(0.05, system.carm.source_to_detector, 0.1):
                result = solver.solve(qp_ik.AxisTarget(tuple(np.asarray(TARGET) - s * d), tuple(d)))
                if result.success:
                    T = system.fk(result.q)
                    on_beam = np.linalg.norm(T[:3, 2] - d) < 1e-6
                    assert not (on_beam and validity.check(system, result.q, margin=DEFAULT_MARGIN, world=scene)
                                .reachable), (name, m.primary_deg[i], m.secondary_deg[k], s)
            checked += 1
    print(f"\n{checked} unreachable cells along the table axis: the QP finds no clear configuration")
    assert checked >= 20


def test_unreachable_cells_are_unreachable(maps):
    """≥ 200 unreachable cells of the four systems (the motorized table's joints held where the map holds
    them): no roll at 1° steps and no distance (5 cm steps) gives a configuration in range and clear of the
    margin."""
    rolls = np.arange(0.37, 360.0, 1.0)  # 1° steps, off the exactly singular integer rolls
    checked = 0
    for name in ("C-arm alone", "6-DOF", "non-isocentric", "motorized"):
        system, patient, m = maps[name]
        scene = World(system, patient.obstacles())
        if system.table.joints:  # the map holds the table joints at mid-range, where the table motion is I:
            system = _held_table(system)  # the pose IK of the same C-arm, the table joints put back for the scene
            scene = _HeldScene(scene, m.q.shape[-1])
        distances = np.arange(0.0, system.carm.source_to_detector + 1e-9, 0.05)
        # Beams along the table axis (|secondary| = 90°) make every pose singular for the pose IK, which then
        # solves each numerically (~17 ms): those cells get the QP instead (the test above).
        cells = [(i, j) for i, j in zip(*np.nonzero(~m.reachable)) if abs(m.secondary_deg[j]) < 90]
        for i, j in cells[:: max(1, len(cells) // 55)]:
            assert not _brute_force_valid(system, patient, m.directions[i, j], scene, rolls, distances), (
                name, m.primary_deg[i], m.secondary_deg[j], m.reason[i, j])
            checked += 1
    print(f"\n{checked} unreachable cells brute-forced")
    assert checked >= 200


def test_plan_view_agrees_with_the_map(maps):
    """Cell by cell: the same answer. On the motorized table plan_view may also free the table joints the map
    holds (solver "qp") for a cell the map finds unreachable; that plan is checked by a fresh scene and FK."""
    compared = freed = 0
    for name, (system, patient, m) in maps.items():
        rng = np.random.default_rng(0)
        scene = World(system, patient.obstacles())
        for i, j in zip(rng.integers(0, len(m.primary_deg), 25), rng.integers(0, len(m.secondary_deg), 25)):
            view = View.from_angles(m.primary_deg[i], m.secondary_deg[j], TARGET, patient)
            plan = plan_view(system, view, patient, nearest=False)
            if plan.solver == "qp":
                assert system.table.joints and not m.reachable[i, j]
                T = system.fk(plan.q)
                w = np.array(TARGET) - T[:3, 3]
                assert np.linalg.norm(T[:3, 2] - view.axis) < 1e-6
                assert np.linalg.norm(w - (w @ T[:3, 2]) * T[:3, 2]) < 1e-6
                assert validity.check(system, plan.q, margin=DEFAULT_MARGIN, world=scene).reachable
                freed += 1
                continue
            assert plan.success == m.reachable[i, j], (name, m.primary_deg[i], m.secondary_deg[j])
            if plan.success:
                np.testing.assert_allclose(plan.q, m.q[i, j], atol=1e-12)
                assert plan.clearance == pytest.approx(m.clearance[i, j], abs=1e-12)
            else:
                assert plan.reason and plan.reason == m.reason[i, j]
            compared += 1
    print(f"\nplan_view agrees with the map on {compared} cells; {freed} more reached by freeing the motorized table")


def test_nearest_is_never_farther_than_the_nearest_reachable_cell(maps):
    for name in ("C-arm alone", "6-DOF"):
        system, patient, m = maps[name]
        rng = np.random.default_rng(1)
        reachable = m.directions[m.reachable]
        # Unreachable cells at the edge of the reachable set (the search's cost grows with the angle it covers).
        cells = [(i, j) for i, j in zip(*np.nonzero(~m.reachable))
                 if np.max(reachable @ m.directions[i, j]) > math.cos(math.radians(13.0))]
        for k in rng.choice(len(cells), 4, replace=False):
            i, j = cells[k]
            view = View.from_angles(m.primary_deg[i], m.secondary_deg[j], TARGET, patient)
            plan = plan_view(system, view, patient)
            assert not plan.success and plan.nearest is not None and plan.nearest.success
            nearest_cell = np.min(np.arccos(np.clip(reachable @ view.axis, -1, 1)))
            assert plan.angle <= nearest_cell + 1e-9, (name, math.degrees(plan.angle), math.degrees(nearest_cell))
            assert plan.nearest.clearance >= DEFAULT_MARGIN


def test_source_pose_of_angles_is_dicom_s():
    """The view's beam is the DICOM pose's principal axis (interop's own code)."""
    for p, s in ((30, 20), (-45, -10), (90, 0)):
        view = View.from_angles(p, s, TARGET, "HFS")
        T = pose_from_xa_angles(p, s, TARGET, 0.6, "HFS")
        np.testing.assert_allclose(view.axis, T[:3, 2], atol=1e-15)
