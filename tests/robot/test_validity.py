"""Validity report (§4.4.3) on hand-built configurations: joints out of range, collisions, X-ray cone."""

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from strategies import PRESET

import carmkin
from carmkin.errors import InvalidConfigurationError
from carmkin.robot import validity
from carmkin.world import Obstacle, World

TABLE_CENTER = np.array(PRESET.table.top_center)
TABLE_HALF = 0.5 * np.array(PRESET.table.top_size)
SCENE = World(PRESET)
unit6 = st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6).map(np.array)


def in_range(u):
    return PRESET.lower + u * (PRESET.upper - PRESET.lower)


def inside_table(p):
    return bool(np.all(np.abs(p - TABLE_CENTER) <= TABLE_HALF))


def test_zero_configuration_is_valid():
    """At q = 0 the beam goes up through the isocentre (table frame origin) and the C clears the table."""
    report = validity.check(PRESET, np.zeros(6), world=SCENE)
    assert report.valid and report.reasons == () and str(report) == "valid at margin 10 mm"
    assert report.min_distance > 0


def test_joints_out_of_range_are_named_with_their_excess():
    q = np.zeros(6)
    q[1] = PRESET.upper[1] + 0.05  # vertical 5 cm too high
    q[5] = PRESET.lower[5] - 0.1  # orbital 0.1 rad too low
    report = validity.check(PRESET, q, world=SCENE)
    excess = {j.name: j.excess for j in report.joints}
    assert excess == pytest.approx({"vertical": 0.05, "orbital": -0.1})
    assert not report.valid and not report.reachable
    assert "vertical" in str(report) and "orbital" in str(report)


def test_extra_table_joints_are_reported_by_name():
    system = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
    q = np.zeros(system.nq)
    k = system.joint_names.index("table_tilt")
    q[k] = system.upper[k] + 0.02
    report = validity.check(system, q)
    assert [(j.name, round(j.excess, 12)) for j in report.joints] == [("table_tilt", 0.02)]


def test_source_inside_the_table_is_a_table_collision():
    """Hand-built: configurations whose source centre (closed-form FK) lies inside the table-top box; the
    tube housing contains the source centre, so the report must name xray_source against the table."""
    rng = np.random.default_rng(3)
    found = 0
    for q in rng.uniform(PRESET.lower, PRESET.upper, size=(20000, 6)):
        if not inside_table(PRESET.fk(q)[:3, 3]):
            continue
        report = validity.check(PRESET, q, world=SCENE)
        assert ("xray_source", "table") in [c.links for c in report.collisions]
        assert not report.valid and "intersects table" in str(report)
        found += 1
        if found == 5:
            break
    assert found == 5


def test_obstacle_at_the_source_is_reported_by_name():
    q = np.array([0.1, 0.2, 0.05, 0.1, 0.4, -0.3])
    patient = Obstacle.capsule("patient", 0.05, 0.3, center=PRESET.fk(q)[:3, 3])
    report = validity.check(PRESET, q, obstacles=[patient])
    assert any(c.second == "patient" and c.first == "xray_source_0" and c.distance < 0 for c in report.collisions)


def test_margin_counts_near_pairs():
    q = np.zeros(6)
    d = validity.check(PRESET, q, world=SCENE).min_distance
    assert validity.check(PRESET, q, world=SCENE, margin=0.5 * d).reachable
    report = validity.check(PRESET, q, world=SCENE, margin=d + 1e-3)
    assert report.collisions and "within the margin" in str(report)


def test_beam_parallel_to_the_table_misses_it():
    """Orbital = 90°: the principal axis turns from the table normal (Y0) into the table plane; moved
    (vertical joint) away from the thin table top, the source-detector segment misses it."""
    q = np.array([0.0, 0.4, 0.0, 0.0, 0.0, np.pi / 2])
    T = PRESET.fk(q)
    assert abs(T[1, 2]) < 1e-9  # axis perpendicular to Y0, i.e. parallel to the table top
    assert abs(T[1, 3] - TABLE_CENTER[1]) > TABLE_HALF[1]  # and off its thickness
    report = validity.check(PRESET, q, world=SCENE)
    assert not report.table_in_cone
    assert "not in the X-ray cone" in str(report)


@settings(max_examples=60)
@given(unit6)
def test_cone_test_agrees_with_sampling_the_segment(u):
    """table_in_cone == some point of the source→detector segment lies in the table box (dense sampling);
    configurations where the sampled answer is ambiguous (grazing) are skipped."""
    q = in_range(u)
    T = PRESET.fk(q)
    t = np.linspace(0.0, 1.0, 4001)[:, None]
    points = T[:3, 3] + t * PRESET.carm.source_to_detector * T[:3, 2]
    outside = np.max(np.abs(points - TABLE_CENTER) - TABLE_HALF, axis=1)  # <= 0 inside the box
    assume(abs(outside.min()) > 1e-3)
    assert validity.table_in_cone(PRESET, q) == bool(outside.min() <= 0)


@settings(max_examples=60)
@given(unit6)
def test_pairs_separated_by_bounding_spheres_are_not_reported(u):
    """Independent bound: two boxes whose circumscribed spheres do not meet cannot intersect."""
    q = in_range(u)
    model = SCENE.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    gm = SCENE.geometry_model
    gd = pin.GeometryData(gm)
    pin.updateGeometryPlacements(model, data, gm, gd)
    index = {g.name: i for i, g in enumerate(gm.geometryObjects)}
    radius = {g.name: 0.5 * np.linalg.norm(2 * g.geometry.halfSide) for g in gm.geometryObjects}
    report = validity.check(PRESET, q, world=SCENE)
    reported = {(c.first, c.second) for c in report.collisions}
    for a, b in SCENE.pairs:
        gap = np.linalg.norm(gd.oMg[index[a]].translation - gd.oMg[index[b]].translation) - radius[a] - radius[b]
        if gap > 0:
            assert (a, b) not in reported


def test_bad_configuration_is_rejected():
    with pytest.raises(InvalidConfigurationError):
        validity.check(PRESET, np.zeros(5))
    with pytest.raises(InvalidConfigurationError):
        validity.check(PRESET, np.full(6, np.nan))
    with pytest.raises(InvalidConfigurationError, match="margin"):
        validity.check(PRESET, np.zeros(6), margin=-1.0)


def test_reasons_are_rendered_from_the_fields_in_mm_and_degrees():
    from carmkin.robot.validity import NOT_IN_CONE, Contact, JointViolation, ValidityReport

    report = ValidityReport(q=np.zeros(6), joints=(JointViolation("wigwag", np.radians(100.0), np.radians(10.0)),
                                                   JointViolation("vertical", 0.5, 0.02, prismatic=True)),
                            collisions=(Contact("dh_frame_6_3", "table_top", -0.004),), table_in_cone=False,
                            min_distance=-0.004, margin=0.01)
    assert report.reasons == ("joint wigwag out of range by +10 ° (value 100 °)",
                              "joint vertical out of range by +20 mm (value 500 mm)",
                              "dh_frame_6 intersects table_top (dh_frame_6_3/table_top, distance -4 mm)",
                              NOT_IN_CONE)
    assert not report.valid and not report.reachable
    assert str(report) == "invalid at margin 10 mm: " + "; ".join(report.reasons)


@settings(max_examples=30)
@given(st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6), st.floats(0.0, 0.05), st.booleans())
def test_report_is_the_dataclass_built_by_its_init(values, margin, deferred):
    """validity.report builds its frozen ValidityReport without the generated __init__ (carmkin.validation
    .frozen_instance): the same stored state, fields, equality and text as ValidityReport(...) gives, for
    in- and out-of-range joints, flagged pairs, and values given as numbers or as functions."""
    q = np.array(values)
    world = World(PRESET)
    source = PRESET.fk(np.clip(q, PRESET.lower, PRESET.upper))
    cone = validity.pose_in_cone(PRESET, source)
    smallest = (lambda: -0.002) if deferred else -0.002
    fast = validity.report(PRESET, q, world, [1], [-0.002], smallest, source, margin)
    slow = validity.ValidityReport(q=q, joints=validity.joint_violations(PRESET, q),
                                   collisions=(validity.Contact(*world.pairs[1], -0.002),),
                                   table_in_cone=lambda: cone, min_distance=smallest, margin=margin)
    assert type(fast) is validity.ValidityReport
    assert fast.__dict__.keys() == slow.__dict__.keys()
    assert (fast.joints, fast.collisions, fast.margin) == (slow.joints, slow.collisions, slow.margin)
    assert (fast.table_in_cone, fast.min_distance, fast.valid, fast.reachable) == (
        slow.table_in_cone, slow.min_distance, slow.valid, slow.reachable)
    assert str(fast) == str(slow) and fast == slow
