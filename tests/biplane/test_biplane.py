"""The biplane device (issue 30): the value, its preset, FK of both planes against Pinocchio, the clearance between
the planes against an independent oracle (one Pinocchio model holding both planes), and bad input."""

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import carmkin
from carmkin.biplane import Biplane, BiplaneWorld, check_rest, load_biplane
from carmkin.errors import BiplaneError, PresetError, UnknownPresetError
from carmkin.model.params import JointRange
from carmkin.presets import preset_provenance, read_biplane
from carmkin.world.between import BODY_LINKS, Between
from carmkin.world.obstacles import link_of

BIPLANE = load_biplane("angio-biplane")
WORLD = BiplaneWorld(BIPLANE)
#: Two routes to one signed distance (m): coal's GJK/EPA tolerance (carmkin.world.tolerances.DISTANCE_ACCURACY)
#: on either side.
SAME_DISTANCE = 1e-5
#: FK of either plane against Pinocchio (m, and rotation entries), the acceptance bound of every preset.
FK_AGREEMENT = 1e-12


def configurations(biplane, draw_unit):
    """A biplane configuration (nq,) from unit values in [0, 1]."""
    return biplane.lower + np.asarray(draw_unit) * (biplane.upper - biplane.lower)


unit_q = st.lists(st.floats(0.0, 1.0), min_size=BIPLANE.nq, max_size=BIPLANE.nq)


# --- the value --------------------------------------------------------------------------------------------
def test_the_joint_vector_is_the_shared_table_then_each_planes_carm():
    b = BIPLANE
    k = b.table_nq
    assert b.nq == k + 10 == 15
    assert b.joint_names[:k] == b.frontal.joint_names[:k]
    assert b.joint_names[k:] == tuple(f"frontal.{n}" for n in carmkin.JOINT_NAMES[1:]) + tuple(
        f"lateral.{n}" for n in carmkin.JOINT_NAMES[1:])
    assert b.frontal.table == b.lateral.table
    assert b.frontal == dataclasses.replace(carmkin.load_preset("angio-floor"), name=b.frontal.name)


@given(unit_q)
@settings(max_examples=40)
def test_planes_q_and_join_round_trip_and_share_the_table(u):
    q = configurations(BIPLANE, u)
    q_f, q_l = BIPLANE.planes_q(q)
    k = BIPLANE.table_nq
    assert np.array_equal(q_f[:k], q_l[:k]) and np.array_equal(q_f[:k], q[:k])
    assert np.array_equal(q_f[k:], q[k:k + 5]) and np.array_equal(q_l[k:], q[k + 5:])
    assert np.array_equal(BIPLANE.join(q_f, q_l), q)
    bad = q_l.copy()
    bad[0] += 1e-6
    with pytest.raises(BiplaneError, match="share one table"):
        BIPLANE.join(q_f, bad)


def _pinocchio_source(system, q):
    model, _, _ = system.pinocchio()
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[model.getFrameId("xray_source")].homogeneous


def test_acceptance_fk_of_both_planes_equals_pinocchio_over_10000_configurations():
    """The acceptance row: FK of each plane vs Pinocchio ≤ 1e-12 over 10 000 biplane configurations."""
    rng = np.random.default_rng(30)
    Q = configurations(BIPLANE, rng.random((10_000, BIPLANE.nq)))
    T = BIPLANE.fk(Q)
    worst = 0.0
    for q, poses in zip(Q, T):
        for plane, system, pose in zip(("frontal", "lateral"), (BIPLANE.frontal, BIPLANE.lateral), poses):
            q_plane = BIPLANE.planes_q(q)[0 if plane == "frontal" else 1]
            worst = max(worst, float(np.abs(_pinocchio_source(system, q_plane) - pose).max()))
    assert worst <= FK_AGREEMENT


@given(unit_q)
@settings(max_examples=30)
def test_fk_of_both_planes_equals_pinocchio(u):
    q = configurations(BIPLANE, u)
    T = BIPLANE.fk(q)
    q_f, q_l = BIPLANE.planes_q(q)
    np.testing.assert_allclose(T[0], _pinocchio_source(BIPLANE.frontal, q_f), rtol=0, atol=FK_AGREEMENT)
    np.testing.assert_allclose(T[1], _pinocchio_source(BIPLANE.lateral, q_l), rtol=0, atol=FK_AGREEMENT)


def test_the_planes_share_the_isocentre_at_rest_and_are_clear_there():
    iso = BIPLANE.isocentres(np.array(BIPLANE.rest))
    assert np.linalg.norm(iso[0] - iso[1]) <= 1e-9
    rest = WORLD.clearance(np.array(BIPLANE.rest))
    assert rest.planes > 0.1 and rest.frontal > 0 and rest.lateral > 0  # 322 mm between the planes (docs/biplane.md)
    assert check_rest(BIPLANE) == pytest.approx(rest.planes)


# --- the clearance between the planes -----------------------------------------------------------------------
def _combined():
    """One Pinocchio model holding both planes (the lateral's names prefixed), with every frontal body geometry
    paired with every lateral one: the oracle, sharing none of carmkin.world.between's code."""
    mf, cf, _ = BIPLANE.frontal.pinocchio()
    ml, cl, _ = BIPLANE.lateral.pinocchio()
    ml, cl = ml.copy(), cl.copy()
    for i in range(1, ml.nframes):
        frame = ml.frames[i]
        frame.name = "lateral/" + frame.name
        ml.frames[i] = frame
    for i in range(1, ml.njoints):
        ml.names[i] = "lateral/" + ml.names[i]
    for g in cl.geometryObjects:
        g.name = "lateral/" + g.name
    model, geometry = pin.appendModel(mf, ml, cf, cl, 0, pin.SE3.Identity())
    names = [g.name for g in geometry.geometryObjects]
    front = [i for i, n in enumerate(names) if not n.startswith("lateral/") and link_of(n) in BODY_LINKS]
    back = [i for i, n in enumerate(names) if n.startswith("lateral/") and link_of(n[8:]) in BODY_LINKS]
    geometry.removeAllCollisionPairs()
    for i in front:
        for j in back:
            geometry.addCollisionPair(pin.CollisionPair(i, j))
    data = pin.GeometryData(geometry)
    for request in data.distanceRequests:
        request.enable_signed_distance = True
    return model, geometry, data


ORACLE = _combined()


def _oracle(q):
    model, geometry, gdata = ORACLE
    q_f, q_l = BIPLANE.planes_q(q)
    values = {name: v for name, v in zip(BIPLANE.frontal.joint_names, q_f)}
    values.update({f"lateral/{name}": v for name, v in zip(BIPLANE.lateral.joint_names, q_l)})
    full = np.zeros(model.nq)
    for j in range(1, model.njoints):
        full[model.joints[j].idx_q] = values[model.names[j]]
    data = model.createData()
    pin.computeDistances(model, data, geometry, gdata, full)
    return np.array([r.min_distance for r in gdata.distanceResults])


@given(unit_q)
@settings(max_examples=40)
def test_the_clearance_between_the_planes_equals_an_independent_oracle(u):
    q = configurations(BIPLANE, u)
    expected = _oracle(q)
    q_f, q_l = BIPLANE.planes_q(q)
    every = WORLD.between.distances(q_f, q_l)
    assert len(every) == len(expected) == len(WORLD.between)
    np.testing.assert_allclose(np.sort(every), np.sort(expected), rtol=0, atol=SAME_DISTANCE)
    assert WORLD.planes(q)[0] == pytest.approx(expected.min(), abs=SAME_DISTANCE)  # the pruned search is exact
    assert WORLD.clearance(q).planes == pytest.approx(every.min(), abs=SAME_DISTANCE)


@given(unit_q)
@settings(max_examples=25)
def test_distances_between_the_planes_are_symmetric(u):
    q = configurations(BIPLANE, u)
    q_f, q_l = BIPLANE.planes_q(q)
    forward = Between(WORLD.frontal, WORLD.lateral)
    backward = Between(WORLD.lateral, WORLD.frontal)
    n_lateral = len({lateral for _, lateral in forward.pairs})
    d_fl = forward.distances(q_f, q_l).reshape(-1, n_lateral)
    d_lf = backward.distances(q_l, q_f).reshape(n_lateral, -1)
    np.testing.assert_allclose(d_fl, d_lf.T, rtol=0, atol=SAME_DISTANCE)
    assert forward.clearance(q_f, q_l)[0] == pytest.approx(backward.clearance(q_l, q_f)[0], abs=SAME_DISTANCE)


def test_a_biplane_with_its_planes_swapped_has_the_same_clearance():
    swapped = Biplane(BIPLANE.lateral, BIPLANE.frontal)
    world = BiplaneWorld(swapped)
    rng = np.random.default_rng(3)
    k = BIPLANE.table_nq
    Q = configurations(BIPLANE, rng.random((20, BIPLANE.nq)))
    Q_swapped = np.concatenate((Q[:, :k], Q[:, k + 5:], Q[:, k:k + 5]), axis=1)
    np.testing.assert_allclose(WORLD.planes(Q), world.planes(Q_swapped), rtol=0, atol=SAME_DISTANCE)


# --- presets ----------------------------------------------------------------------------------------------
def test_load_preset_reads_a_biplane_preset_as_its_frontal_plane():
    system = carmkin.load_preset("angio-biplane")
    assert system.name == "angio-biplane"
    assert system == dataclasses.replace(BIPLANE.frontal, name="angio-biplane")
    assert "angio-biplane" in carmkin.list_presets()


def test_every_value_of_the_biplane_preset_has_a_provenance():
    provenance = preset_provenance("angio-biplane")
    own = {k: p for k, p in provenance.items() if not k.startswith(("frontal.", "lateral.carm", "lateral.body",
                                                                    "lateral.table"))}
    assert set(own) >= {"biplane.frontal", "biplane.lateral", "lateral.setup.table_origin_in_xray_mm",
                        "rest.lateral.angular_deg", "rest.lateral.orbital_deg"}
    for key, p in provenance.items():
        if key not in ("name", "description"):
            assert p.kind in ("source", "assumption") and p.note, key
    assert provenance["lateral.setup.table_x_axis_in_xray"].file.endswith("angio-lateral.toml")
    assert provenance["lateral.body.c_radius_mm"].file.endswith("angio-lateral.toml")
    assert provenance["frontal.carm.orbital_offset_mm"].file.endswith("angio-floor.toml")


def _write(tmp_path, text, name="mine.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


GOOD = """
name = "mine"
[biplane]
frontal = "angio-floor"
lateral = "angio-ceiling"
[lateral.setup]
table_origin_in_xray_mm = [0.0, 0.0, 810.0]
table_x_axis_in_xray = [0.0, 1.0, 0.0]
table_z_axis_in_xray = [-1.0, 0.0, 0.0]
[rest.lateral]
angular_deg = 90.0
orbital_deg = -90.0
"""


def test_a_users_biplane_file_loads(tmp_path):
    biplane = load_biplane(_write(tmp_path, GOOD))
    assert biplane.name == "mine"
    assert biplane.frontal == BIPLANE.frontal.replace(name="angio-floor")
    assert np.degrees(biplane.rest[-2:]).tolist() == pytest.approx([90.0, -90.0])


def test_the_builtin_lateral_plane_turns_its_c_over_the_patient_around_the_frontal_one():
    """angio-biplane's lateral plane (angio-lateral): its C-arc larger than the frontal's, its arm axis vertical
    (the C's guide above the isocentre) and its beam across the table at rest (table frame: X0 left, Y0 down)."""
    lateral = BIPLANE.lateral
    assert lateral.body.c_radius > BIPLANE.frontal.carm.source_to_orbital_axis + BIPLANE.frontal.body.c_thickness
    beam = BIPLANE.fk(np.array(BIPLANE.rest))[1][:3, 2]
    assert abs(beam[0]) == pytest.approx(1.0, abs=1e-12)
    frames = lateral.dh_frames(BIPLANE.planes_q(np.array(BIPLANE.rest))[1])
    assert abs(frames[3][1, 2]) == pytest.approx(1.0, abs=1e-12)  # the angular axis (Z of DH frame 3) along Y0


def test_a_biplane_whose_planes_intersect_at_rest_is_refused_naming_the_field(tmp_path):
    path = _write(tmp_path, GOOD.replace("orbital_deg = -90.0", "orbital_deg = 0.0").replace("angular_deg = 90.0",
                                                                                             "angular_deg = 0.0"))
    read_biplane(path)  # the value itself needs no collision model
    with pytest.raises(BiplaneError, match=r"mine\.toml: Biplane\.rest: the planes intersect at rest .* overlap by "
                                           r"[\d.]+ mm; change .*\[rest\.\*\].*\[lateral\.setup\]"):
        load_biplane(path)
    with pytest.raises(BiplaneError, match="the planes intersect at rest"):
        check_rest(Biplane(BIPLANE.frontal, BIPLANE.frontal))


def test_mismatched_tables_are_refused_naming_the_field(tmp_path):
    other = dataclasses.replace(BIPLANE.lateral.table, translation=JointRange(-0.5, 0.5, "table_translation"))
    with pytest.raises(BiplaneError, match=r"Biplane\.lateral\.table must be Biplane\.frontal\.table .* its "
                                           r"translation differ"):
        Biplane(BIPLANE.frontal, BIPLANE.lateral.replace(table=other))
    with pytest.raises(BiplaneError, match=r"mine\.toml: Biplane\.lateral\.table .* translation, top_size, "
                                           r"top_center, joints differ"):
        load_biplane(_write(tmp_path, GOOD.replace('"angio-ceiling"', '"siremobile-iso-c3d"')))


def test_planes_without_one_isocentre_are_refused_naming_the_field(tmp_path):
    text = GOOD.replace("[0.0, 0.0, 810.0]", "[0.0, 0.0, 850.0]")
    with pytest.raises(BiplaneError, match=r"Biplane\.lateral\.setup: the planes must share one isocentre, .* 40\.0 mm "
                                           r"apart \(at most 1 mm\)"):
        load_biplane(_write(tmp_path, text))


@pytest.mark.parametrize("edit, error, message", [
    (("frontal = \"angio-floor\"", "frontal = \"angio-flor\""), UnknownPresetError, "did you mean 'angio-floor'"),
    (("lateral = \"angio-ceiling\"\n", ""), PresetError, r"missing key \[biplane\] lateral"),
    (("orbital_deg = -90.0", "orbital_dg = -90.0"), PresetError, r"unknown key 'orbital_dg' in \[rest\.lateral\]; "
                                                                  "did you mean 'orbital_deg'"),
    (("orbital_deg = -90.0", "orbital_deg = \"-90\""), PresetError, r"\[rest\.lateral\] orbital_deg must be a number "
                                                                      r"\(deg\)"),
    (("[rest.lateral]", "[rest.lateal]"), PresetError, r"unknown section 'lateal' in \[rest\]"),
    (("angular_deg = 90.0", "angular_deg = 200.0"), BiplaneError, r"Biplane\.rest: lateral\.angular = 3\.49066 is "
                                                                  "outside its range"),
    (("lateral = \"angio-ceiling\"", "lateral = \"angio-biplane\""), PresetError, "is itself a biplane preset"),
    (("table_x_axis_in_xray = [0.0, 1.0, 0.0]", "gamma1_deg = 90.0\ntable_x_axis_in_xray = [0.0, 1.0, 0.0]"),
     PresetError, r"\[lateral\.setup\] mixes"),
])
def test_bad_biplane_files_are_refused_naming_the_key(tmp_path, edit, error, message):
    with pytest.raises(error, match=message):
        load_biplane(_write(tmp_path, GOOD.replace(*edit)))


def test_a_one_plane_preset_is_not_a_biplane():
    with pytest.raises(PresetError, match="not a biplane preset"):
        read_biplane("angio-floor")


@pytest.mark.parametrize("args, message", [
    (("frontal", "lateral"), r"Biplane\.frontal must be a carmkin\.CArmSystem"),
    ((None, None), r"Biplane\.frontal must be a carmkin\.CArmSystem .*, got NoneType"),
    ((carmkin.load_preset("angio-floor"), 3), r"Biplane\.lateral must be a carmkin\.CArmSystem .*, got int"),
])
def test_a_biplane_of_other_things_is_refused(args, message):
    with pytest.raises(BiplaneError, match=message):
        Biplane(*args)


@pytest.mark.parametrize("rest, message", [
    ((0.0,) * 14, r"Biplane\.rest must be real numbers \(m, rad\) of shape \(15,\)"),
    ((math.nan,) * 15, r"Biplane\.rest"),
    ((0.0,) * 14 + (3.0,), r"Biplane\.rest: lateral\.orbital = 3 is outside its range"),
])
def test_a_bad_rest_is_refused(rest, message):
    with pytest.raises(BiplaneError, match=message):
        Biplane(BIPLANE.frontal, BIPLANE.lateral, rest)


@pytest.mark.parametrize("q", [np.zeros(14), np.full(15, np.inf), "q", [[0.0] * 16]])
def test_a_bad_biplane_configuration_is_refused(q):
    with pytest.raises(BiplaneError, match=r"^q must be (real numbers|finite)"):
        BIPLANE.fk(q)


def test_a_configuration_in_mm_and_degrees_is_caught_by_the_planes_unit_check():
    with pytest.raises(carmkin.InvalidConfigurationError, match=r"\(table_translation\) = 90 m is not a C-arm joint "
                                                                r"value.*given in mm\?"):
        BIPLANE.fk(np.full(15, 90.0))


def test_each_plane_is_measured_against_table_floor_and_patient():
    from carmkin.patient import ParametricPatient
    from carmkin.world import World

    patient = ParametricPatient.on_table(BIPLANE.frontal)
    world = BiplaneWorld(BIPLANE, patient)
    rng = np.random.default_rng(5)
    for q in configurations(BIPLANE, rng.random((10, BIPLANE.nq))):
        q_f, q_l = BIPLANE.planes_q(q)
        got = world.clearance(q)
        assert got.frontal == pytest.approx(World(BIPLANE.frontal, patient).distances(q=q_f).min(), abs=SAME_DISTANCE)
        assert got.lateral == pytest.approx(World(BIPLANE.lateral, patient).distances(q=q_l).min(), abs=SAME_DISTANCE)
        assert got.minimum == min(got.planes, got.frontal, got.lateral)
    with pytest.raises(BiplaneError, match="biplane must be a carmkin.model.biplane.Biplane"):
        BiplaneWorld(BIPLANE.frontal)


@pytest.mark.parametrize("q", [np.zeros(15, complex), np.zeros(15, bool), np.array("2"), None, [[0.0] * 15] * 2 + [[0.0]]])
def test_junk_configurations_are_typed_errors_without_warnings(q):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(BiplaneError, match=r"^q must be"):
            BIPLANE.planes_q(q)


@pytest.mark.parametrize("q_f, q_l, message", [
    (np.zeros(10), np.zeros(9), r"q_lateral must be \(10,\) or \(N, 10\)"),
    (np.zeros((2, 10)), np.zeros(10), "as many configurations"),
    (np.zeros(10), "q", "q_lateral must be real numbers"),
    (np.zeros((1, 1, 10)), np.zeros(10), r"q_frontal must be \(10,\) or \(N, 10\)"),
])
def test_join_refuses_mismatched_plane_vectors(q_f, q_l, message):
    with pytest.raises(BiplaneError, match=message):
        BIPLANE.join(q_f, q_l)


def test_plane_presets_are_found_beside_the_biplane_file(tmp_path):
    folder = tmp_path / "suite"
    folder.mkdir()
    (folder / "front.toml").write_text('base = "angio-floor"\nname = "front"\n[carm]\nwigwag_min_deg = -90.0  '
                                       '# assumption: a narrower L-arm\n')
    path = _write(folder, GOOD.replace('frontal = "angio-floor"', 'frontal = "front.toml"  # assumption: ours'))
    biplane = load_biplane(path)
    assert biplane.frontal.name == "front" and biplane.frontal.carm.wigwag.lower == pytest.approx(-math.pi / 2)
    assert carmkin.load_preset(path).name == "mine"  # the frontal plane, named after the biplane
    provenance = preset_provenance(path)
    assert provenance["frontal.carm.wigwag_min_deg"].note == "a narrower L-arm"
    assert provenance["biplane.frontal"].note == "ours"
