"""The time law (issue 37): sampled at 1 kHz no joint exceeds its speed or acceleration limit, the samples lie on
the planned polyline, and a straight segment's duration matches the time-optimal parameterization computed
independently (toppra, when installed; a single joint's trapezoid by hand otherwise)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import carmkin
from carmkin.model.motion import JointMotion, Motion
from carmkin.motion import TimeLaw

#: Relative slack on a limit at 1 kHz samples: round-off only.
LIMIT_SLACK = 1e-9
SYSTEMS = [carmkin.load_preset(n) for n in ("siremobile-iso-c3d", "robotic-carm", "angio-floor")]


def polylines(system, rng, k):
    return rng.uniform(system.lower, system.upper, (k + 1, system.nq))


@settings(max_examples=30, deadline=None, derandomize=True)
@given(which=st.integers(0, len(SYSTEMS) - 1), seed=st.integers(0, 2**31 - 1), k=st.integers(1, 4))
def test_limits_hold_at_1khz_and_samples_lie_on_the_polyline(which, seed, k):
    system = SYSTEMS[which]
    Q = polylines(system, np.random.default_rng(seed), k)
    law = TimeLaw(system.motion, Q)
    t = np.arange(0.0, law.duration, 1e-3)
    q, qd, qdd = law.sample(t)
    v = np.array([j.speed for j in system.motion.joints])
    a = np.array([j.acceleration for j in system.motion.joints])
    assert np.all(np.abs(qd) <= v * (1 + LIMIT_SLACK))
    assert np.all(np.abs(qdd) <= a * (1 + LIMIT_SLACK))
    q_end, qd_end, _ = law.sample([law.duration])
    np.testing.assert_allclose(q_end[0], Q[-1], atol=1e-12)
    np.testing.assert_allclose(qd_end[0], 0.0, atol=1e-12)
    # on the polyline: each sample is Q[i] + s (Q[i+1] - Q[i]) with s in [0, 1]
    which_seg = np.clip(np.searchsorted(law.times, t, side="right") - 1, 0, k - 1)
    delta = Q[which_seg + 1] - Q[which_seg]
    s = np.einsum("ij,ij->i", q - Q[which_seg], delta) / np.einsum("ij,ij->i", delta, delta)
    np.testing.assert_allclose(q, Q[which_seg] + s[:, None] * delta, atol=1e-9)
    assert s.min() >= -1e-12 and s.max() <= 1 + 1e-12
    # the speed integrates to the displacement (trapezoid rule on the 1 kHz samples)
    moved = np.trapezoid(qd, t, axis=0)
    np.testing.assert_allclose(moved, q[-1] - Q[0], atol=2e-3 * np.abs(Q[-1] - Q[0]).max() + 1e-6)


def test_one_joint_is_its_own_trapezoid():
    """One joint moving alone: the textbook trapezoid t = d/v + v/a (and the triangle 2 sqrt(d/a))."""
    motion = Motion((JointMotion(0.5, 1.0, "a"), JointMotion(2.0, 3.0, "b")))
    long = TimeLaw(motion, np.array([[0.0, 0.0], [2.0, 0.0]]))
    assert long.duration == pytest.approx(2.0 / 0.5 + 0.5 / 1.0, rel=1e-12)
    short = TimeLaw(motion, np.array([[0.0, 0.0], [0.0, 0.3]]))
    assert short.duration == pytest.approx(2.0 * math.sqrt(0.3 / 3.0), rel=1e-12)


@settings(max_examples=15, deadline=None, derandomize=True)
@given(which=st.integers(0, len(SYSTEMS) - 1), seed=st.integers(0, 2**31 - 1))
def test_straight_segment_is_time_optimal_against_toppra(which, seed):
    toppra = pytest.importorskip("toppra", reason="toppra (the test extra) is the independent time-optimal route")
    import toppra.algorithm as algo
    import toppra.constraint as constraint

    system = SYSTEMS[which]
    Q = polylines(system, np.random.default_rng(seed), 1)
    law = TimeLaw(system.motion, Q)
    v = np.array([j.speed for j in system.motion.joints])
    a = np.array([j.acceleration for j in system.motion.joints])
    path = toppra.SplineInterpolator([0.0, 0.5, 1.0], np.array([Q[0], Q.mean(axis=0), Q[1]]))
    instance = algo.TOPPRA([constraint.JointVelocityConstraint(np.stack((-v, v), axis=1)),
                            constraint.JointAccelerationConstraint(np.stack((-a, a), axis=1))], path,
                           gridpoints=np.linspace(0, 1, 1001), parametrizer="ParametrizeConstAccel")
    jnt = instance.compute_trajectory(0, 0)
    assert jnt is not None
    assert law.duration == pytest.approx(jnt.duration, rel=0.02)
