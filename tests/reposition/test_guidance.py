"""Guidance: reading joints off poses, the swept collision check, moves one joint at a time to the goal."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import carmkin
from carmkin.reposition import guidance
from carmkin.robot import validity
from carmkin.world import World

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")
MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
SCENE = World(SYSTEM)
finite = dict(allow_nan=False, allow_infinity=False)
#: coal's GJK distances between boxes repeat only to ~1e-6 m (measured: 1.4e-6 m for the same q twice).
DISTANCE_NOISE = 1e-5


def in_range(system, data):
    return np.array([data.draw(st.floats(lo, hi, **finite)) for lo, hi in zip(system.lower, system.upper)])


@given(st.data())
def test_read_joints_inverts_the_fk(data):
    for system in (SYSTEM, MOTORIZED):
        q = in_range(system, data)
        nearby = q + data.draw(st.floats(-0.01, 0.01, **finite))
        read = guidance.read_joints(system, system.fk(q), nearby, q_table=system.split(q)[1])
        np.testing.assert_allclose(system.fk(read), system.fk(q), atol=1e-9)
        np.testing.assert_allclose(read, q, atol=1e-7)


def dense_min_distance(q0, q1, samples=400):
    return min(validity.check(SYSTEM, q0 + t * (q1 - q0), world=SCENE).min_distance
               for t in np.linspace(0.0, 1.0, samples))


def test_sweep_finds_a_collision_between_two_clear_ends():
    # raise the arm to the top with the C turned 90° about the orbital axis: the path of the angular joint
    # from -60° to +60° passes through the table although both ends are clear
    q0 = np.array([0.0, 0.4, 0.0, 0.1, math.radians(-100), 0.0])
    q1 = q0.copy()
    q1[4] = math.radians(100)
    ends = [validity.check(SYSTEM, q, world=SCENE).min_distance for q in (q0, q1)]
    middle = dense_min_distance(q0, q1)
    assert min(ends) > 0.005 and middle < 0.0, (ends, middle)
    result = SCENE.swept(q0, q1, margin=0.005, stop_at_contact=True)
    assert not result.clear


@settings(max_examples=40)  # each example checks 100 configurations densely
@given(st.data())
def test_a_clear_sweep_is_clear_everywhere(data):
    q0 = in_range(SYSTEM, data)
    j = data.draw(st.integers(0, SYSTEM.nq - 1))
    q1 = q0.copy()
    q1[j] = data.draw(st.floats(SYSTEM.lower[j], SYSTEM.upper[j], **finite))
    result = SCENE.swept(q0, q1, margin=0.005, stop_at_contact=True)
    if result.clear:
        assert dense_min_distance(q0, q1, 100) >= 0.005 - DISTANCE_NOISE


def test_exact_guidance_reaches_the_goal_one_joint_at_a_time():
    q_start = np.zeros(6)
    q_goal = np.array([0.1, 0.1, math.radians(5), 0.12, math.radians(15), math.radians(-10)])
    guide = guidance.Guide(SYSTEM, SYSTEM.fk(q_goal), q_start)
    q, moved = q_start, []
    for _ in range(10):
        step = guide.step(SYSTEM.fk(q))
        if step.done:
            break
        assert step.sweep.clear and step.blocked is None
        moved.append(step.joint)
        q = q.copy()
        q[step.joint] += step.move
    assert step.done
    np.testing.assert_allclose(q, q_goal, atol=1e-7)
    assert len(moved) == len(set(moved)) <= 6  # each joint once


def test_each_guidance_move_and_what_remains_are_timed():
    """Each step moves one joint from rest to rest: t = d/v + v/a, or 2√(d/a) when short (by hand); the
    remaining moves add up, one joint after another; the step times add up to the first step's remaining."""
    def by_hand(j, d):
        d = abs(d)
        return d / j.speed + j.speed / j.acceleration if d >= j.speed ** 2 / j.acceleration \
            else 2 * math.sqrt(d / j.acceleration)

    q_start = np.zeros(6)
    q_goal = np.array([0.1, 0.1, math.radians(5), 0.12, math.radians(15), math.radians(-10)])
    guide = guidance.Guide(SYSTEM, SYSTEM.fk(q_goal), q_start)
    q, total, first = q_start, 0.0, None
    for _ in range(10):
        step = guide.step(SYSTEM.fk(q))
        remaining = sum(by_hand(j, d) for j, d in zip(SYSTEM.motion.joints, step.remaining))
        assert step.remaining_duration.seconds == pytest.approx(remaining, rel=1e-9, abs=1e-9)
        first = remaining if first is None else first
        if step.done:
            break
        joint = SYSTEM.motion.joints[step.joint]
        assert step.duration.seconds == pytest.approx(by_hand(joint, step.move), rel=1e-12)
        assert step.duration.slowest == joint.name and str(step.duration).endswith(f"({joint.name} alone)")
        total += step.duration.seconds
        q = q.copy()
        q[step.joint] += step.move
    assert step.done and total == pytest.approx(first, rel=1e-6)


def test_motorized_table_guidance_uses_the_one_solve():
    q_start = np.zeros(MOTORIZED.nq)
    q_goal = q_start.copy()
    q_goal[MOTORIZED.joint_names.index("orbital")] = math.radians(10)
    q_goal[MOTORIZED.joint_names.index("table_height")] = 0.05
    guide = guidance.Guide(MOTORIZED, MOTORIZED.fk(q_goal), q_start)
    np.testing.assert_allclose(MOTORIZED.fk(guide.q_goal), MOTORIZED.fk(q_goal), atol=1e-6)
    q = q_start
    for _ in range(MOTORIZED.nq + 1):
        _, q_table = MOTORIZED.split(q)
        step = guide.step(MOTORIZED.fk(q), q_table=q_table)
        if step.done:
            break
        q = q.copy()
        q[step.joint] += step.move
    assert step.done
    np.testing.assert_allclose(MOTORIZED.fk(q), MOTORIZED.fk(q_goal), atol=1e-6)


def test_thresholds_stop_the_guidance():
    q = np.array([0.0, 0.1, 0.0, 0.1, 0.0, 0.0])
    near = q + np.array([0.0015, 0.0, math.radians(0.4), 0.0, 0.0, 0.0])
    guide = guidance.Guide(SYSTEM, SYSTEM.fk(near), q)
    assert guide.step(SYSTEM.fk(q)).done
    strict = guidance.Guide(SYSTEM, SYSTEM.fk(near), q, guidance.GuidanceOptions(translation_threshold=0.001))
    step = strict.step(SYSTEM.fk(q))
    assert not step.done and SYSTEM.joint_names[step.joint] == "table_translation"


@pytest.mark.parametrize("changes, match", [
    ({"translation_threshold": 0.0}, "translation_threshold"),
    ({"rotation_threshold": float("nan")}, "rotation_threshold"),
    ({"path_clearance": 0.02}, "path_clearance"),
    ({"order": ("vertical", "tilt")}, "unknown joint"),
])
def test_bad_options_raise(changes, match):
    with pytest.raises(guidance.GuidanceError, match=match):
        options = guidance.GuidanceOptions(**changes)
        options.move_order(SYSTEM)


def test_an_unreachable_reference_raises():
    T = SYSTEM.fk(np.zeros(6))
    T[:3, 3] += (0.0, 0.0, 5.0)  # 5 m along the table: beyond the translation range
    with pytest.raises(guidance.GuidanceError, match="no collision-free solution"):
        guidance.Guide(SYSTEM, T, np.zeros(6))


def _estimate(T, covariance, condition=100.0):
    from carmkin.reposition.pose import PoseEstimate

    return PoseEstimate(T, 0.25, np.asarray(covariance, float), 48, np.zeros((48, 2)), condition, 0.2)


def test_reading_covariance_agrees_with_monte_carlo():
    """Pose noise (ω, δp) drawn from a covariance, joints read off each noisy pose: their spread matches the
    linear propagation (loose: 400 samples, ratio of variances within [0.75, 1.33])."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(8)
    q = np.array([0.05, 0.08, 0.05, 0.1, 0.3, -0.2])
    T = SYSTEM.fk(q)
    sd = np.array([2e-3, 1.5e-3, 3e-4, 1e-3, 8e-4, 2e-4])
    A = rng.normal(size=(6, 6)) * 0.3 + np.eye(6)
    cov = (A * sd) @ (A * sd).T
    reads = []
    for x in rng.multivariate_normal(np.zeros(6), cov, 400):
        Tn = T.copy()
        Tn[:3, :3] = Rotation.from_rotvec(x[:3]).as_matrix() @ T[:3, :3]
        Tn[:3, 3] += x[3:]
        reads.append(guidance.read_joints(SYSTEM, Tn, q))
    ratio = np.var(np.array(reads), axis=0) / np.diag(guidance.reading_covariance(SYSTEM, q, cov))
    assert np.all((ratio > 0.75) & (ratio < 1.33)), ratio


def test_the_stop_rule_accounts_for_the_pose_uncertainty():
    q = np.array([0.0, 0.1, 0.0, 0.1, 0.0, 0.0])
    near = q + np.array([0.0015, 0.0, 0.0, 0.0, 0.0, 0.0])  # 1.5 mm of table translation left: below 2 mm
    position_sd = lambda mm: np.diag([1e-16] * 3 + [(mm * 1e-3) ** 2] * 3)  # noqa: E731
    guide = guidance.Guide(SYSTEM, SYSTEM.fk(near), q)
    assert guide.step(_estimate(SYSTEM.fk(q), np.zeros((6, 6)))).done  # exact estimate: the seed's rule
    assert guide.step(_estimate(SYSTEM.fk(q), position_sd(1.5))).done  # sd 1.5 mm <= the 2 mm threshold
    unresolved = guide.step(_estimate(SYSTEM.fk(q), position_sd(2.5)))  # sd 2.5 mm > the threshold
    assert not unresolved.done and unresolved.blocked and "too uncertain" in unresolved.blocked
    assert unresolved.sd[0] == pytest.approx(2.5e-3, rel=0.05)
    half = guidance.Guide(SYSTEM, SYSTEM.fk(near), q, guidance.GuidanceOptions(max_sd_fraction=0.5))
    assert "too uncertain" in half.step(_estimate(SYSTEM.fk(q), position_sd(1.5))).blocked
    strict = guidance.Guide(SYSTEM, SYSTEM.fk(near), q, guidance.GuidanceOptions(stop_sigmas=1.0))
    step = strict.step(_estimate(SYSTEM.fk(q), position_sd(0.8)))  # 1.5 mm + 0.8 mm > 2 mm: move again
    assert not step.done and SYSTEM.joint_names[step.joint] == "table_translation"
    flagged = guide.step(_estimate(SYSTEM.fk(q), np.zeros((6, 6)), condition=1e5))
    assert flagged.ill_conditioned and not flagged.done and "ill-conditioned" in flagged.blocked


@given(st.data())
def test_stop_rule_bound_bounds_the_source_displacement(data):
    """Every joint moved by its threshold, in any signs: the source moves at most the bound (+ 2nd order)."""
    options = guidance.GuidanceOptions()
    q = in_range(SYSTEM, data) * 0.9
    bound_m, bound_rad = guidance.stop_rule_bound(SYSTEM, q, options)
    signs = np.array([data.draw(st.sampled_from([-1.0, 1.0])) for _ in range(SYSTEM.nq)])
    moved = SYSTEM.fk(q + signs * options.thresholds(SYSTEM))
    from carmkin.reposition.calibration import rotation_angle

    assert np.linalg.norm(moved[:3, 3] - SYSTEM.fk(q)[:3, 3]) <= bound_m * 1.01 + 1e-6
    assert rotation_angle(moved[:3, :3], SYSTEM.fk(q)[:3, :3]) <= bound_rad * 1.01 + 1e-9
