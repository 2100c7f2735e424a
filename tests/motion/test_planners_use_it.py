"""The planners move the C-arm through the certified motion (issue 37): plan_view's motion from q_current,
plan_sweep's approach to its first frame; a start too close to something gets no motion and says why."""

from __future__ import annotations

import numpy as np

import carmkin
from carmkin.motion import END_TOLERANCE
from carmkin.patient import ParametricPatient
from carmkin.sweeps import plan_sweep
from carmkin.views import plan_view
from carmkin.views.plan import PATH_CLEARANCE
from carmkin.views.standard import standard_view

ISO = carmkin.load_preset("siremobile-iso-c3d")
PATIENT = ParametricPatient.on_table(ISO)


def test_plan_view_carries_the_certified_motion_from_q_current():
    q_current = np.array([0.0, 0.2, 0.0, 0.1, 0.0, 0.35])
    plan = plan_view(ISO, standard_view("lao-30"), PATIENT, q_current)
    assert plan.success and plan.motion.success
    np.testing.assert_array_equal(plan.motion.waypoints[0], q_current)
    np.testing.assert_array_equal(plan.motion.waypoints[-1], plan.q)
    assert plan.motion.min_clearance >= PATH_CLEARANCE - END_TOLERANCE
    assert plan_view(ISO, standard_view("lao-30"), PATIENT).motion is None  # no q_current, no motion
    assert plan_view(ISO, standard_view("lao-30"), PATIENT, q_current, motion_plan=False).motion is None


def test_a_start_in_contact_has_no_motion_and_says_why():
    q_current = np.zeros(ISO.nq)
    q_current[ISO.joint_names.index("angular")] = np.radians(90.0)  # the C through the table
    plan = plan_view(ISO, standard_view("ap"), PATIENT, q_current)
    assert plan.success and not plan.motion.success
    assert "q_from is not clear" in plan.motion.reason


def test_plan_sweep_plans_its_approach():
    q_start = np.array([0.0, 0.2, 0.0, 0.1, 0.0, -1.4])
    sweep = plan_sweep(ISO, np.zeros(3), 160, 30, patient=PATIENT, q_start=q_start)
    assert sweep.success and sweep.approach_motion.success
    np.testing.assert_allclose(sweep.approach_motion.waypoints[-1], sweep.q[0])
    assert sweep.approach_motion.min_clearance >= 0.5 * sweep.margin - END_TOLERANCE
    assert plan_sweep(ISO, np.zeros(3), 160, 30, patient=PATIENT).approach_motion is None
