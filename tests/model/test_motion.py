"""Move durations: the trapezoidal (or triangular) profile per joint, checked by hand and by its properties;
synchronized, joint-by-joint and path durations; the sweep speed check; bad input gets a typed error."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import carmkin
from carmkin.errors import CarmkinError, InvalidParameterError, MotionError
from carmkin.model.motion import (
    MAX_RATE,
    MIN_RATE,
    NO_SPEEDS,
    Follow,
    JointMotion,
    Motion,
    Timing,
    follow,
    joint_time,
    move_duration,
    path_duration,
    system_move,
    velocity_profile,
)

DEG = math.pi / 180
MM = 1e-3

#: Two joints: an orbital rotation (10°/s, 20°/s²) and a vertical lift (50 mm/s, 100 mm/s²).
TWO = Motion.of(["vertical", "orbital"], [50 * MM, 10 * DEG], [100 * MM, 20 * DEG])


# --- by hand: t = d/v + v/a (trapezoid, d ≥ v²/a), t = 2√(d/a) (triangle), t = d/v (speed only) ---------

def test_trapezoid_by_hand():
    # 90° at 10°/s with 20°/s²: v²/a = 5° ≤ 90°, t = 90/10 + 10/20 = 9 + 0.5 s
    assert joint_time(90 * DEG, 10 * DEG, 20 * DEG) == pytest.approx(9.5, rel=1e-12)


def test_triangle_by_hand():
    # 2° at 10°/s with 20°/s²: v²/a = 5° > 2°, never at full speed: t = 2 √(2/20) = 0.632455... s
    assert joint_time(2 * DEG, 10 * DEG, 20 * DEG) == pytest.approx(2 * math.sqrt(0.1), rel=1e-12)


def test_prismatic_and_speed_only_by_hand():
    # 100 mm at 50 mm/s with 100 mm/s²: 2 + 0.5 s; without an acceleration 100/50 = 2 s
    assert joint_time(0.1, 0.05, 0.1) == pytest.approx(2.5, rel=1e-12)
    assert joint_time(-0.1, 0.05) == pytest.approx(2.0, rel=1e-12)


def test_synchronized_joint_by_joint_and_path_by_hand():
    q0, q1 = np.zeros(2), np.array([0.1, 90 * DEG])  # vertical 2.5 s, orbital 9.5 s (above)
    sync = move_duration(TWO, q0, q1)
    assert sync.seconds == pytest.approx(9.5) and sync.slowest == "orbital" and sync.timing is Timing.SYNCHRONIZED
    assert move_duration(TWO, q0, q1, Timing.JOINT_BY_JOINT).seconds == pytest.approx(12.0)
    # path: there (9.5 s), then orbital back by 2° (0.632 s): each segment from rest to rest
    path = path_duration(TWO, [q0, q1, q1 - [0, 2 * DEG]])
    assert path.seconds == pytest.approx(9.5 + 2 * math.sqrt(0.1)) and len(path.parts) == 2


def test_the_preset_orbital_scan_by_hand():
    """The Iso-C 3D's 190° orbital arc at 190°/120 s (the preset's source) and 5°/s²: 120 + 1.5833/5 s."""
    system = carmkin.load_preset("siremobile-iso-c3d")
    q0 = np.zeros(system.nq)
    q0[-1] = -95 * DEG
    q1 = q0.copy()
    q1[-1] = 95 * DEG
    assert system_move(system, q0, q1).seconds == pytest.approx(120 + (190 / 120) / 5, rel=1e-9)


# --- properties -----------------------------------------------------------------------------------------

rates = st.floats(1e-3, 10.0)
distances = st.floats(0.0, 10.0)


@settings(max_examples=60)
@given(distances, distances, rates, rates)
def test_monotone_in_distance(d1, d2, v, a):
    lo, hi = sorted((d1, d2))
    assert joint_time(lo, v, a) <= joint_time(hi, v, a)


@settings(max_examples=60)
@given(distances, rates, rates)
def test_symmetric_and_at_least_distance_over_speed(d, v, a):
    t = joint_time(d, v, a)
    assert t == joint_time(-d, v, a)
    assert t >= d / v * (1 - 1e-12)
    # and at most the trapezoid through the switch: d/v + v/a
    assert t <= (d / v + v / a) * (1 + 1e-12)


@settings(max_examples=60)
@given(rates, rates, st.floats(1e-9, 1e-4))
def test_continuous_at_the_switch(v, a, eps):
    """Triangle below d = v²/a, trapezoid above; both give 2v/a at the switch."""
    switch = v * v / a
    below, above = joint_time(switch * (1 - eps), v, a), joint_time(switch * (1 + eps), v, a)
    assert below == pytest.approx(2 * v / a, rel=2 * eps) and above == pytest.approx(2 * v / a, rel=2 * eps)


@settings(max_examples=30)
@given(st.lists(st.floats(-3.0, 3.0), min_size=2, max_size=2), st.lists(st.floats(-3.0, 3.0), min_size=2, max_size=2))
def test_move_symmetric_and_the_slowest_joint(a, b):
    there, back = move_duration(TWO, a, b), move_duration(TWO, b, a)
    assert there.seconds == back.seconds
    assert there.seconds == max(j.time(y - x) for j, x, y in zip(TWO.joints, a, b))


@settings(max_examples=30)
@given(st.lists(st.floats(-3.0, 3.0), min_size=2, max_size=2).filter(lambda d: max(map(abs, d)) > 1e-3))
def test_velocity_profile_reaches_the_goal_within_the_limits(delta):
    """The synchronized profiles (an independent check of the timing): every joint ends at rest at T, never
    above its speed, never changing speed faster than its acceleration, and integrates to its move."""
    q0, q1 = np.zeros(2), np.array(delta)
    T = move_duration(TWO, q0, q1).seconds
    t = np.linspace(0.0, T, 20001)
    v = velocity_profile(TWO, q0, q1, t)
    speeds = np.array([j.speed for j in TWO.joints])
    accels = np.array([j.acceleration for j in TWO.joints])
    assert np.all(np.abs(v) <= speeds * (1 + 1e-9))
    assert np.all(np.abs(np.diff(v, axis=0)) <= accels * (t[1] - t[0]) * (1 + 1e-6))
    assert np.allclose(v[0], 0) and np.allclose(v[-1], 0, atol=1e-9)
    displacement = np.trapezoid(v, t, axis=0) if hasattr(np, "trapezoid") else np.trapz(v, t, axis=0)
    assert np.allclose(displacement, q1 - q0, atol=1e-6 * max(1.0, T))


#: Any speed or acceleration of the documented range [MIN_RATE, MAX_RATE] (log-uniform), and a move's distance.
documented_rates = st.floats(math.log10(MIN_RATE), math.log10(MAX_RATE)).map(
    lambda e: min(max(10.0 ** e, MIN_RATE), MAX_RATE))
moves = st.floats(-10.0, 10.0).filter(lambda d: d == 0.0 or abs(d) > 1e-9)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(documented_rates, documented_rates | st.none(), moves), min_size=1, max_size=3)
       .filter(lambda js: any(d != 0.0 for _, _, d in js)))
def test_velocity_profile_over_the_documented_rates_stays_below_the_speeds_and_integrates_to_the_move(joints):
    """Issue 41 (fuzz, MED): ½(aT − √((aT)² − 4ad)) lost the cruise speed to cancellation: peaks 1.4e-3 above
    the speed limit and profiles 6.5 % off the move. Every joint: never above its speed (no tolerance), a
    trapezoid of slope a whose area pT − p²/a (p its peak, in 50-digit decimals) is the move, and a trapezoidal
    quadrature of the sampled profile within its error bound (2 kinks · peak · dt each) of the move."""
    from decimal import Decimal, localcontext

    motion = Motion.of([f"j{k}" for k in range(len(joints))], [v for v, _, _ in joints], [a for _, a, _ in joints])
    q0, q1 = np.zeros(len(joints)), np.array([d for _, _, d in joints])
    T = move_duration(motion, q0, q1).seconds
    n = 20001
    t = np.linspace(0.0, T, n)
    profile = velocity_profile(motion, q0, q1, t)
    peak = np.abs(velocity_profile(motion, q0, q1, [T / 2])[0])
    for k, (speed, accel, d) in enumerate(joints):
        assert np.all(np.abs(profile[:, k]) <= speed), (k, np.abs(profile[:, k]).max() / speed - 1)
        assert peak[k] <= speed
        assert np.all(np.sign(profile[:, k]) * np.sign(d) >= 0)
        if d == 0.0:
            assert not profile[:, k].any()
            continue
        with localcontext() as context:
            context.prec = 50
            p, TT = Decimal(float(peak[k])), Decimal(T)
            area = p * TT - (p * p / Decimal(accel) if accel is not None else 0)
            assert abs(float(area) - abs(d)) <= 1e-11 * abs(d), (float(area), d)
        dt = T / (n - 1)
        quadrature = abs(float(np.sum((profile[1:, k] + profile[:-1, k]) * 0.5) * dt))
        assert abs(quadrature - abs(d)) <= 4 * peak[k] * dt + 1e-12 * abs(d)


# --- the sweep speed check ------------------------------------------------------------------------------

ORBITAL = Motion.of(["orbital"], [190 / 120 * DEG], [5 * DEG])
ARC = np.linspace(-95, 95, 100)[:, None] * DEG  # 100 views over 190°, 99 steps of 1.919°


def test_a_sweep_the_joints_follow():
    check = follow(ORBITAL, ARC, 150.0)
    # 190° in 150 s: 1.2667°/s of 1.5833°/s = 80 %
    assert check.status is Follow.FOLLOWS and check.joint == "orbital" and check.quantity == "speed"
    assert check.ratio == pytest.approx(120 / 150)
    assert check.minimum_time == pytest.approx(120.0)
    # run-up and stop: 1.2667°/s at 5°/s² = 0.2533 s each
    assert check.duration == pytest.approx(150 + 2 * (190 / 150) / 5)


def test_a_sweep_too_fast_for_the_joints():
    check = follow(ORBITAL, ARC, 60.0, prismatic=[False])
    assert check.status is Follow.TOO_FAST and check.joint == "orbital" and check.quantity == "speed"
    assert check.ratio == pytest.approx(2.0)  # twice its speed: 3.1667°/s of 1.5833°/s
    assert "orbital needs speed 3.17 °/s, its limit is 1.58 °/s (2.00x)" in str(check)


def test_a_sweep_too_fast_for_the_acceleration():
    # views at 0, 0, 1°: over 2 s the speed jumps from 0 to 1°/s in 1 s: 1°/s² of 0.5°/s² (twice)
    motion = Motion.of(["orbital"], [10 * DEG], [0.5 * DEG])
    check = follow(motion, np.array([[0.0], [0.0], [1.0 * DEG]]), 2.0)
    assert check.status is Follow.TOO_FAST and check.quantity == "acceleration"
    assert check.ratio == pytest.approx(2.0)
    assert check.minimum_time == pytest.approx(2 * math.sqrt(2))  # Δt ≥ √(1/0.5) s, two steps


def test_no_speeds_is_data():
    assert follow(None, ARC, 60.0).status is Follow.NO_SPEEDS
    system = carmkin.load_preset("siremobile-iso-c3d").replace(motion=None)
    duration = system_move(system, np.zeros(6), np.ones(6) * 0.1)
    assert duration.seconds is None and duration.reason == NO_SPEEDS


# --- bad input ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("speed", [0.0, -1.0, math.nan, math.inf, True, "1", 1e9])
def test_bad_speed_names_the_joint(speed):
    with pytest.raises(MotionError, match="orbital speed"):
        JointMotion(speed, 1.0, "orbital")


@pytest.mark.parametrize("acceleration", [0.0, -2.0, math.nan, math.inf])
def test_bad_acceleration_names_the_joint(acceleration):
    with pytest.raises(MotionError, match="wigwag acceleration"):
        JointMotion(1.0, acceleration, "wigwag")


def test_bad_moves_and_motions():
    with pytest.raises(MotionError, match="twice"):
        Motion.of(["a", "a"], [1.0, 1.0])
    with pytest.raises(MotionError, match="q_to"):
        move_duration(TWO, np.zeros(2), np.zeros(3))
    with pytest.raises(MotionError, match="q_from"):
        move_duration(TWO, [0.0, math.nan], np.zeros(2))
    with pytest.raises(MotionError, match="acquisition_time_s"):
        follow(ORBITAL, ARC, 0.0)
    with pytest.raises(MotionError, match="two views"):
        follow(ORBITAL, ARC[:1], 10.0)
    with pytest.raises(MotionError, match="motion must be"):
        move_duration(None, np.zeros(2), np.zeros(2))
    assert issubclass(MotionError, CarmkinError)


def test_system_motion_must_name_its_joints():
    system = carmkin.load_preset("siremobile-iso-c3d")
    with pytest.raises(InvalidParameterError, match="CArmSystem.motion"):
        system.replace(motion=TWO)
    # a table with new joints keeps the speeds by name, or none when a joint has none
    motorized = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
    assert system.replace(table=motorized.table).motion is None
    assert motorized.replace(table=system.table).motion == motorized.motion.for_joints(system.joint_names)
