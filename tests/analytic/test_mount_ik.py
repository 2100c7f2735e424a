"""The closed-form IK of a robot that holds the C (:mod:`carmkin.analytic.mount`): every solution it returns is
held to Pinocchio's forward kinematics (the URDF route, independent of the closed form) to 1e-12, every pose
drawn from a configuration gets that configuration back among its branches, branches are counted, a pose out of
reach is a result (not an exception), and junk is refused with a typed error."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import KR210, KR210_REST_DEG, configurations, finite

import carmkin
from carmkin.analytic import mount
from carmkin.errors import CarmkinError, InvalidConfigurationError, InvalidPoseError, UnsupportedMountError
from carmkin.model.mount_joints import MountJoint, partial_chains
from carmkin.model.params import JOINT_RANGE_TOLERANCE

ROBOT = carmkin.load_preset("robotic-carm")
#: FK(IK(T)) against Pinocchio's FK (m and rotation-matrix entries): the issue's bound.
FK_AGREEMENT = 1e-12
#: The configuration a pose was drawn from is among the branches to this (rad): round-off over the Jacobian's
#: smallest singular value.
SAME_CONFIGURATION = 1e-9
#: ... where the robot's Jacobian has no singular value below this (m or 1 per rad): near a singularity the
#: joints are not determined by the pose (a wrist singularity leaves a4 + a6), only the pose is checked there.
WELL_CONDITIONED = 1e-5
#: Round-off of a pose (m and rotation-matrix entries, a few ulp of 1): two solutions of one pose agree in their
#: angles to this over the Jacobian's smallest singular value (at least to 1e-12).
POSE_ROUNDOFF = 1e-15
MOUNT = slice(1, 7)  # the robot's joints in q: [d0, a1..a6, vertical, wigwag, horizontal, angular, orbital]


def _pinocchio_pose(system, q) -> np.ndarray:
    model = system.pinocchio()[0]
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[model.getFrameId("xray_source")].homogeneous


def _smallest_singular_value(system, q) -> float:
    """The smallest singular value of the source frame's Jacobian in the robot's six joints (Pinocchio)."""
    model = system.pinocchio()[0]
    data = model.createData()
    J = pin.computeFrameJacobian(model, data, q, model.getFrameId("xray_source"), pin.LOCAL_WORLD_ALIGNED)
    return float(np.linalg.svd(J[:, MOUNT], compute_uv=False)[-1])


def _angle_gap(a, b) -> np.ndarray:
    return np.abs(np.remainder(a - b + np.pi, 2 * np.pi) - np.pi)


def _urdf(degrees) -> np.ndarray:
    """The preset's configuration (nq,) (the ranges' middle, the robot's joints set) where the robot's joints are
    at the URDF's angles ``degrees`` (6,): the preset states its twists at the rest pose :data:`KR210_REST_DEG`,
    its joint values are the URDF's less those."""
    q = 0.5 * (ROBOT.lower + ROBOT.upper)
    q[MOUNT] = np.radians(np.asarray(degrees, dtype=float) - KR210_REST_DEG)
    return q


def kr210_class(lengths, rest_deg, origin=ROBOT.mount.base_origin, turn=0.0):
    """A robot of the KR 210's class on the preset: the URDF's axes at its zero (:data:`KR210`) through points
    set by ``lengths`` (m: shoulder offset, shoulder height, upper arm, elbow offset, forearm, flange) with the
    arm stretched out as the URDF states it, the twists stated at the rest pose ``rest_deg`` (the URDF's angles:
    each carried by the motion of the joints below it to there) and each range the URDF's less its rest angle;
    its base at ``origin`` (frame 0) turned by ``turn`` (rad) about the vertical."""
    a, h, upper, elbow, fore, flange = lengths
    points = [(0.0, 0.0, h), (a, 0.0, h), (a + upper, 0.0, h), (a + upper + fore, 0.0, h + elbow),
              (a + upper + fore, 0.0, h + elbow), (a + upper + fore + flange, 0.0, h + elbow)]
    rest = np.radians(rest_deg)
    zero = [MountJoint(j.name, False, axis, p, carmkin.JointRange(np.radians(lo), np.radians(hi), j.name))
            for j, (axis, _, (lo, hi)), p in zip(ROBOT.mount.joints, KR210, points)]
    carried = np.concatenate((np.eye(4)[None], partial_chains(tuple(zero), rest)[:-1]))  # G_{i-1}(rest)
    joints = tuple(dataclasses.replace(j.moved(G), range=carmkin.JointRange(j.range.lower - r, j.range.upper - r,
                                                                              j.name))
                   for j, G, r in zip(zero, carried, rest))
    geometry = dataclasses.replace(ROBOT.mount, joints=joints, base_origin=origin,
                                   base_x_axis=(np.cos(turn), 0.0, np.sin(turn)))
    return ROBOT.replace(mount=geometry)


def _on_grid(degrees: float) -> float:
    """An angle (deg) on a 1e-6° grid. Pinocchio's URDF parser takes an axis within 1e-12 of a coordinate axis
    for that axis (Eigen's isApprox): its model, the oracle here, would then move 1e-12 away from the one
    stated. Turned by angles of the grid, an axis is on a coordinate axis or 1.7e-8 rad from it."""
    return round(degrees, 6)


@st.composite
def robots(draw):
    """KR 210 class robots: the preset's, its base placed anywhere on the floor and turned about the vertical,
    its link lengths changed (shoulder offset, upper arm, elbow offset, forearm, flange), the structure kept,
    its twists stated at any rest pose within the URDF's ranges (the preset's, or drawn: the URDF's own zero
    of A1, A3 to A6 with the arm stretched out, the wrist singular at rest, ...)."""
    lengths = (draw(st.floats(0.0, 0.6, **finite)), draw(st.floats(0.3, 1.0, **finite)),
               draw(st.floats(0.6, 1.6, **finite)), draw(st.floats(-0.3, 0.3, **finite)),
               draw(st.floats(0.6, 1.6, **finite)), draw(st.floats(0.1, 0.4, **finite)))
    # each rest angle within the URDF's range, and so that the range less it stays within a turn each way
    rest = draw(st.sampled_from([KR210_REST_DEG]) | st.tuples(*(
        st.floats(max(lo, hi - 360.0), min(hi, lo + 360.0), **finite).map(_on_grid) for _, _, (lo, hi) in KR210)))
    turn = np.radians(draw(st.floats(-180.0, 180.0, **finite).map(_on_grid)))
    origin = (draw(st.floats(-3.0, -1.5, **finite)), 1.2, draw(st.floats(-1.0, 1.0, **finite)))
    return kr210_class(lengths, rest, origin, turn)


def _check_solutions(system, q, result) -> None:
    T = _pinocchio_pose(system, q)
    assert result.reachable.any() and result.success
    for k in np.flatnonzero(result.reachable):
        np.testing.assert_allclose(_pinocchio_pose(system, result.solutions[k]), T, rtol=0, atol=FK_AGREEMENT)
    for k in np.flatnonzero(result.within_limits):
        s = result.solutions[k]
        assert np.all(s >= system.lower - JOINT_RANGE_TOLERANCE) and np.all(s <= system.upper + JOINT_RANGE_TOLERANCE)
    # the configuration the pose came from is one of the branches, within limits, and nearest q_current (itself),
    # wherever the joints are determined by the pose (the robot's Jacobian, by Pinocchio, well conditioned)
    if _smallest_singular_value(system, q) > WELL_CONDITIONED:
        gaps = _angle_gap(result.solutions[:, MOUNT], q[MOUNT]).max(axis=1)
        assert np.nanmin(gaps) <= SAME_CONFIGURATION
        assert np.abs(result.q - q).max() <= SAME_CONFIGURATION
    # the held joints are held
    held = np.r_[0, 7:system.nq]
    np.testing.assert_array_equal(result.solutions[result.reachable][:, held],
                                  np.broadcast_to(q[held], (int(result.reachable.sum()), len(held))))


@settings(max_examples=150, deadline=None)
@given(st.data())
def test_every_branch_gives_the_pose_back_by_pinocchio(data):
    q = data.draw(configurations(ROBOT))
    _check_solutions(ROBOT, q, mount.solve(ROBOT, _pinocchio_pose(ROBOT, q), q_current=q))


@settings(max_examples=40, deadline=None)
@given(robots(), st.data())
def test_any_robot_of_the_class_anywhere_on_the_floor(system, data):
    q = data.draw(configurations(system))
    _check_solutions(system, q, mount.solve(system, _pinocchio_pose(system, q), q_current=q))


def test_an_arm_stretched_straight_at_the_edge_of_its_reach_is_reached():
    """The upper arm and forearm in line (no elbow offset, A3 at the URDF's 0): the wrist centre at the edge of
    the reach, a double root of the elbow whose discriminant round-off leaves a few ulp below 0. Every such pose
    drawn from a configuration is reached, wherever the rest pose puts the stretch (at the twists' rest, or
    not), and its branches give it back by Pinocchio."""
    rng = np.random.default_rng(41)
    for rest in ((0.0, -90.0, 0.0, 0.0, 0.0, 0.0), KR210_REST_DEG):
        system = kr210_class((0.0, 1.0, 1.0, 0.0, 1.0, 0.25), rest, origin=(-2.0, 1.2, 0.0), turn=2.0)
        for i in range(20):
            q = 0.5 * (system.lower + system.upper)
            q[MOUNT] = 0.0 if i == 0 else system.lower[MOUNT] + rng.random(6) * (system.upper - system.lower)[MOUNT]
            q[3] = -np.radians(rest[2])  # A3 at the URDF's 0: stretched
            _check_solutions(system, q, mount.solve(system, _pinocchio_pose(system, q), q_current=q))


def test_the_strategys_robot_at_the_urdfs_lengths_and_the_presets_rest_is_the_preset():
    """kr210_class (the hypothesis strategy's robots) carries the URDF to a rest pose as the preset does: at the
    URDF's lengths and the preset's rest pose it is the preset's robot (twists and ranges)."""
    lengths = (0.33, 0.645, 1.35, 0.115, 1.42, 0.24)  # kr210_r3100-2_macro.xacro (KR210's points)
    system = kr210_class(lengths, KR210_REST_DEG)
    for built, preset in zip(system.mount.joints, ROBOT.mount.joints):
        np.testing.assert_allclose(built.axis, preset.axis, rtol=0, atol=1e-12)
        np.testing.assert_allclose(built.point, preset.point, rtol=0, atol=1e-12)
        assert built.range.lower == pytest.approx(preset.range.lower, abs=1e-12)
        assert built.range.upper == pytest.approx(preset.range.upper, abs=1e-12)


def test_branch_count_shoulder_elbow_wrist():
    """A wrist centre near the robot's base (the arm folded) has all eight branches, pairwise distinct, each a
    different (shoulder, elbow, wrist) choice; the wrist flip keeps joints 1–3 and turns A5 to −A5 (the URDF's
    angles: A5 = 0 puts axes 4 and 6 in line). Far out, only the shoulder in front reaches: four."""
    far = _urdf([10.0, -80.0, 30.0, 20.0, 40.0, -30.0])
    assert mount.solve(ROBOT, _pinocchio_pose(ROBOT, far), q_current=far).reachable.sum() == 4
    q = _urdf([10.0, -100.0, 60.0, 20.0, 40.0, -30.0])
    result = mount.solve(ROBOT, _pinocchio_pose(ROBOT, q), q_current=q)
    assert result.reachable.sum() == mount.BRANCHES == 8
    angles = result.solutions[:, MOUNT]
    for i in range(8):
        for j in range(i + 1, 8):
            assert _angle_gap(angles[i], angles[j]).max() > 1e-3
    a5 = angles[:, 4] + np.radians(KR210_REST_DEG[4])  # the URDF's A5
    for k in range(0, 8, 2):  # branch 4·shoulder + 2·elbow + wrist
        np.testing.assert_allclose(angles[k, :3], angles[k + 1, :3], atol=1e-12)
        assert _angle_gap(a5[k], -a5[k + 1]) <= 1e-12
    assert result.within_limits.sum() >= 2


def test_a_wrist_singular_pose_keeps_the_reference_of_axis_4():
    """The URDF's A5 = 0 puts axes 4 and 6 in line: a4 keeps q_current's value, a6 takes the rest, the pose is
    met."""
    q = _urdf([-20.0, -60.0, 10.0, 35.0, 0.0, 50.0])
    result = mount.solve(ROBOT, _pinocchio_pose(ROBOT, q), q_current=q)
    _check_solutions(ROBOT, q, result)
    assert abs(result.q[4] - q[4]) <= 1e-12


def test_batch_agrees_with_one_pose_at_a_time():
    rng = np.random.default_rng(5)
    Q = ROBOT.lower + (ROBOT.upper - ROBOT.lower) * rng.random((30, ROBOT.nq))
    out = mount.branches(ROBOT, ROBOT.fk(Q), Q)
    for k in range(len(Q)):
        one = mount.solve(ROBOT, ROBOT.fk(Q[k]), q_current=Q[k])
        np.testing.assert_array_equal(out.reachable[k], one.reachable)
        np.testing.assert_array_equal(out.within_limits[k], one.within_limits)
        # the same angles (a representative 2π apart where two in range are equally near the reference)
        # to round-off over the Jacobian's smallest singular value (a pose near a wrist singularity leaves a4 - a6
        # loosely determined: one drawn 0.02° from it has 1e-4)
        reached = one.reachable
        atol = max(1e-12, POSE_ROUNDOFF / _smallest_singular_value(ROBOT, Q[k]))
        np.testing.assert_allclose(_angle_gap(out.q[k][reached], one.solutions[reached]), 0.0, rtol=0, atol=atol)


@pytest.mark.parametrize("position", [(10.0, 0.0, 0.0), (0.0, -6.0, 0.0), (-2.2, 1.2, 6.0)])
def test_a_pose_out_of_reach_is_reported_not_raised(position):
    """Source poses whose wrist centre lies beyond the arm (10 m away, 6 m up, 6 m along the table from the
    robot): a result without a solution and its reason."""
    T = ROBOT.fk(0.5 * (ROBOT.lower + ROBOT.upper))
    T[:3, 3] = position
    result = mount.solve(ROBOT, T)
    assert not result.reachable.any() and not result.within_limits.any()
    assert not result.success and result.q is None and "out of reach" in result.reason
    assert np.isnan(result.solutions[:, MOUNT]).all()


def test_a_pose_reachable_only_out_of_range_names_the_joints():
    q = _urdf([10.0, -80.0, 30.0, 20.0, 40.0, -30.0])
    limited = ROBOT.mount.joints[1]
    tight = dataclasses.replace(limited, range=carmkin.JointRange(-0.01, 0.01, limited.name))
    system = ROBOT.replace(mount=dataclasses.replace(ROBOT.mount, joints=(ROBOT.mount.joints[0], tight)
                                                     + ROBOT.mount.joints[2:]))
    result = mount.solve(system, _pinocchio_pose(ROBOT, q), q_current=q)
    assert result.reachable.any() and not result.within_limits.any()
    assert "robot_a2" in result.reason


@pytest.mark.parametrize("T", ["pose", np.eye(3), np.full((4, 4), np.nan), np.diag([2.0, 1.0, 1.0, 1.0]),
                               [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]], 1j * np.eye(4)])
def test_a_junk_pose_is_a_typed_error(T):
    with pytest.raises(InvalidPoseError, match="T"):
        mount.solve(ROBOT, T)


@pytest.mark.parametrize("q_current", ["q", np.zeros(6), np.full(12, np.nan), [True] * 12])
def test_a_junk_q_current_is_a_typed_error(q_current):
    with pytest.raises(InvalidConfigurationError, match="q_current"):
        mount.solve(ROBOT, np.eye(4), q_current=q_current)


def test_systems_without_such_a_mount_are_refused_naming_why():
    with pytest.raises(UnsupportedMountError, match="0 mount joint"):
        mount.solve(carmkin.load_preset("siremobile-iso-c3d"), np.eye(4))
    with pytest.raises(UnsupportedMountError, match="CArmSystem"):
        mount.solve("robotic-carm", np.eye(4))
    joints = list(ROBOT.mount.joints)
    a6 = joints[5]
    joints[5] = MountJoint(a6.name, False, a6.axis, (a6.point[0], 0.1, a6.point[2]), a6.range)  # off the wrist
    with pytest.raises(UnsupportedMountError, match="meet in one point"):
        mount.solve(ROBOT.replace(mount=dataclasses.replace(ROBOT.mount, joints=tuple(joints))), np.eye(4))
    joints = list(ROBOT.mount.joints)
    joints[2] = MountJoint(joints[2].name, False, (0.0, 0.0, 1.0), joints[2].point, joints[2].range)
    with pytest.raises(UnsupportedMountError, match="not parallel"):
        mount.solve(ROBOT.replace(mount=dataclasses.replace(ROBOT.mount, joints=tuple(joints))), np.eye(4))
    assert issubclass(UnsupportedMountError, CarmkinError)


def test_with_a_world_the_nearest_branch_clear_of_the_margin_is_chosen():
    """Poses of random configurations with the patient on the table: the branch chosen is, of the branches within
    limits whose every pair (coal on all of them, World.distances) keeps the margin, the nearest q_current."""
    from carmkin.patient import ParametricPatient
    from carmkin.world import World

    world = World(ROBOT, ParametricPatient().on_table(ROBOT))
    rng = np.random.default_rng(4)
    span = ROBOT.upper - ROBOT.lower
    margin, contact, chosen = carmkin.DEFAULT_MARGIN, 0, 0
    for _ in range(25):
        q = ROBOT.lower + rng.random(ROBOT.nq) * span
        ref = ROBOT.lower + rng.random(ROBOT.nq) * span
        ref[np.r_[0, 7:ROBOT.nq]] = q[np.r_[0, 7:ROBOT.nq]]
        result = mount.solve(ROBOT, ROBOT.fk(q), q_current=ref, world=world, margin=margin)
        clear = np.array([result.within_limits[k] and world.distances(q=result.solutions[k]).min() >= margin
                          for k in range(8)])
        contact += bool(result.within_limits.any() and not clear.all())
        if not clear.any():
            assert not result.success and result.reason
            continue
        cost = np.where(clear, np.nansum(np.abs((result.solutions - ref) / np.maximum(span, 1e-9)), axis=1), np.inf)
        assert result.chosen == int(np.argmin(cost))
        chosen += 1
        np.testing.assert_allclose(result.clearance[result.within_limits],
                                   [world.distances(q=s).min() for s in result.solutions[result.within_limits]],
                                   rtol=0, atol=1e-5)
    assert chosen >= 5 and contact >= 1  # the test saw both: a choice, and a branch the clearance ruled out


@pytest.mark.parametrize("kwargs", [{"world": "world"}, {"world": object()}, {"margin": -0.1}, {"margin": "1"},
                                    {"margin": np.nan}])
def test_a_junk_world_or_margin_is_a_typed_error(kwargs):
    with pytest.raises(InvalidConfigurationError, match=next(iter(kwargs))):
        mount.solve(ROBOT, np.eye(4), **kwargs)
