"""Mount joints (a robot holding the C): the closed form, the URDF/Pinocchio route and a matrix exponential agree;
the preset states the robot as its data sheet does; bad input is refused naming the field."""

from __future__ import annotations

import math
import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm
from strategies import KR210, KR210_REST_DEG, PRESET, configurations, finite, motorized_systems, systems, unit_vectors

import carmkin
from carmkin import InvalidParameterError, JointRange
from carmkin.errors import PresetError, UnsupportedSystemError
from carmkin.model.mount_joints import MountGeometry, MountJoint
from carmkin.presets import parse_preset, to_toml
from carmkin.robot.verify import closed_form_frames, pinocchio_frames
from carmkin.transforms import skew

ROBOT = carmkin.load_preset("robotic-carm")
ROBOT_TEXT = (carmkin.presets._preset_dir() / "robotic-carm.toml").read_text()
#: FK agreement of the closed form and Pinocchio (m and rotation-matrix entries), the issue's acceptance bound.
FK_AGREEMENT = 1e-12


def _pinocchio_poses(system, Q, frame: str = "xray_source") -> np.ndarray:
    model = system.pinocchio()[0]
    data, fid = model.createData(), model.getFrameId(frame)
    out = np.empty((len(Q), 4, 4))
    for k, q in enumerate(Q):
        pin.framesForwardKinematics(model, data, q)
        out[k] = data.oMf[fid].homogeneous
    return out


def _twist_exponential(joint: MountJoint, value: float) -> np.ndarray:
    """``e^{η q}`` by scipy's matrix exponential of the twist's 4x4 matrix: an oracle independent of Rodrigues."""
    u, c = np.asarray(joint.axis), np.asarray(joint.point)
    hat = np.zeros((4, 4))
    if joint.prismatic:
        hat[:3, 3] = u
    else:
        hat[:3, :3] = skew(u)
        hat[:3, 3] = -skew(u) @ c
    return expm(hat * value)


@st.composite
def mounts(draw, min_joints: int = 1, max_joints: int = 6) -> MountGeometry:
    """Random mounts: 1–6 joints, each prismatic or revolute about a random unit axis through a random point
    (±2 m) of a randomly placed robot base, ranges up to ±0.5 m or ±3 rad."""
    joints = []
    for k in range(draw(st.integers(min_joints, max_joints))):
        prismatic = draw(st.booleans())
        reach = 0.5 if prismatic else 3.0
        span = JointRange(-draw(st.floats(0.0, reach, **finite)), draw(st.floats(0.0, reach, **finite)), f"m{k}")
        point = tuple(draw(st.floats(-2.0, 2.0, **finite)) for _ in range(3))
        joints.append(MountJoint(f"m{k}", prismatic, tuple(draw(unit_vectors())), point, span))
    x = draw(unit_vectors())
    z = np.cross(x, draw(unit_vectors()))
    z = z / np.linalg.norm(z) if np.linalg.norm(z) > 1e-3 else np.cross(x, [1.0, 0.0, 0.0] if abs(x[0]) < 0.9 else [0, 1, 0])
    z = z / np.linalg.norm(z)
    origin = tuple(draw(st.floats(-3.0, 3.0, **finite)) for _ in range(3))
    return MountGeometry(tuple(joints), origin, tuple(x), tuple(z), draw(st.floats(0.05, 0.4, **finite)))


@st.composite
def mounted_systems(draw) -> carmkin.CArmSystem:
    """Random geometries and setups, 0–5 random table joints and 1–6 random mount joints."""
    return draw(motorized_systems(max_joints=2)).replace(mount=draw(mounts()))


# --- the preset -------------------------------------------------------------------------------------------------
def test_the_robotic_preset_orders_its_joints_table_mount_carm():
    assert ROBOT.nq == 12
    assert ROBOT.joint_names == ("table_translation",) + tuple(f"robot_a{k}" for k in range(1, 7)) + carmkin.JOINT_NAMES[1:]
    assert ROBOT.prismatic == (True,) + (False,) * 6 + (True, False, True, False, False)
    assert list(ROBOT.pinocchio()[0].names[1:]) == list(ROBOT.joint_names)
    # the C-arm's own joints are locked except the orbital slide
    for name in ("vertical", "wigwag", "horizontal", "angular"):
        k = ROBOT.joint_names.index(name)
        assert ROBOT.lower[k] == ROBOT.upper[k] == 0.0
    # the KR 210 R3100-2's A2 range (ROS-Industrial URDF: -140°..-5°) about the rest pose
    k = ROBOT.joint_names.index("robot_a2")
    assert math.degrees(ROBOT.lower[k]) + KR210_REST_DEG[1] == pytest.approx(-140.0)
    assert math.degrees(ROBOT.upper[k]) + KR210_REST_DEG[1] == pytest.approx(-5.0)
    q = ROBOT.mount_part(np.arange(12.0))
    np.testing.assert_array_equal(q, np.arange(1.0, 7.0))


def test_at_rest_the_carm_base_sits_on_the_flange_as_the_preset_states():
    """The setup derived from ``[mount] carm_base_*``: the C-arm base at rest is the flange (1200, 0, 1200) mm of
    the robot base, which stands at (-2200, 1200, 0) mm facing +X0 with Z_B up (= -Y0)."""
    np.testing.assert_allclose(ROBOT.carm_base_pose[:3, 3], [-2.2 + 1.2, 1.2 - 1.2, 0.0], atol=1e-12)
    np.testing.assert_allclose(ROBOT.carm_base_pose[:3, 2], [0.0, -1.0, 0.0], atol=1e-12)  # vertical axis up
    np.testing.assert_allclose(ROBOT.carm_base_pose[:3, 1], [1.0, 0.0, 0.0], atol=1e-12)  # the arm along A6


def _kr210(theta) -> np.ndarray:
    """G(θ) (4, 4) in the robot base frame by the URDF's twists at its zero, each e^{ξ̂ θ} by scipy's expm."""
    from scipy.linalg import expm

    out = np.eye(4)
    for (axis, point, _), angle in zip(KR210, theta):
        w, p = np.array(axis, float), np.array(point, float) / 1e3
        xi = np.zeros((4, 4))
        xi[:3, :3] = [[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]
        xi[:3, 3] = -np.cross(w, p)
        out = out @ expm(xi * angle)
    return out


def test_the_robot_rests_in_range_with_the_isocentre_at_the_table_origin_as_the_urdf_moves_it():
    """Issue 41: the URDF's zero (A2 = 0°) is outside A2's range, and at it the isocentre stood 2.1 m beyond the
    table. The preset's twists are the URDF's carried to a rest pose in range: at every configuration the
    preset's robot equals the URDF's at q + rest (an independent route: the xacro's numbers, scipy's expm); at
    rest the URDF's flange lands where the preset puts the C-arm base; every joint's range is the URDF's less
    its rest angle; the zero configuration is in range and puts the isocentre at the table origin."""
    rest = np.radians(KR210_REST_DEG)
    mount = [ROBOT.joint_names.index(f"robot_a{i}") for i in range(1, 7)]
    flange = np.eye(4)
    flange[:3, 3] = [3.34, 0.0, 0.76]  # the URDF's flange at its zero
    at_rest = np.eye(4)
    at_rest[:3, 3] = [1.2, 0.0, 1.2]  # the preset's carm_base_origin_mm, the flange's orientation unchanged
    np.testing.assert_allclose(_kr210(rest) @ flange, at_rest, atol=1e-12)
    T_0B = ROBOT.mount.base_pose
    rng = np.random.default_rng(41)
    worst = 0.0
    for _ in range(500):
        q = ROBOT.lower[mount] + rng.random(6) * (ROBOT.upper[mount] - ROBOT.lower[mount])
        urdf = T_0B @ _kr210(q + rest) @ np.linalg.inv(_kr210(rest)) @ np.linalg.inv(T_0B)
        worst = max(worst, float(np.abs(ROBOT.mount_motion(q) - urdf).max()))
    assert worst <= 1e-12, worst
    for k, (_, _, (low, high)) in zip(mount, KR210):
        assert math.degrees(ROBOT.lower[k]) + KR210_REST_DEG[mount.index(k)] == pytest.approx(low, abs=1e-12)
        assert math.degrees(ROBOT.upper[k]) + KR210_REST_DEG[mount.index(k)] == pytest.approx(high, abs=1e-12)
    assert np.all(ROBOT.lower <= 0.0) and np.all(ROBOT.upper >= 0.0)
    T = ROBOT.fk(np.zeros(ROBOT.nq))
    np.testing.assert_allclose(T[:3, 3] + ROBOT.carm.source_to_orbital_axis * T[:3, 2], 0.0, atol=1e-12)


def test_fk_agrees_with_pinocchio_over_10000_configurations_of_the_robotic_preset():
    rng = np.random.default_rng(30)
    Q = ROBOT.lower + rng.random((10_000, ROBOT.nq)) * (ROBOT.upper - ROBOT.lower)
    reference = _pinocchio_poses(ROBOT, Q)
    batch = ROBOT.fk(Q)
    scalar = np.array([ROBOT.fk(q) for q in Q])
    assert np.abs(batch - reference).max() <= FK_AGREEMENT
    assert np.abs(scalar - reference).max() <= FK_AGREEMENT
    print(f"\nrobotic-carm FK vs Pinocchio over 10000 q: batch {np.abs(batch - reference).max():.2e}, "
          f"scalar {np.abs(scalar - reference).max():.2e}")


def test_a_robot_axis_turns_the_source_about_that_axis():
    """A1 (vertical, through the robot base) turns the source about the robot's vertical axis: its distance to
    that axis and its height stay, the angle about it moves by −q (the KUKA's A1 axis points down)."""
    q0 = 0.5 * (ROBOT.lower + ROBOT.upper)
    q1 = q0.copy()
    q1[1] += 0.3
    p0, p1 = ROBOT.fk(q0)[:3, 3], ROBOT.fk(q1)[:3, 3]
    base = np.asarray(ROBOT.mount.base_origin)
    r0, r1 = p0 - base, p1 - base
    assert r0[1] == pytest.approx(r1[1], abs=1e-12)  # height (Y0) unchanged
    a0, a1 = math.atan2(r0[2], r0[0]), math.atan2(r1[2], r1[0])
    # about -Y0 (up) by -0.3: seen with Y0 down that is a turn by +0.3 about +Y0, i.e. atan2(z, x) by -0.3
    assert math.remainder(a1 - a0 + 0.3, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)


# --- random mounts ----------------------------------------------------------------------------------------------
@settings(max_examples=25)
@given(mounted_systems(), st.data())
def test_fk_scalar_batch_and_pinocchio_agree_for_random_mount_twists(system, data):
    Q = np.array([data.draw(configurations(system, beyond=0.2)) for _ in range(4)])
    reference = _pinocchio_poses(system, Q)
    assert np.abs(system.fk(Q) - reference).max() <= FK_AGREEMENT
    assert max(np.abs(system.fk(q) - T).max() for q, T in zip(Q, reference)) <= FK_AGREEMENT
    # every DH frame, the detector, and the mount bodies' frames as well
    np.testing.assert_allclose(closed_form_frames(system, Q), pinocchio_frames(system, Q), rtol=0, atol=FK_AGREEMENT)
    frames = system.mount_frames(Q)
    for i, joint in enumerate(system.mount.joints):
        np.testing.assert_allclose(frames[:, i], _pinocchio_poses(system, Q, f"{joint.name}_frame"), rtol=0,
                                   atol=FK_AGREEMENT)


@settings(max_examples=40)
@given(mounts(), st.data())
def test_the_mount_motion_is_the_product_of_twist_exponentials(mount, data):
    """``G = e^{η1 q1} ··· e^{ηn qn}`` with the twists carried into frame 0 by the robot base: against scipy's
    matrix exponential of each twist matrix."""
    system = PRESET.replace(mount=mount)
    q = data.draw(configurations(system))
    expected = np.eye(4)
    for joint, value in zip(mount.twists, system.mount_part(q)):
        expected = expected @ _twist_exponential(joint, value)
    np.testing.assert_allclose(system.mount_motion(system.mount_part(q)), expected, rtol=0, atol=1e-12)
    # the base pose carries the rest-frame twists: axes turn with it, points move with it
    for stated, twist in zip(mount.joints, mount.twists):
        np.testing.assert_allclose(twist.axis, mount.base_pose[:3, :3] @ stated.axis, atol=1e-15)


@settings(max_examples=15)
@given(systems(), mounts())
def test_a_random_mounted_system_round_trips_through_toml(system, mount):
    system = system.replace(mount=mount)  # (a preset states only the standard table joints: none here)
    back = parse_preset(to_toml(system), source="round-trip.toml")
    assert back.joint_names == system.joint_names
    for a, b in zip(back.mount.joints, system.mount.joints):
        np.testing.assert_allclose(a.axis, b.axis, atol=1e-15)
        np.testing.assert_allclose(a.point, b.point, rtol=1e-12, atol=1e-15)
        assert (a.prismatic, a.name) == (b.prismatic, b.name)
        np.testing.assert_allclose((a.range.lower, a.range.upper), (b.range.lower, b.range.upper), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(back.mount.base_pose, system.mount.base_pose, rtol=0, atol=1e-12)


def test_a_preset_based_on_the_robot_locks_the_orbital_slide():
    locked = parse_preset('base = "robotic-carm"\n[carm]\norbital_min_deg = 0.0\norbital_max_deg = 0.0\n')
    assert locked.mount == ROBOT.mount and locked.setup == ROBOT.setup
    assert locked.lower[-1] == locked.upper[-1] == 0.0


def test_the_robotic_preset_round_trips_and_keeps_its_carm_base():
    text = to_toml(ROBOT)
    assert "[setup]" not in text and "carm_base_origin_mm" in text
    assert parse_preset(text) == ROBOT


# --- the closed-form IK refuses, the QP solves --------------------------------------------------------------------
def test_the_closed_form_refuses_a_mounted_system_naming_the_mount_joints():
    from carmkin import analytic_ik

    with pytest.raises(UnsupportedSystemError, match=r"mount joints \(robot_a1, .*robot_a6\): use carmkin.qp_ik"):
        analytic_ik.solve(ROBOT, ROBOT.fk(0.5 * (ROBOT.lower + ROBOT.upper)))


def test_the_single_axis_closed_form_holds_the_mount():
    """The closed form the QP tries first on a system with more than six joints: the table translation active,
    the mount held; its branches reach the pose whenever they are in range (here: the C-arm's joints are
    locked, so the held mount's pose is what it reaches)."""
    from carmkin.analytic.single_axis import solve_single_axis

    q = 0.5 * (ROBOT.lower + ROBOT.upper)
    q[0] = 0.1
    result = solve_single_axis(ROBOT, ROBOT.fk(q), "table_translation", q)
    hits = [k for k in range(2) if np.abs(ROBOT.fk(result.solutions[k], check_units=False) - ROBOT.fk(q)).max() < 1e-9]
    assert hits and any(np.allclose(result.solutions[k], q, atol=1e-9) for k in hits)


# --- bad input ----------------------------------------------------------------------------------------------------
def _robot_text(old: str, new: str) -> str:
    assert old in ROBOT_TEXT, old
    return ROBOT_TEXT.replace(old, new, 1)


@pytest.mark.parametrize(("old", "new", "message"), [
    ("axis = [0.0, 1.0, 0.0]           # source: kr210_r3100-2_macro.xacro joint_a2 axis",
     "axis = [0.0, 0.9, 0.0]", r"\[mount\.joints\.robot_a2\] axis must be a unit vector, got \[0\.0, 0\.9, 0\.0\]"),
    ("min_deg = -21.30664879450302", "min_deg = 120.0",
     r"\[mount\.joints\.robot_a2\] min_deg = 120 deg > max_deg = 113\.693 deg"),
    ("min_deg = -21.30664879450302", "min_mm = -140.0",
     r"\[mount\.joints\.robot_a2\] needs min_deg and max_deg .* or min_mm and max_mm"),
    ("point_mm = [330.0, 0.0, 645.0]", "point_mm = [330.0, 0.0]", r"\[mount\.joints\.robot_a2\] point_mm must be a list of 3"),
    ("[mount.joints.robot_a2]", "[mount.joints.robot_a2]\nspeed_deg = 1.0", r"unknown key 'speed_deg' in \[mount\.joints\.robot_a2\]"),
    ("base_z_axis_in_table = [0.0, -1.0, 0.0]", "base_z_axis_in_table = [1.0, 0.0, 0.0]",
     r"MountGeometry\.base_x_axis and base_z_axis must be orthogonal"),
    ("carm_base_z_axis = [0.0, 0.0, 1.0]", "carm_base_z_axis = [0.0, -1.0, 0.0]",
     r"\[mount\] carm_base_x_axis and carm_base_z_axis must be orthonormal"),
    ("[table]\n", "[setup]\ngamma1_deg = 90.0\ngamma2_deg = 0.0\ngamma3_deg = 0.0\nD1_mm = 0.0\nD2_mm = 0.0\nD3_mm = 0.0\n"
     "[table]\n", r"replace \[setup\]; give one of the two"),
    ("max_deg = 350.0                  # source: kr210_r3100-2_macro.xacro joint_a6 limit", "max_deg = 400.0",
     r"\[mount\.joints\.robot_a6\] max_deg must be within \[-360, 360\] deg, got 400"),
])
def test_a_bad_mount_is_a_preset_error_naming_the_field(old, new, message):
    with pytest.raises(PresetError, match=message):
        parse_preset(_robot_text(old, new), source="robot.toml")


def test_a_mount_joint_with_a_non_unit_axis_is_refused_in_python():
    with pytest.raises(InvalidParameterError, match=r"a1: axis must be a unit 3-vector"):
        MountJoint("a1", False, (0.0, 0.0, 2.0), (0.0, 0.0, 0.0), JointRange(-1.0, 1.0, "a1"))
    with pytest.raises(InvalidParameterError, match=r"a1: lower limit 1\.0 > upper limit -1\.0"):
        MountJoint("a1", False, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), JointRange(1.0, -1.0, "a1"))
    with pytest.raises(InvalidParameterError, match=r"CArmSystem\.a1\.upper must be within"):
        PRESET.replace(mount=MountGeometry((MountJoint("a1", False, (0, 0, 1.0), (0, 0, 0), JointRange(0.0, 7.0, "a1")),)))
    with pytest.raises(InvalidParameterError, match=r"MountGeometry\.joints must be distinct MountJoint"):
        MountGeometry(("robot",))
    with pytest.raises(InvalidParameterError, match=r"CArmSystem\.mount must be a MountGeometry"):
        PRESET.replace(mount=())


def test_the_pedestal_is_fixed_and_the_robot_bodies_are_checked_against_table_floor_and_patient():
    from carmkin.world import World

    world = World(ROBOT)
    moving = {a.rpartition("_")[0] for a, _ in world.pairs}
    assert {f"mount_body_{k}" for k in range(1, 7)} <= moving and "mount_body_0" not in moving
    assert not any("mount_body_0" in b for _, b in world.pairs)
    # the floor stays on the floor while the robot moves: its pose does not depend on the mount joints
    model, collision, _ = ROBOT.pinocchio()
    floor = next(g for g in collision.geometryObjects if g.name == "floor_0")
    assert model.names[floor.parentJoint] == "table_translation"


@settings(max_examples=25)
@given(mounts(), st.data())
def test_the_batch_mount_motion_is_the_scalar_one_row_by_row(mount, data):
    """``mount_motion`` and ``mount_frames`` of (N, nq) configurations (vectorised Rodrigues) against the scalar
    product of :meth:`MountJoint.motion` per row."""
    system = PRESET.replace(mount=mount)
    Q = np.array([data.draw(configurations(system)) for _ in range(4)])
    batch = system.mount_motion(system.mount_part(Q))
    for k, q in enumerate(Q):
        expected = np.eye(4)
        for joint, value in zip(mount.twists, system.mount_part(q)):
            expected = expected @ joint.motion(float(value))
        np.testing.assert_allclose(batch[k], expected, rtol=0, atol=1e-12)
        np.testing.assert_allclose(system.mount_frames(Q)[k], system.mount_frames(q), rtol=0, atol=1e-12)
