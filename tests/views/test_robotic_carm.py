"""The robot-held C-arm (preset ``robotic-carm``) through the planners: QP IK, validity, views, reach map, a
200° sweep, DICOM angles, the viewer and the CLI. Every answer is checked by the FK or by coal, not by the
planner that gave it."""

from __future__ import annotations

import math

import numpy as np
import pytest

import carmkin
from carmkin import qp_ik, sweeps, views
from carmkin.interop import dicom
from carmkin.patient import ParametricPatient
from carmkin.robot import validity
from carmkin.transforms import pose_error
from carmkin.views.standard import STANDARD_VIEWS
from carmkin.world import World

ROBOT = carmkin.load_preset("robotic-carm")
PATIENT = ParametricPatient().on_table(ROBOT)
#: What the QP's answers are held to (m, rad): its own convergence tolerances with room for the last step
#: (:data:`carmkin.views.refine.QP_AXIS_TOLERANCE`).
QP_TOLERANCE = 2e-6
#: What the closed form's answers are held to (m, rad): :data:`carmkin.analytic.mount.RESIDUAL_TOLERANCE`.
CLOSED_FORM_TOLERANCE = 1e-9
#: DICOM geometry round trip (m and rad): a few ulp of the pose compositions.
ROUND_TRIP = 1e-9


@pytest.fixture(scope="module")
def ap():
    """The AP view of the table origin with the patient: its plan (found by the robot's closed form)."""
    plan = views.plan_view(ROBOT, views.View.from_angles(0.0, 0.0, (0.0, 0.0, 0.0)), patient=PATIENT)
    assert plan.success
    return plan


def test_the_qp_reaches_poses_of_the_robot_and_keeps_the_locked_joints(ap):
    rng = np.random.default_rng(3)
    world, solved = World(ROBOT), 0
    while solved < 6:  # poses the robot reaches clear of table and floor: small moves from the AP configuration
        q = np.clip(ap.q + rng.normal(0.0, 0.1, ROBOT.nq) * (ROBOT.upper > ROBOT.lower), ROBOT.lower, ROBOT.upper)
        if world.clearance(q[None])[0] < 0.05:
            continue
        solved += 1
        T = ROBOT.fk(q)
        result = qp_ik.solve(ROBOT, T, q_current=ap.q, accept=lambda report: report.reachable)
        assert result.success, result
        assert pose_error(ROBOT.fk(result.q), T)[0] <= QP_TOLERANCE
        assert np.all(result.q >= ROBOT.lower - 1e-9) and np.all(result.q <= ROBOT.upper + 1e-9)
        for name in ("vertical", "wigwag", "horizontal", "angular"):
            assert abs(result.q[ROBOT.joint_names.index(name)]) <= 1e-9


def test_a_planned_view_is_valid_and_clear_by_coal(ap):
    T = ROBOT.fk(ap.q)
    np.testing.assert_allclose(T[:3, 2], [0.0, -1.0, 0.0], atol=QP_TOLERANCE)  # AP: the beam goes up (Y0 down)
    report = validity.check(ROBOT, ap.q, obstacles=PATIENT.obstacles(), margin=carmkin.DEFAULT_MARGIN)
    assert report.reachable and report.valid
    world = World(ROBOT, PATIENT)
    assert world.distances(q=ap.q).min() == pytest.approx(ap.clearance, abs=1e-5)
    assert ap.clearance >= carmkin.DEFAULT_MARGIN


def test_every_standard_view_is_planned_with_the_patient():
    reached = 0
    for name in STANDARD_VIEWS:
        plan = views.plan_view(ROBOT, name, patient=PATIENT)
        if plan.success:
            reached += 1
            T = ROBOT.fk(plan.q)
            assert np.linalg.norm(T[:3, 2] - plan.view.direction) <= QP_TOLERANCE, name
            assert World(ROBOT, PATIENT).distances(q=plan.q).min() >= carmkin.DEFAULT_MARGIN - 1e-5, name
        else:
            assert plan.reason, name
    print(f"\nrobotic-carm: {reached} of {len(STANDARD_VIEWS)} standard views reachable with the patient")
    assert len(STANDARD_VIEWS) >= 14 and reached == len(STANDARD_VIEWS)


def test_the_reach_map_frees_the_robot_by_its_closed_form():
    """Every cell by the robot's closed form (:mod:`carmkin.views.mount`), none left to the QP; each answer's beam
    held by the FK to the closed form's residual, its clearance by coal on every pair."""
    primary, secondary = np.arange(-90.0, 91.0, 45.0), np.arange(-40.0, 41.0, 40.0)
    reach = views.reach_map(ROBOT, (0.0, 0.0, 0.0), primary, secondary, patient=PATIENT)
    assert reach.reachable.all()  # the QP, before it, reached every cell of this map too
    world = World(ROBOT, PATIENT)
    for i, j in zip(*np.nonzero(reach.reachable)):
        q = reach.q[i, j]
        T = ROBOT.fk(q)
        assert np.linalg.norm(T[:3, 2] - reach.directions[i, j]) <= CLOSED_FORM_TOLERANCE
        w = -T[:3, 3]  # to the target (the origin)
        assert np.linalg.norm(w - (w @ T[:3, 2]) * T[:3, 2]) <= CLOSED_FORM_TOLERANCE
        assert np.all(q >= ROBOT.lower - 1e-9) and np.all(q <= ROBOT.upper + 1e-9)
        assert world.distances(q=q).min() == pytest.approx(reach.clearance[i, j], abs=1e-5)
        assert reach.clearance[i, j] >= carmkin.DEFAULT_MARGIN - 1e-9
    assert np.all(reach.rank[reach.reachable] < views.maps.QP_RANK)  # the closed form, not the QP


def test_a_200_degree_sweep_about_the_patient_with_certified_clearance(ap):
    """The orbital slide (±95°) and the robot's compensation together: 200° around the patient."""
    q_start = ap.q.copy()
    q_start[-1] = ROBOT.lower[-1]  # orbital at its lower limit: the robot takes the rest
    sweep = sweeps.plan_sweep(ROBOT, (0.0, 0.0, 0.0), arc_deg=200.0, n_views=41, patient=PATIENT, q_start=q_start)
    assert sweep.success, sweep.failure
    assert sweep.min_clearance >= carmkin.DEFAULT_MARGIN
    T = ROBOT.fk(sweep.q)
    beam = T[:, :3, 2]
    turned = math.degrees(math.acos(np.clip(beam[0] @ beam[-1], -1.0, 1.0)))
    assert turned == pytest.approx(160.0, abs=1e-3)  # 200° of arc: the first and last beams 160° apart
    axis = np.cross(beam[0], beam[20])
    np.testing.assert_allclose(beam @ (axis / np.linalg.norm(axis)), 0.0, atol=1e-6)  # one plane: a rotation
    distance = ROBOT.carm.source_to_orbital_axis
    np.testing.assert_allclose(T[:, :3, 3] + distance * beam, 0.0, atol=1e-6)  # the target stays the isocentre


def test_dicom_geometry_round_trips_and_the_equipment_axes_stay_on_the_floor(ap):
    rng = np.random.default_rng(7)
    axes = dicom.equipment_axes(ROBOT, ap.q)
    for _ in range(20):
        q = ROBOT.lower + rng.random(ROBOT.nq) * (ROBOT.upper - ROBOT.lower)
        q[0] = ap.q[0]
        geometry = dicom.isocenter_geometry(ROBOT, q)
        assert pose_error(geometry.source_pose(), ROBOT.fk(q))[0] <= ROUND_TRIP
        np.testing.assert_allclose(dicom.equipment_axes(ROBOT, q), axes, atol=1e-15)  # the robot moved, not they
        primary, secondary, rotation = dicom.xa_angles(ROBOT.fk(q))
        T = dicom.pose_from_xa_angles(primary, secondary, (0.0, 0.0, 0.0), 0.785, rotation_deg=rotation)
        again = dicom.xa_angles(T)
        assert max(abs(math.remainder(a - b, 360.0)) for a, b in zip(again, (primary, secondary, rotation))) <= 1e-9


def test_the_viewer_shows_the_robot_and_its_distances(ap):
    from carmkin.viz import CArmViewer

    viewer = CArmViewer(ROBOT, q=ap.q)
    pairs = viewer.show_distances(ap.q)
    assert [(d.part, d.obstacle) for d in pairs] == list(World(ROBOT).pairs)
    assert any(d.part.startswith("mount_body_") for d in pairs)
    visuals = viewer.vis.window.tree["meshcat"]["carmkin"]["robot"]["visuals"]
    assert {f"mount_body_{k}_0" for k in range(7)} <= set(visuals)  # the pedestal and the six moving bodies


def test_the_cli_plans_a_view_of_the_robotic_preset(capsys):
    from carmkin.cli import main

    assert main(["views", "plan", "--preset", "robotic-carm", "--primary-deg", "30", "--secondary-deg", "20"]) == 0
    out = capsys.readouterr().out
    assert "robot_a1=" in out and "reachable" in out
    # the closed form's command refuses in one line, naming the mount (usage error: exit 2)
    assert main(["ik", "--preset", "robotic-carm", "--pose", "0,0,0,0,0,0"]) == 2
    assert "extra table and mount joints robot_a1" in capsys.readouterr().err


def test_the_cli_sweep_runs_with_its_default_start(capsys):
    """Issue 41: ``carmkin sweep plan --preset robotic-carm --arc-deg 190 --views 30`` exited 2 ("cannot be put on
    the principal axis ... with the start orientation"): the default start was the zero configuration clipped
    into A2's range, the isocentre far from the table. At rest the robot now holds the isocentre at the table
    origin, inside every range."""
    from carmkin.cli import main

    assert np.all(ROBOT.lower <= 0.0) and np.all(ROBOT.upper >= 0.0)
    assert main(["sweep", "plan", "--preset", "robotic-carm", "--arc-deg", "190", "--views", "30"]) == 0
    assert "feasible" in capsys.readouterr().out
