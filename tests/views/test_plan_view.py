"""plan_view: completeness on views built from collision-free configurations (three systems), the DICOM round
trip for every Patient Position, moves swept from q_current, typed errors for bad input."""

import math

import numpy as np
import pytest

import carmkin
from view_systems import SYSTEMS

from carmkin.errors import CarmkinError, PatientModelError, ViewError
from carmkin.imaging.projection import PATIENT_POSITIONS
from carmkin.interop.dicom import xa_angles
from carmkin.patient import ParametricPatient
from carmkin.robot import validity
from carmkin.world import World
from carmkin.views import DEFAULT_MARGIN, View, plan_view
from carmkin.views.standard import STANDARD_VIEWS

#: XA angles read back from FK agree to this (deg); every answer comes from a closed form.
ANGLE_TOLERANCE_DEG = 1e-9


def _views_from_configurations(system, patient, count, rng):
    scene = World(system, patient.obstacles())
    out = []
    while len(out) < count:
        q = system.lower + rng.random(system.nq) * (system.upper - system.lower)
        if not validity.check(system, q, margin=DEFAULT_MARGIN, world=scene).reachable:
            continue
        T = system.fk(q)
        s = rng.uniform(0.05, system.carm.source_to_detector - 0.05)
        out.append((q, View(tuple(T[:3, 3] + s * T[:3, 2]), tuple(T[:3, 2]))))
    return out


@pytest.mark.parametrize("roll", [False, True], ids=["free roll", "fixed roll"])
@pytest.mark.parametrize("name", ["6-DOF", "non-isocentric", "motorized"])
def test_every_view_of_a_collision_free_configuration_is_planned(name, roll):
    """Views of collision-free configurations (free distance; with ``roll``, the configuration's source x
    axis kept): each is planned, the beam along the view (and the x axis the view's) to 1e-9 (closed form)."""
    system = SYSTEMS[name]
    patient = ParametricPatient.on_table(system)
    rng = np.random.default_rng(11 if roll else 7)
    scene = World(system, patient.obstacles())
    missed = []
    views = _views_from_configurations(system, patient, 60 if roll else 170, rng)
    for q, view in views:
        if roll:
            view = View(view.target, view.direction, x_axis=tuple(system.fk(q)[:3, 0]))
        # The motorized table stays where it is (its joints are held at q_current's); the C-arm moves.
        plan = plan_view(system, view, patient, q_current=q if system.table.joints else None, nearest=False)
        if not plan.success:
            missed.append((q, plan.reason))
            continue
        T = system.fk(plan.q)
        w = np.array(view.target) - T[:3, 3]
        assert np.linalg.norm(T[:3, 2] - view.axis) < 1e-9
        assert np.linalg.norm(w - (w @ T[:3, 2]) * T[:3, 2]) < 1e-9
        if roll:
            assert np.linalg.norm(T[:3, 0] - np.array(view.x_axis)) < 1e-9
        assert validity.check(system, plan.q, margin=DEFAULT_MARGIN, world=scene).reachable
    print(f"\n{name}: {len(views) - len(missed)} of {len(views)} views of collision-free configurations planned"
          + (" with their roll" if roll else ""))
    assert not missed, missed[:3]


@pytest.mark.parametrize("position", list(PATIENT_POSITIONS))
def test_dicom_round_trip_for_every_patient_position(position):
    system = SYSTEMS["6-DOF"]
    patient = ParametricPatient.on_table(system, position=position)
    planned, worst = 0, 0.0
    for p, s in ((0.0, 0.0), (30.0, 20.0), (-25.0, -15.0), (60.0, 10.0), (-90.0, 0.0), (120.0, 30.0)):
        plan = plan_view(system, View.from_angles(p, s, (0.0, 0.0, 0.0), patient), patient, nearest=False)
        if not plan.success:
            continue
        p2, s2, _ = xa_angles(system.fk(plan.q), patient.pose())
        worst = max(worst, abs((p2 - p + 180.0) % 360.0 - 180.0), abs(s2 - s))
        assert abs((p2 - p + 180.0) % 360.0 - 180.0) < ANGLE_TOLERANCE_DEG
        assert abs(s2 - s) < ANGLE_TOLERANCE_DEG
        planned += 1
    print(f"\n{position}: {planned} views round-tripped, worst angle error {worst:.1e}°")
    assert planned >= 2


def test_standard_views_have_a_source_and_plan():
    system = SYSTEMS["6-DOF"]
    patient = ParametricPatient.on_table(system)
    for name, v in STANDARD_VIEWS.items():
        assert v.source
        plan = plan_view(system, name, patient, nearest=False)
        assert plan.success or plan.reason
        assert View.from_angles(v.primary_deg, v.secondary_deg, (0, 0, 0), patient).angle_to(plan.view) < 1e-12


def test_moves_from_q_current_are_swept():
    system = SYSTEMS["6-DOF"]
    patient = ParametricPatient.on_table(system)
    start = plan_view(system, "ap", patient).q
    plan = plan_view(system, View.from_angles(30, 20, (0, 0, 0), patient), patient, q_current=start)
    assert plan.success and plan.moves
    q = start.copy()
    for move in plan.moves:
        assert move.clear
        q[system.joint_names.index(move.joint)] = move.end
    np.testing.assert_allclose(q, plan.q, atol=0)


def _by_hand(d: float, v: float, a: float) -> float:
    """One joint from rest to rest: d/v + v/a when it reaches its speed (d ≥ v²/a), else 2√(d/a)."""
    d = abs(d)
    return d / v + v / a if d >= v * v / a else 2 * math.sqrt(d / a)


@pytest.mark.parametrize("name", ["6-DOF", "motorized"])
def test_the_moves_duration_is_the_sum_of_each_joints_profile(name):
    """The plan's moves go one joint after another, each from rest to rest: Σ_j t_j at the preset's speeds."""
    system = SYSTEMS[name]
    patient = ParametricPatient.on_table(system)
    start = plan_view(system, "ap", patient).q
    plan = plan_view(system, View.from_angles(30, 20, (0, 0, 0), patient), patient, q_current=start)
    expected = sum(_by_hand(b - a, j.speed, j.acceleration) for j, a, b in zip(system.motion.joints, start, plan.q))
    assert plan.duration.seconds == pytest.approx(expected, rel=1e-12) and expected > 0
    moved = {m.joint for m in plan.moves}
    assert {n for n, t in zip(system.joint_names, plan.duration.parts) if t > 0} == moved
    # without speeds, or without q_current, the duration is unknown and says why
    assert plan_view(system.replace(motion=None), plan.view, patient, q_current=start).duration.reason == \
        "no joint speeds in the preset"
    assert plan_view(system, plan.view, patient).duration.seconds is None


def test_perpendicular_views_are_perpendicular():
    a, b = np.array([0.01, -0.05, 0.02]), np.array([0.05, -0.02, 0.09])
    views = View.perpendicular_to(a, b, count=12)
    for v in views:
        assert abs(v.axis @ (b - a)) < 1e-12
    system = SYSTEMS["6-DOF"]
    patient = ParametricPatient.on_table(system)
    plans = [plan_view(system, v, patient, nearest=False) for v in views]
    assert any(p.success for p in plans)


@pytest.mark.parametrize("call", [
    lambda: View.from_angles("30", 20, (0, 0, 0)),
    lambda: View.from_angles(30, 95, (0, 0, 0)),
    lambda: View.from_angles(30, 20, (0, float("nan"), 0)),
    lambda: View.from_angles(30, 20, (0, 0, 0), position="XYZ"),
    lambda: View((0, 0, 0), (0, 0, 0)),
    lambda: View.perpendicular_to((0, 0, 0), (0, 0, 0)),
    lambda: plan_view(SYSTEMS["6-DOF"], "no-such-view"),
    lambda: plan_view(SYSTEMS["6-DOF"], View((0, 0, 0), (0, 0, 1)), patient=[1, 2]),
    lambda: plan_view(SYSTEMS["6-DOF"], View((0, 0, 0), (0, 0, 1)), q_current=[0.0] * 5),
])
def test_bad_input_is_a_typed_error(call):
    with pytest.raises(CarmkinError):
        call()


def test_patient_sinking_into_the_table_is_refused():
    system = SYSTEMS["6-DOF"]
    with pytest.raises(PatientModelError, match="sinks"):
        plan_view(system, View((0, 0, 0), (0, 0, 1)), ParametricPatient(origin=(0.0, 0.3, 0.0)), nearest=False)


def test_out_of_reach_target_is_an_unreachable_plan_with_its_reason():
    plan = plan_view(SYSTEMS["6-DOF"], View.from_angles(0, 0, (3.0, 0.0, 0.0)), nearest=False)
    assert not plan.success and "joint limits" in plan.reason and np.all(np.isnan(plan.q))


def test_no_plan_touches_the_patient():
    system = SYSTEMS["6-DOF"]
    patient = ParametricPatient.on_table(system, mass=140.0)
    scene = World(system, patient.obstacles())
    rng = np.random.default_rng(3)
    for p, s in rng.uniform([-180, -90], [180, 90], (40, 2)):
        plan = plan_view(system, View.from_angles(p, s, (0.0, -0.05, 0.0), patient), patient, nearest=False)
        if plan.success:
            assert validity.check(system, plan.q, margin=DEFAULT_MARGIN, world=scene).reachable
        else:
            assert plan.reason
    assert math.isfinite(DEFAULT_MARGIN)
    with pytest.raises(ViewError):
        plan_view(system, "ap", patient, margin=-1.0)


def test_dicom_round_trip_with_a_detector_rotation():
    """(primary, secondary, rotation) → plan_view → xa_angles gives all three back; the rotations tried are a
    few degrees about the one the free plan takes (the wigwag's ±10° is all the roll this C-arm has)."""
    system = SYSTEMS["6-DOF"]
    patient = ParametricPatient.on_table(system)
    planned, worst = 0, 0.0
    for p, s in ((0.0, 0.0), (30.0, 20.0), (-25.0, -15.0), (60.0, 10.0)):
        free = plan_view(system, View.from_angles(p, s, (0.0, 0.0, 0.0), patient), patient, nearest=False)
        assert free.success
        r0 = xa_angles(system.fk(free.q), patient.pose())[2]
        for r in (round(r0) + 3.0, round(r0) - 4.0):
            plan = plan_view(system, View.from_angles(p, s, (0.0, 0.0, 0.0), patient, rotation_deg=r), patient,
                             nearest=False)
            if not plan.success:
                assert plan.reason
                continue
            p2, s2, r2 = xa_angles(system.fk(plan.q), patient.pose())
            for got, want in ((p2, p), (s2, s), (r2, r)):
                worst = max(worst, abs((got - want + 180.0) % 360.0 - 180.0))
                assert abs((got - want + 180.0) % 360.0 - 180.0) < ANGLE_TOLERANCE_DEG
            planned += 1
    print(f"\n{planned} views with a detector rotation round-tripped, worst angle error {worst:.1e}°")
    assert planned >= 6


def test_an_unreachable_roll_names_the_wigwag_and_offers_the_same_beam():
    """A roll no wigwag value gives (the preset's wigwag spans ±10°): unreachable by the wigwag, and the
    nearest view is the same beam with its own roll."""
    system = SYSTEMS["6-DOF"]
    patient = ParametricPatient.on_table(system)
    view = View.from_angles(0.0, 0.0, (0.0, 0.0, 0.0), patient, rotation_deg=60.0)
    plan = plan_view(system, view, patient)
    assert not plan.success and plan.binding == "wigwag", plan.reason
    assert plan.nearest is not None and plan.nearest.success and plan.angle == 0.0
    assert plan.nearest.view.x_axis is None


@pytest.mark.parametrize("call", [
    lambda: View((0, 0, 0), (0, 0, 1), x_axis=(0, 0, 2)),
    lambda: View((0, 0, 0), (0, 0, 1), x_axis=("1", 0, 0)),
    lambda: View((0, 0, 0), (0, 0, 1), x_axis=(np.nan, 0, 0)),
    lambda: View.from_angles(30, 20, (0, 0, 0), rotation_deg=200),
    lambda: View.from_angles(30, 20, (0, 0, 0), rotation_deg="5"),
    lambda: View.from_pose(np.eye(3), 0.5),
    lambda: View.from_pose(np.eye(4), -1.0),
])
def test_bad_roll_input_is_a_view_error(call):
    with pytest.raises(ViewError):
        call()


def test_the_qp_frees_a_motorized_table_where_the_closed_form_holds_it():
    """Views the closed form (table joints held) leaves unreachable on the motorized table: with ``qp=False``
    unreachable as the map says; by default the QP tilts/turns the table and a fresh scene and FK confirm."""
    system = SYSTEMS["motorized"]
    patient = ParametricPatient.on_table(system)
    scene = World(system, patient.obstacles())
    freed = 0
    for p, s in ((-60.0, 45.0), (50.0, 45.0), (90.0, -45.0), (90.0, -25.0)):
        view = View.from_angles(p, s, (0.0, 0.0, 0.0), patient)
        held = plan_view(system, view, patient, nearest=False, qp=False)
        assert not held.success and held.reason
        plan = plan_view(system, view, patient, nearest=False)
        if not plan.success:
            continue
        assert plan.solver == "qp"
        T = system.fk(plan.q)
        w = np.array(view.target) - T[:3, 3]
        assert np.linalg.norm(T[:3, 2] - view.axis) < 1e-6 and np.linalg.norm(w - (w @ T[:3, 2]) * T[:3, 2]) < 1e-6
        assert validity.check(system, plan.q, margin=DEFAULT_MARGIN, world=scene).reachable
        assert np.any(system.split(plan.q)[1] != system.split(0.5 * (system.lower + system.upper))[1])
        freed += 1
    assert freed >= 2


def test_a_plan_reports_its_roll_clearances_and_validity():
    """The plan's clearance to patient, table and floor against a fresh scene's pairs grouped by hand; its
    validity report and roll against the FK."""
    system = SYSTEMS["6-DOF"]
    patient = ParametricPatient.on_table(system)
    scene = World(system, patient.obstacles())
    names = {o.name for o in patient.obstacles()}
    for p, s in ((0.0, 0.0), (30.0, 20.0), (-45.0, -30.0)):
        plan = plan_view(system, View.from_angles(p, s, (0.0, 0.0, 0.0), patient), patient, nearest=False)
        assert plan.success
        d = scene.distances(q=plan.q)
        by_hand = {"patient": min(x for x, (_, b) in zip(d, scene.pairs) if b in names),
                   "table": min(x for x, (_, b) in zip(d, scene.pairs) if b.startswith("table_")),
                   "floor": min(x for x, (_, b) in zip(d, scene.pairs) if b.startswith("floor_"))}
        assert set(plan.clearance_to) == set(by_hand)
        for k in by_hand:
            assert plan.clearance_to[k] == pytest.approx(by_hand[k], abs=2e-6)
        assert min(plan.clearance_to.values()) == pytest.approx(plan.clearance, abs=2e-6)
        assert plan.validity.reachable and plan.validity.min_distance == pytest.approx(plan.clearance, abs=2e-6)
        np.testing.assert_allclose(plan.x_axis, system.fk(plan.q)[:3, 0], atol=1e-15)
    unreachable = plan_view(system, View.from_angles(0, 0, (3.0, 0.0, 0.0)), nearest=False)
    assert unreachable.validity is None and unreachable.clearance_to is None


def test_the_best_perpendicular_view_of_a_segment():
    """plan_perpendicular against plan_view on every member of the family: perpendicular, through the
    midpoint, valid by a fresh scene, with the most clearance of the reachable members (or, with ``prefer``,
    the reachable member nearest it)."""
    from carmkin.views import plan_perpendicular

    system = SYSTEMS["6-DOF"]
    patient = ParametricPatient.on_table(system)
    scene = World(system, patient.obstacles())
    a, b = np.array([0.0, 0.05, -0.02]), np.array([0.03, 0.0, 0.05])
    members = View.perpendicular_to(a, b, 36)
    plans = [plan_view(system, v, patient, nearest=False, qp=False) for v in members]
    assert any(p.success for p in plans) and not all(p.success for p in plans)
    best = plan_perpendicular(system, a, b, patient, count=36)
    assert best.success and abs(best.view.axis @ (b - a)) < 1e-12
    T = system.fk(best.q)
    w = 0.5 * (a + b) - T[:3, 3]
    assert np.linalg.norm(w - (w @ T[:3, 2]) * T[:3, 2]) < 1e-9
    assert validity.check(system, best.q, margin=DEFAULT_MARGIN, world=scene).reachable
    assert best.clearance >= max(p.clearance for p in plans if p.success) - 1e-12
    prefer = np.array([0.0, -1.0, 0.0])
    near = plan_perpendicular(system, a, b, patient, count=36, prefer=prefer)
    assert near.success
    assert near.view.axis @ prefer >= max(p.view.axis @ prefer for p in plans if p.success) - 1e-12
    far = plan_perpendicular(system, a + [3.0, 0, 0], b + [3.0, 0, 0], patient, count=12)
    assert not far.success and "no view perpendicular to the segment is reachable" in far.reason


@pytest.mark.parametrize("name", carmkin.list_presets())
def test_a_current_configuration_outside_the_ranges_is_refused_on_every_preset(name):
    """Issue 31: a q_current slightly past a (held) table joint's range once gave success with that joint out of
    range. Every joint just past either limit is refused with the joint named; on the limit it is in range and
    every successful plan keeps every joint in range."""
    system = carmkin.load_preset(name)
    view = View.from_angles(30.0, 20.0, (0.0, 0.0, 0.0))
    middle = 0.5 * (system.lower + system.upper)
    for k, joint in enumerate(system.joint_names):
        for limit, sign in ((system.lower[k], -1.0), (system.upper[k], 1.0)):
            q = middle.copy()
            q[k] = limit + sign * 1e-4
            with pytest.raises(carmkin.InvalidConfigurationError, match=f"q_current: {joint}"):
                plan_view(system, view, q_current=q, nearest=False)
            q[k] = limit
            plan = plan_view(system, view, q_current=q, nearest=False)
            if plan.success:
                assert np.all(plan.q >= system.lower - 1e-9) and np.all(plan.q <= system.upper + 1e-9)


def test_coronary_views_lie_in_the_ranges_of_the_table_they_cite():
    """Issue 31: the coronary standard views once lay outside the angle ranges of Di Mario & Sutaria's Table 2, and
    the LAO cranial view was called spider-free though the spider is LAO caudal. The ranges, typed here from the
    table (primary LAO +, secondary CRA +, deg), are the oracle."""
    table_2 = {"rao-30": ((-45, -30), (0, 0)), "lao-50": ((45, 60), (0, 0)),
               "lao-40-cranial-30": ((30, 45), (25, 35)), "lao-45-caudal-30": ((40, 50), (-40, -25)),
               "rao-35-caudal-35": ((-45, -30), (-40, -30)), "rao-10-cranial-40": ((-10, -5), (35, 45)),
               "rao-10-caudal-30": ((-15, -5), (-30, -30))}
    cited = {name for name, v in STANDARD_VIEWS.items() if "Di Mario" in v.source}
    assert cited == set(table_2)
    for name, ((p_lo, p_hi), (s_lo, s_hi)) in table_2.items():
        v = STANDARD_VIEWS[name]
        assert p_lo <= v.primary_deg <= p_hi and s_lo <= v.secondary_deg <= s_hi, name
    assert "spider" in STANDARD_VIEWS["lao-45-caudal-30"].description
    assert not any("spider" in v.description for n, v in STANDARD_VIEWS.items() if v.secondary_deg >= 0)
