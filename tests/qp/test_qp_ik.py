"""QP IK: convergence on full-pose, axis and aim targets, joint limits, collision margin, backends
(OSQP included), the hybrid closed-form/QP solve, and a UR5 from example-robot-data (generic models).

Final poses are checked with the closed-form forward kinematics (system.fk), not with Pinocchio.
"""

import importlib.metadata
import os
import sys
import types

import numpy as np
import pinocchio as pin
import pytest
import qpsolvers
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from strategies import PRESET, systems

import carmkin
from carmkin import qp_ik
from carmkin.qp.tasks import AimTask, AxisTask, PoseTask, TaskError
from carmkin.qp_ik import QPIK, AimTarget, AxisTarget, QPIKError, QPIKOptions, make_task
from carmkin.robot import validity
from carmkin.world import Obstacle, World

MODEL = PRESET.pinocchio()[0]
SCENE = World(PRESET)
MARGIN = QPIKOptions().safety_margin
TOL = 1e-6
unit6 = st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6).map(np.array)
noise6 = st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6).map(np.array)
# Hand-built blocked case (docs/qp_ik.md): C-arm with the beam straight up through the table, a box touching
# the middle of the C from the side. Rolling about the beam (wigwag, compensated by table translation and
# horizontal) clears it; the full pose of q_A cannot.
Q_A = np.array([0.0, 0.1, 0.0, 0.1, 0.0, 0.0])


def pose_error_of(system, q, T):
    F = system.fk(q)
    return np.linalg.norm(F[:3, 3] - T[:3, 3]), np.linalg.norm(pin.log3(T[:3, :3].T @ F[:3, :3]))


def pose_error(q, T):
    return pose_error_of(PRESET, q, T)


def case(u, noise, fraction=0.05):
    """Target configuration in range with clearance, and a perturbed, projected, clear seed."""
    q = PRESET.lower + u * (PRESET.upper - PRESET.lower)
    q0 = np.clip(q + fraction * noise * (PRESET.upper - PRESET.lower), PRESET.lower, PRESET.upper)
    assume(SCENE.distances(q=q).min() > MARGIN and SCENE.distances(q=q0).min() > MARGIN)
    return q, q0


def blocking_box(side=+1, size=0.08, overlap=0.02):
    """A cube beside the middle C segment of Q_A, overlapping it by ``overlap`` along the orbital axis."""
    data = MODEL.createData()
    pin.framesForwardKinematics(MODEL, data, Q_A)
    gm = SCENE.geometry_model
    gd = pin.GeometryData(gm)
    pin.updateGeometryPlacements(MODEL, data, gm, gd)
    M = gd.oMg[[g.name for g in gm.geometryObjects].index("dh_frame_6_3")]
    offset = PRESET.body.c_depth / 2 + size / 2 - overlap
    return Obstacle.box("patient", (size,) * 3, M.translation + side * offset * M.rotation[:, 2])


@settings(max_examples=25)
@given(unit6, noise6)
def test_pose_targets_converge_within_limits_and_margin(u, noise):
    q, q0 = case(u, noise)
    T = PRESET.fk(q)
    run = QPIK(MODEL, [PoseTask(MODEL, "xray_source", T)], SCENE).solve(q0, record=True)
    assert run.success, run.reason
    p, a = pose_error(run.q, T)
    assert p <= 1.01 * TOL and a <= 1.01 * TOL
    assert np.all(run.q >= PRESET.lower) and np.all(run.q <= PRESET.upper)
    fresh = World(PRESET)
    assert min(fresh.distances(q=h).min() for h in run.history) >= MARGIN - 1e-9
    assert run.min_distance >= MARGIN - 1e-9


@settings(max_examples=10)
@given(systems(), unit6, noise6)
def test_random_non_isocentric_systems_converge(system, u, noise):
    """Kinematics only (no collision rows): any geometry and table setup, checked with its closed-form FK."""
    model = system.pinocchio()[0]
    q = system.lower + u * (system.upper - system.lower)
    q0 = np.clip(q + 0.05 * noise * (system.upper - system.lower), system.lower, system.upper)
    T = system.fk(q)
    run = QPIK(model, [PoseTask(model, "xray_source", T)]).solve(q0)
    assume(run.success)  # a perturbed seed can fall in a local minimum at the joint limits
    F = system.fk(run.q)
    assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1.01 * TOL
    assert np.linalg.norm(pin.log3(T[:3, :3].T @ F[:3, :3])) <= 1.01 * TOL


def test_random_systems_mostly_converge():
    rng = np.random.default_rng(4)
    from carmkin.model.sampling import random_system

    ok = 0
    for _ in range(10):
        system = random_system(rng, PRESET)
        model = system.pinocchio()[0]
        q = rng.uniform(system.lower, system.upper)
        q0 = np.clip(q + rng.uniform(-0.05, 0.05, 6) * (system.upper - system.lower), system.lower, system.upper)
        run = QPIK(model, [PoseTask(model, "xray_source", system.fk(q))]).solve(q0)
        ok += run.success and max(pose_error_of(system, run.q, system.fk(q))) <= 1.01 * TOL
    assert ok >= 9


def test_motorized_table_model_with_eleven_joints():
    """Nothing assumes six joints: the motorized-table preset (nq = 11) with collision rows, and an axis
    target blocked at Q_A that the extra table joints help to clear."""
    system = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
    assert system.nq == 11
    scene = World(system)
    model = scene.model
    rng = np.random.default_rng(9)
    task = PoseTask(model, "xray_source", np.eye(4))
    ik = QPIK(model, [task], scene)
    solved = 0
    while solved < 10:
        q = rng.uniform(system.lower, system.upper)
        step = rng.uniform(-0.05, 0.05, system.nq) * (system.upper - system.lower)
        q0 = np.clip(q + step, system.lower, system.upper)
        if min(scene.distances(q=q).min(), scene.distances(q=q0).min()) <= MARGIN:
            continue
        task.set_target(system.fk(q))
        run = ik.solve(q0)
        assert run.success, run.reason
        assert run.q.shape == (11,) and max(pose_error_of(system, run.q, system.fk(q))) <= 1.01 * TOL
        assert np.all(run.q >= system.lower) and np.all(run.q <= system.upper) and run.min_distance >= MARGIN - 1e-9
        solved += 1
    q_a = np.concatenate((Q_A[:1], np.zeros(5), Q_A[1:]))  # extra table joints at rest: the paper's chain
    assert np.allclose(system.fk(q_a), PRESET.fk(Q_A))
    blocked = World(system, [blocking_box()])
    T = system.fk(q_a)
    run = QPIK(model, [make_task(model, AxisTarget(T[:3, 3], T[:3, 2]))], blocked).solve(q_a)
    assert run.success, run.reason
    assert validity.check(system, run.q, world=blocked, margin=MARGIN - 1e-6).reachable


@pytest.mark.parametrize("backend", [b for b in qp_ik.BACKENDS if b in qpsolvers.available_solvers])
def test_every_installed_backend_converges_inside_the_bounds(backend):
    rng = np.random.default_rng(7)
    task = PoseTask(MODEL, "xray_source", np.eye(4))
    ik = QPIK(MODEL, [task], SCENE, backend=backend)
    solved = 0
    while solved < 8:
        q = rng.uniform(PRESET.lower, PRESET.upper)
        q0 = np.clip(q + rng.uniform(-0.05, 0.05, 6) * (PRESET.upper - PRESET.lower), PRESET.lower, PRESET.upper)
        if min(SCENE.distances(q=q).min(), SCENE.distances(q=q0).min()) <= MARGIN:
            continue
        task.set_target(PRESET.fk(q))
        run = ik.solve(q0)
        assert run.success, (backend, run.reason)
        assert max(pose_error(run.q, PRESET.fk(q))) <= 1.01 * TOL
        assert np.all(run.q >= PRESET.lower) and np.all(run.q <= PRESET.upper)
        solved += 1


@settings(max_examples=15)
@given(unit6, noise6)
def test_axis_target_leaves_the_roll_free(u, noise):
    q, q0 = case(u, noise)
    T = PRESET.fk(q)
    task = make_task(MODEL, AxisTarget(T[:3, 3], T[:3, 2]))
    run = QPIK(MODEL, [task], SCENE).solve(q0)
    assert run.success, run.reason
    F = PRESET.fk(run.q)
    assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1.01 * TOL
    assert np.arccos(np.clip(F[:3, 2] @ T[:3, 2], -1, 1)) <= 2e-6


@settings(max_examples=15)
@given(unit6, noise6)
def test_aim_target_passes_the_axis_through_the_point(u, noise):
    q, q0 = case(u, noise)
    T = PRESET.fk(q)
    point = T[:3, 3] + 0.6 * T[:3, 2]
    run = QPIK(MODEL, [make_task(MODEL, AimTarget(point, (0.5, 0.55)))], SCENE).solve(q0)
    assume(run.success)  # a 0.05 m distance window can be out of reach from a perturbed seed
    F = PRESET.fk(run.q)
    w = point - F[:3, 3]
    s = w @ F[:3, 2]
    assert np.linalg.norm(w - s * F[:3, 2]) <= 1.01 * TOL
    assert 0.5 - 1e-6 <= s <= 0.55 + 1e-6


def test_aim_target_usually_converges():
    rng = np.random.default_rng(5)
    ok = total = 0
    while total < 20:
        q = rng.uniform(PRESET.lower, PRESET.upper)
        q0 = np.clip(q + rng.uniform(-0.05, 0.05, 6) * (PRESET.upper - PRESET.lower), PRESET.lower, PRESET.upper)
        if min(SCENE.distances(q=q).min(), SCENE.distances(q=q0).min()) <= MARGIN:
            continue
        T = PRESET.fk(q)
        run = QPIK(MODEL, [make_task(MODEL, AimTarget(T[:3, 3] + 0.6 * T[:3, 2], (0.5, 0.55)))], SCENE).solve(q0)
        ok += run.success
        total += 1
    assert ok >= 18


def test_unreachable_target_fails_inside_the_limits():
    T = PRESET.fk(np.zeros(6))
    T[:3, 3] += [3.0, 0.0, 0.0]  # 3 m sideways: beyond every joint range
    run = QPIK(MODEL, [PoseTask(MODEL, "xray_source", T)], SCENE).solve(np.zeros(6))
    assert not run.success and run.reason
    assert np.all(run.q >= PRESET.lower) and np.all(run.q <= PRESET.upper)
    assert run.min_distance >= MARGIN - 1e-9


def test_blocked_branch_rolls_around_the_obstacle():
    """The closed-form configuration Q_A collides with the box; with the roll free the QP finds a
    collision-free configuration on the same axis. A collision-free alternative exists: the QP without the
    box reaches the pose rolled by 6° about the axis, and that configuration clears the box."""
    box = blocking_box()
    scene = World(PRESET, [box])
    assert not validity.check(PRESET, Q_A, world=scene).reachable
    T = PRESET.fk(Q_A)
    for roll in (+1, -1):
        rolled = T.copy()
        rolled[:3, :3] = T[:3, :3] @ pin.exp3(np.array([0.0, 0.0, roll * np.radians(6)]))
        alternative = QPIK(MODEL, [PoseTask(MODEL, "xray_source", rolled)], SCENE).solve(Q_A)
        if alternative.success and validity.check(PRESET, alternative.q, world=scene, margin=MARGIN).reachable:
            break
    else:
        pytest.fail("constructed case: no collision-free alternative found")
    run = QPIK(MODEL, [make_task(MODEL, AxisTarget(T[:3, 3], T[:3, 2]))], scene).solve(Q_A, record=True)
    assert run.success, run.reason
    assert validity.check(PRESET, run.q, world=scene, margin=MARGIN - 1e-6).reachable
    F = PRESET.fk(run.q)
    assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1.01 * TOL and F[:3, 2] @ T[:3, 2] >= 1 - 1e-12
    assert abs(run.q[2]) > 0.01  # it rolled with the wigwag


def test_no_alternative_gives_a_failure_not_a_colliding_answer():
    """An obstacle around the source centre blocks every configuration with that source pose."""
    T = PRESET.fk(Q_A)
    patient = Obstacle.box("patient", (0.1, 0.1, 0.1), T[:3, 3])
    scene = World(PRESET, [patient])
    for target in (T, AxisTarget(T[:3, 3], T[:3, 2])):
        run = QPIK(MODEL, [make_task(MODEL, target)], scene).solve(Q_A)
        assert not run.success and run.reason


def test_bad_inputs_are_rejected():
    with pytest.raises(QPIKError, match="not installed|available"):
        QPIK(MODEL, [PoseTask(MODEL, "xray_source", np.eye(4))], backend="nosuchsolver")
    with pytest.raises(QPIKError, match="collision_gain"):
        QPIKOptions(collision_gain=1.5)
    with pytest.raises(QPIKError, match="influence"):
        QPIKOptions(safety_margin=0.2, influence_distance=0.1)
    with pytest.raises(TaskError, match="frame"):
        PoseTask(MODEL, "nosuchframe", np.eye(4))
    with pytest.raises(TaskError, match="direction"):
        AxisTask(MODEL, "xray_source", np.zeros(3), np.zeros(3))
    with pytest.raises(TaskError, match="distance_range"):
        AimTask(MODEL, "xray_source", np.zeros(3), (0.6, 0.5))
    with pytest.raises(QPIKError, match="target"):
        make_task(MODEL, np.eye(3))
    with pytest.raises(QPIKError, match="nq == nv"):
        QPIK(pin.buildSampleModelHumanoid(), [PoseTask(pin.buildSampleModelHumanoid(), "universe", np.eye(4))])
    with pytest.raises(carmkin.InvalidConfigurationError):
        QPIK(MODEL, [PoseTask(MODEL, "xray_source", np.eye(4))]).solve(np.zeros(5))


# --- hybrid solve -----------------------------------------------------------------------------------------
def fake_closed_form(monkeypatch, solutions):
    """Stand-in for carmkin.analytic_ik returning fixed branches (tests the hybrid's decisions only)."""
    module = types.SimpleNamespace(
        solve=lambda system, T, q_current=None: types.SimpleNamespace(solutions=np.array(solutions), chosen=0)
    )
    monkeypatch.setitem(sys.modules, "carmkin.analytic_ik", module)
    monkeypatch.setattr(carmkin, "analytic_ik", module, raising=False)


def test_hybrid_returns_a_valid_closed_form_branch(monkeypatch):
    fake_closed_form(monkeypatch, [Q_A, Q_A])
    result = qp_ik.solve(PRESET, PRESET.fk(Q_A), q_current=Q_A)
    assert result.success and result.path == "closed_form" and result.seed == "branch 0"
    assert np.array_equal(result.q, Q_A)


def rolled_alternative(degrees=6.0):
    """A configuration on the beam axis of Q_A rolled by ``degrees`` about it (QP without obstacles)."""
    T = PRESET.fk(Q_A)
    T[:3, :3] = T[:3, :3] @ pin.exp3(np.array([0.0, 0.0, np.radians(degrees)]))
    run = QPIK(MODEL, [PoseTask(MODEL, "xray_source", T)], SCENE).solve(Q_A)
    assert run.success, run.reason
    return run.q


def test_hybrid_takes_the_other_branch_when_the_chosen_one_collides(monkeypatch):
    box = blocking_box()
    q_other = next(q for q in (rolled_alternative(6), rolled_alternative(-6))
                   if validity.check(PRESET, q, obstacles=[box], margin=MARGIN).reachable)
    fake_closed_form(monkeypatch, [Q_A, q_other])
    T = PRESET.fk(Q_A)
    result = qp_ik.solve(PRESET, AxisTarget(T[:3, 3], T[:3, 2]), obstacles=[box])
    assert result.path == "closed_form" and result.seed == "branch 1" and np.array_equal(result.q, q_other)
    assert "patient" in str(result.branch_reports[0].validity)


def test_hybrid_goes_around_a_blocked_branch(monkeypatch):
    fake_closed_form(monkeypatch, [Q_A, Q_A])
    T = PRESET.fk(Q_A)
    result = qp_ik.solve(PRESET, AxisTarget(T[:3, 3], T[:3, 2]), q_current=Q_A, obstacles=[blocking_box()])
    assert result.success and result.path == "qp", result.reason
    assert result.validity.reachable
    assert any("patient" in str(b.validity) for b in result.branch_reports)


def test_hybrid_reports_failure_without_a_colliding_answer(monkeypatch):
    fake_closed_form(monkeypatch, [Q_A, Q_A])
    T = PRESET.fk(Q_A)
    patient = Obstacle.box("patient", (0.1, 0.1, 0.1), T[:3, 3])
    result = qp_ik.solve(PRESET, T, q_current=Q_A, obstacles=[patient])
    assert not result.success
    assert "branch 0" in result.reason and "patient" in result.reason and "QP from" in result.reason
    if np.all(np.isfinite(result.q)):
        assert validity.check(PRESET, result.q, obstacles=[patient]).reachable


@pytest.fixture
def analytic():
    return pytest.importorskip("carmkin.analytic_ik", reason="carmkin.analytic_ik not written yet")


def test_hybrid_with_the_real_closed_form(analytic):
    T = PRESET.fk(Q_A)
    clean = qp_ik.solve(PRESET, T, q_current=Q_A)
    assert clean.success and clean.path == "closed_form"
    assert max(pose_error(clean.q, T)) <= 1e-6
    blocked = qp_ik.solve(PRESET, AxisTarget(T[:3, 3], T[:3, 2]), q_current=Q_A, obstacles=[blocking_box()])
    assert blocked.success and blocked.path == "qp", blocked.reason
    patient = Obstacle.box("patient", (0.1, 0.1, 0.1), T[:3, 3])
    failed = qp_ik.solve(PRESET, T, q_current=Q_A, obstacles=[patient])
    assert not failed.success and "patient" in failed.reason
    # The full pose of Q_A has two branches: Q_A (blocked by the box) and one out of range. No way around.
    full = qp_ik.solve(PRESET, T, q_current=Q_A, obstacles=[blocking_box()])
    assert not full.success and full.path == "qp"
    assert "branch 0" in full.reason and "branch 1" in full.reason and "out of range" in full.reason
    if np.all(np.isfinite(full.q)):
        assert validity.check(PRESET, full.q, obstacles=[blocking_box()]).reachable


# --- generic models ---------------------------------------------------------------------------------------
def ur5():
    try:
        share = importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share")
    except importlib.metadata.PackageNotFoundError:
        pytest.skip("example-robot-data not installed (optional extra: pip install 'carmkin[robots]')")
    urdf = os.path.join(str(share), "example-robot-data", "robots", "ur_description", "urdf", "ur5_robot.urdf")
    return pin.buildModelFromUrdf(urdf)


def test_ur5_reaches_random_reachable_targets():
    model = ur5()
    data = model.createData()
    frame = model.getFrameId("tool0")
    rng = np.random.default_rng(2)
    task = PoseTask(model, "tool0", np.eye(4))
    ik = QPIK(model, [task])
    lower, upper = model.lowerPositionLimit, model.upperPositionLimit
    for _ in range(30):
        q = rng.uniform(-np.pi, np.pi, model.nq)
        pin.framesForwardKinematics(model, data, q)
        T = data.oMf[frame].homogeneous.copy()
        task.set_target(T)
        run = ik.solve(np.clip(q + rng.uniform(-0.3, 0.3, model.nq), lower, upper))
        assert run.success, run.reason
        pin.framesForwardKinematics(model, data, run.q)
        assert np.linalg.norm(data.oMf[frame].translation - T[:3, 3]) <= 1.01 * TOL
        assert np.linalg.norm(pin.log3(T[:3, :3].T @ data.oMf[frame].rotation)) <= 1.01 * TOL


# --- the decision path of the one solve -------------------------------------------------------------------
def test_acceptance_rule_decides_and_failures_are_structured():
    T = PRESET.fk(Q_A)
    refused = qp_ik.solve(PRESET, T, q_current=Q_A, accept=lambda report: False)
    assert not refused.success and refused.failure is qp_ik.Failure.NOT_REACHED
    assert all(not b.accepted for b in refused.branch_reports)
    converged = [a for a in refused.attempts if a.status is qp_ik.RunStatus.REJECTED]
    assert converged and all(not a.success and a.rejection is not None for a in converged)
    assert "rejected by the acceptance rule" in refused.reason
    assert refused.reasons == tuple(refused.reason.split(" | "))
    closed_only = qp_ik.solve(PRESET, T, q_current=Q_A, accept=lambda report: False, qp=False)
    assert closed_only.failure is qp_ik.Failure.QP_NOT_RUN and closed_only.attempts == ()
    assert closed_only.path == qp_ik.Path.NONE and np.all(np.isnan(closed_only.q))
    taken = qp_ik.solve(PRESET, T, q_current=Q_A)
    assert taken.success and taken.failure is None and taken.reason is None and taken.reasons == ()


def test_scene_or_obstacles_not_both():
    with pytest.raises(QPIKError, match="either"):
        qp_ik.solve(PRESET, PRESET.fk(Q_A), obstacles=[blocking_box()], world=SCENE)
