"""plan_motion (issue 37): a returned trajectory keeps the margin at dense samples of its time law (0.05° / 0.05 mm
between samples, exact coal distances on every pair), stays within every joint's limits at 1 kHz, takes the
straight line when it is free (and then lasts exactly its time-optimal trapezoid), finds a way around when it is
not; bad input is a typed error naming the argument; a search that runs out of time says so."""

from __future__ import annotations

import math

import numpy as np
import pytest

import carmkin
from carmkin.errors import CarmkinError, MotionPlanError
from carmkin.motion import END_TOLERANCE, MotionPlanner, plan_motion, segment_law
from carmkin.patient import ParametricPatient
from carmkin.views import plan_view
from carmkin.views.standard import standard_view
from carmkin.world.tolerances import DISTANCE_ACCURACY

DENSE_ANGLE, DENSE_LENGTH = math.radians(0.05), 5e-5
ISO = carmkin.load_preset("siremobile-iso-c3d")
PATIENT = ParametricPatient.on_table(ISO)


@pytest.fixture(scope="module")
def planner():
    return MotionPlanner(ISO, PATIENT)


def view_q(system, name, patient):
    plan = plan_view(system, standard_view(name), patient=patient)
    assert plan.success, name
    return plan.q


def dense_check(planner, trajectory):
    """The smallest exact distance (m) at time-law samples no joint moves more than 0.05° / 0.05 mm between,
    and the largest speed and acceleration ratios to the limits at 1 kHz."""
    system = planner.system
    step = np.where(system.prismatic, DENSE_LENGTH, DENSE_ANGLE)
    # the time law follows the polyline: sample each segment densely in its path parameter, at the law's times
    smallest = math.inf
    for i in range(len(trajectory.waypoints) - 1):
        a, b = trajectory.waypoints[i], trajectory.waypoints[i + 1]
        # the path parameter's peak rate v bounds each joint's speed by |Δq_j| v: a time step of
        # min_j step_j / (|Δq_j| v) moves no joint more than its step
        rate = trajectory.law.segments[i].v * np.abs(b - a)
        dt = float(np.min(np.where(rate > 0, step / np.where(rate > 0, rate, 1.0), np.inf)))
        t = np.append(np.arange(trajectory.times[i], trajectory.times[i + 1], dt), trajectory.times[i + 1])
        q, _, _ = trajectory.sample(t)
        assert np.all(np.abs(np.diff(q, axis=0)) <= step * (1 + 1e-9))
        smallest = min(smallest, float(planner.world.clearance(q).min()))  # exact (branch and bound, coal)
    t = np.arange(0.0, trajectory.duration, 1e-3)
    _, qd, qdd = trajectory.sample(t)
    v = np.array([j.speed for j in system.motion.joints])
    acc = np.array([j.acceleration for j in system.motion.joints])
    return smallest, float((np.abs(qd) / v).max()), float((np.abs(qdd) / acc).max())


def test_a_free_straight_line_is_the_motion_and_time_optimal(planner):
    q_a, q_b = view_q(ISO, "lao-30", PATIENT), view_q(ISO, "rao-30", PATIENT)
    trajectory = planner.plan(q_a, q_b)
    assert trajectory.success and trajectory.method == "straight"
    assert trajectory.duration == pytest.approx(segment_law(ISO.motion, q_b - q_a).duration, rel=1e-12)
    smallest, speed, accel = dense_check(planner, trajectory)
    assert smallest >= planner.margin - END_TOLERANCE - DISTANCE_ACCURACY
    assert trajectory.min_clearance <= smallest + DISTANCE_ACCURACY
    assert speed <= 1 + 1e-9 and accel <= 1 + 1e-9


def test_a_blocked_line_is_planned_around_and_certified(planner):
    q_a, q_b = view_q(ISO, "lao-30", PATIENT), view_q(ISO, "lateral-right", PATIENT)
    assert not planner.certifier.segment(q_a, q_b, planner.world.distances(q=q_a).copy(),
                                         planner.world.distances(q=q_b).copy(), planner.margin).clear
    trajectory = planner.plan(q_a, q_b, time_limit_s=30.0)
    assert trajectory.success, trajectory.reason
    assert trajectory.method == "RRTConnect" and len(trajectory.waypoints) >= 3
    np.testing.assert_array_equal(trajectory.waypoints[0], q_a)
    np.testing.assert_array_equal(trajectory.waypoints[-1], q_b)
    smallest, speed, accel = dense_check(planner, trajectory)
    assert smallest >= planner.margin - END_TOLERANCE - DISTANCE_ACCURACY
    assert trajectory.min_clearance <= smallest + DISTANCE_ACCURACY
    assert speed <= 1 + 1e-9 and accel <= 1 + 1e-9


@pytest.mark.parametrize("name", ["siremobile-iso-c3d-motorized-table", "robotic-carm", "angio-ceiling", "cios-spin"])
def test_every_family_plans_between_random_clear_configurations(name):
    system = carmkin.load_preset(name)
    patient = ParametricPatient.on_table(system)
    planner = MotionPlanner(system, patient)
    rng = np.random.default_rng(7)
    ends = []
    while len(ends) < 2:
        q = rng.uniform(system.lower, system.upper)
        if planner.world.distances(q=q).min() >= planner.margin + 0.02:
            ends.append(q)
    trajectory = planner.plan(ends[0], ends[1], time_limit_s=5.0)
    if not trajectory.success:
        assert "not found within 5 s" in trajectory.reason
        return
    smallest, speed, accel = dense_check(planner, trajectory)
    assert smallest >= planner.margin - END_TOLERANCE - DISTANCE_ACCURACY
    assert speed <= 1 + 1e-9 and accel <= 1 + 1e-9
    assert trajectory.duration > 0 and len(trajectory.joint_names) == system.nq


def test_a_search_that_runs_out_of_time_does_not_claim_no_path(planner):
    q_a, q_b = view_q(ISO, "ap", PATIENT), view_q(ISO, "pa", PATIENT)
    trajectory = planner.plan(q_a, q_b, time_limit_s=0.05)
    assert not trajectory.success
    assert "not found within 0.05 s" in trajectory.reason and "does not prove" in trajectory.reason
    with pytest.raises(MotionPlanError, match="no time law"):
        trajectory.sample([0.0])


def test_bad_input_is_a_typed_error_naming_it(planner):
    q = view_q(ISO, "ap", PATIENT)
    far = q.copy()
    far[ISO.joint_names.index("orbital")] = math.radians(120.0)
    with pytest.raises(MotionPlanError, match=r"q_to: orbital = 120 ° is outside its range"):
        planner.plan(q, far)
    inside = np.zeros(ISO.nq)
    inside[ISO.joint_names.index("angular")] = math.radians(90.0)
    with pytest.raises(MotionPlanError, match=r"q_from is not clear of the 10 mm margin: \w+ is -?\d+\.\d mm from"):
        planner.plan(inside, q)
    for kwargs, name in (({"time_limit_s": -1}, "time_limit_s"), ({"time_limit_s": float("nan")}, "time_limit_s"),
                         ({"time_limit_s": 1e6}, "time_limit_s"), ({"planner": "rrt*"}, "planner")):
        with pytest.raises(MotionPlanError, match=name):
            planner.plan(q, q, **kwargs)
    with pytest.raises(MotionPlanError, match="q_from"):
        planner.plan(q[:3], q)
    with pytest.raises(CarmkinError, match="margin"):
        plan_motion(ISO, q, q, margin="wide")
    trajectory = planner.plan(q, q)
    assert trajectory.success and trajectory.duration == 0.0
    with pytest.raises(MotionPlanError, match=r"t must lie in \[0, 0\] s"):
        trajectory.sample([1.0])
