"""Planning two views at once (issue 30): a plan's two beams are what was asked — recomputed from each plane's
Pinocchio model, not from the planner's numbers —, the planes and the patient are clear of each other by the margin
(checked by an independent coal oracle), and a failure is typed."""

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from carmkin.biplane import Failure, lateral_view, load_biplane, plan_biplane
from carmkin.errors import BiplaneError, ViewError
from carmkin.patient import ParametricPatient
from carmkin.views import View
from carmkin.views.plan import DEFAULT_MARGIN
from carmkin.views.standard import STANDARD_VIEWS
from carmkin.world import World

from test_biplane import _oracle

BIPLANE = load_biplane("angio-biplane")
PATIENT = ParametricPatient.on_table(BIPLANE.frontal)
#: A planned beam's direction (rad) and its line's distance from the target (m): the view search solves in closed
#: form (to rounding, ~1e-12); a table joint held to JOINT_RANGE_TOLERANCE (1e-9) moves the lateral beam by as much.
ON_THE_BEAM = 1e-7
#: Two routes to one signed distance (m), coal's tolerance on either side.
SAME_DISTANCE = 1e-5


def _beam(system, q):
    """(source, unit direction) of a plane at q, from its Pinocchio model (table frame)."""
    model, _, _ = system.pinocchio()
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    T = data.oMf[model.getFrameId("xray_source")].homogeneous
    return T[:3, 3], T[:3, 2]


def _check_beam(system, q, view):
    source, direction = _beam(system, q)
    assert math.acos(min(1.0, float(direction @ view.axis))) <= ON_THE_BEAM
    offset = np.asarray(view.target) - source
    assert np.linalg.norm(offset - (offset @ direction) * direction) <= ON_THE_BEAM
    return direction


def _check_plan(plan, frontal, lateral, patient=PATIENT, margin=DEFAULT_MARGIN):
    q_f, q_l = BIPLANE.planes_q(plan.q)
    d_f = _check_beam(BIPLANE.frontal, q_f, frontal)
    d_l = _check_beam(BIPLANE.lateral, q_l, lateral)
    assert abs(math.acos(np.clip(d_f @ d_l, -1, 1)) - frontal.angle_to(lateral)) <= 2 * ON_THE_BEAM
    assert abs(plan.angle - frontal.angle_to(lateral)) <= 2 * ON_THE_BEAM
    # the planes: an oracle sharing none of the planner's code
    planes = _oracle(plan.q).min()
    assert planes >= margin - SAME_DISTANCE and plan.clearance == pytest.approx(planes, abs=SAME_DISTANCE)
    # each plane against table, floor and the patient: a fresh world of each plane
    for system, q in ((BIPLANE.frontal, q_f), (BIPLANE.lateral, q_l)):
        assert World(system, patient).distances(q=q).min() >= margin - SAME_DISTANCE
    assert np.all(plan.q >= BIPLANE.lower - 1e-9) and np.all(plan.q <= BIPLANE.upper + 1e-9)


def test_ap_with_a_lateral_at_90_degrees_without_a_patient():
    plan = plan_biplane(BIPLANE, "ap", 90.0)
    assert plan.success and plan.failure is None and plan.reason is None
    frontal = STANDARD_VIEWS["ap"]
    ap = View.from_angles(frontal.primary_deg, frontal.secondary_deg, (0, 0, 0))
    _check_plan(plan, ap, View.from_angles(90.0, 0.0, (0, 0, 0)), patient=None)
    assert plan.clearance > 0.1 and plan.pair is not None


def test_the_lateral_view_is_the_frontal_turned_about_the_long_axis():
    ap = View.from_angles(0.0, 0.0, (0.0, 0.0, 0.0))
    assert np.allclose(lateral_view(ap, 90.0).axis, View.from_angles(90.0, 0.0, (0, 0, 0)).axis, atol=1e-12)
    assert np.allclose(lateral_view(ap, -90.0).axis, View.from_angles(-90.0, 0.0, (0, 0, 0)).axis, atol=1e-12)
    assert np.allclose(lateral_view(ap, 0.0).axis, ap.axis, atol=1e-15)


@given(st.floats(-180, 180), st.floats(-80, 80), st.floats(-180, 180))
@settings(max_examples=100)
def test_a_turned_view_is_the_angle_asked_away_about_the_long_axis(primary, secondary, angle):
    frontal = View.from_angles(primary, secondary, (0.01, 0.02, -0.03))
    lateral = lateral_view(frontal, angle)
    assert lateral.target == frontal.target
    assert abs(math.degrees(frontal.angle_to(lateral)) - abs(angle)) <= 1e-9
    # the turn is about the patient's long axis (Z0 for HFS) taken across the frontal beam: that axis is across
    # both beams, and the long axis keeps its angle to the beam scaled by the turn's cosine
    d, e, s = frontal.axis, lateral.axis, np.array([0.0, 0.0, 1.0])
    across = s - (s @ d) * d
    assert abs(e @ across) <= 1e-12
    assert abs(e @ s - (s @ d) * math.cos(math.radians(angle))) <= 1e-12


@pytest.mark.parametrize("name", ["rao-35-caudal-35", "lao-40-cranial-30", "rao-10-caudal-30"])
def test_standard_views_with_a_lateral_at_90_degrees_and_a_patient(name):
    plan = plan_biplane(BIPLANE, name, 90.0, patient=PATIENT)
    view = STANDARD_VIEWS[name]
    frontal = View.from_angles(view.primary_deg, view.secondary_deg, (0, 0, 0))
    assert plan.success, plan.reason
    _check_plan(plan, frontal, lateral_view(frontal, 90.0))


@given(st.integers(-60, 60), st.integers(-40, 40), st.sampled_from([60.0, 75.0, 90.0, 105.0]))
@settings(max_examples=12)
def test_a_plan_takes_the_two_views_asked_or_says_why_not(primary, secondary, angle):
    frontal = View.from_angles(primary, secondary, (0.0, 0.0, 0.0))
    lateral = lateral_view(frontal, angle)
    plan = plan_biplane(BIPLANE, frontal, lateral, patient=PATIENT)
    if plan.success:
        _check_plan(plan, frontal, lateral)
    else:
        assert isinstance(plan.failure, Failure) and plan.reason.startswith(plan.failure.value)
        assert np.isnan(plan.q).all() and math.isnan(plan.clearance)


def test_an_unreachable_frontal_view_says_so():
    # the frontal isocentre moves on a circle of 1.2 m about the stand's floor axis (the wigwag) and the table at
    # most 150 mm sideways: no vertical beam passes 2 m aside of the table's axis
    view = View.from_angles(0.0, 0.0, (2.0, 0.0, 0.0))
    plan = plan_biplane(BIPLANE, view, 90.0)
    assert not plan.success and plan.failure is Failure.FRONTAL_UNREACHABLE
    assert plan.reason.startswith("the frontal view is unreachable: ") and plan.lateral is None
    assert not plan.frontal.success and plan.frontal.reason in plan.reason


def test_a_frontal_view_along_the_long_axis_needs_its_lateral_view_given():
    view = View((0.0, 0.0, 0.3), (0.0, 0.0, 1.0))
    with pytest.raises(ViewError, match=r"the frontal view \[0.0, 0.0, 1.0\] runs along the patient's long axis"):
        plan_biplane(BIPLANE, view, 90.0)


def test_planes_that_cannot_both_take_their_views_give_a_typed_reason():
    # the lateral beam along the frontal beam: the two detectors would have to share one place
    plan = plan_biplane(BIPLANE, "ap", 0.0)
    assert not plan.success
    assert plan.failure in (Failure.LATERAL_UNREACHABLE, Failure.PLANES_COLLIDE)
    assert "lateral" in plan.reason


@pytest.mark.parametrize("args, kwargs, error, message", [
    (("not a biplane", "ap"), {}, BiplaneError, "biplane must be a carmkin.model.biplane.Biplane"),
    ((BIPLANE, "ap", True), {}, ViewError, "lateral must be a View, a standard view name or an angle in degrees"),
    ((BIPLANE, "ap", 200.0), {}, ViewError, "angle_deg"),
    ((BIPLANE, "apx", 90.0), {}, ViewError, "unknown standard view 'apx'"),
    ((BIPLANE, 3, 90.0), {}, ViewError, "frontal_view must be a carmkin.views.View or a standard view name"),
    ((BIPLANE, "ap"), {"q_current": np.zeros(14)}, BiplaneError, r"q_current must be real numbers .* \(15,\)"),
    ((BIPLANE, "ap"), {"margin": -0.1}, ViewError, "margin"),
])
def test_bad_input_is_refused_naming_the_argument(args, kwargs, error, message):
    with pytest.raises(error, match=message):
        plan_biplane(*args, **kwargs)
