"""DICOM XA geometry (carmkin.interop.dicom, dicom_io): positioner and table matrices against the sign rules
of PS3.3, pose ↔ Isocenter Reference System ↔ pose and pose ↔ XA angles ↔ pose over random non-isocentric
systems, the operator-relative table terms, synthetic datasets written and read with pydicom, and the moves
that reproduce a DICOM image's view."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from strategies import PRESET, configurations, rotations, systems

import carmkin
from carmkin.interop import dicom
from carmkin.imaging.projection import PATIENT_POSITIONS

#: Round-trip tolerance of issue 15 (m, rad, deg).
ROUND_TRIP = 1e-9
#: Through a file: Enhanced XA stores angles and positions as FL (float32) — m and rad.
FILE_ROUND_TRIP = 1e-5

MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
finite = dict(allow_nan=False, allow_infinity=False)


def pose_error(T1, T2) -> float:
    E = T1[:3, :3].T @ T2[:3, :3]
    sin = 0.5 * np.linalg.norm([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    return max(float(np.linalg.norm(T1[:3, 3] - T2[:3, 3])), float(np.arctan2(sin, 0.5 * (np.trace(E) - 1))))


def angle_difference(a, b) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


# --- matrices and the standard's sign rules -------------------------------------------------------------
def test_positioner_angle_signs_follow_ps3_3():
    """Ap1 from −Y to +X positive (about Z); Ap2 from −Y to +Z positive; the beam runs source → isocentre
    → detector, so the detector sits on −Yp."""
    detector = lambda *a: -dicom.positioner_matrix(*a)[1]  # noqa: E731
    assert np.allclose(detector(0, 0), [0, -1, 0])
    assert np.allclose(detector(90, 0), [1, 0, 0])
    assert np.allclose(detector(0, 90), [0, 0, 1])
    assert np.allclose(detector(-90, 0), [-1, 0, 0])


def test_table_angle_signs_follow_ps3_3():
    """At1: +Zt turns from +Z towards +X; At2: the head (+Zt) goes up (−Y); At3: the left (+Xt) goes up."""
    assert np.allclose(dicom.table_matrix(90, 0, 0)[2], [1, 0, 0])
    assert dicom.table_matrix(0, 30, 0)[2][1] < 0
    assert dicom.table_matrix(0, 0, 30)[0][1] < 0
    assert np.allclose(dicom.table_matrix(0, 0, 0), np.eye(3))


angles = st.tuples(st.floats(-179.9, 179.9, **finite), st.floats(-89.9, 89.9, **finite), st.floats(-179.9, 179.9, **finite))
CONVENTIONS = sorted(dicom.CONVENTIONS)


@pytest.mark.parametrize("convention", CONVENTIONS)
@given(a=angles)
def test_positioner_and_table_angles_round_trip(convention, a):
    positioner = (lambda *x: dicom.positioner_matrix(*x, convention=convention),
                  lambda M: dicom.positioner_angles(M, convention=convention))
    for forward, backward in (positioner, (dicom.table_matrix, dicom.table_angles)):
        M = forward(*a)
        assert np.allclose(M @ M.T, np.eye(3), atol=1e-12) and np.isclose(np.linalg.det(M), 1.0)
        assert max(angle_difference(x, y) for x, y in zip(backward(M), a)) <= ROUND_TRIP


@pytest.mark.parametrize("convention", CONVENTIONS)
@given(R=rotations())
def test_any_rotation_has_positioner_and_table_angles(convention, R):
    assume(abs(R[1, 2]) < 1 - 1e-6 and abs(R[2, 1]) < 1 - 1e-6)
    again = dicom.positioner_matrix(*dicom.positioner_angles(R, convention=convention), convention=convention)
    assert np.abs(again - R).max() <= ROUND_TRIP
    assert np.abs(dicom.table_matrix(*dicom.table_angles(R)) - R).max() <= ROUND_TRIP


@given(a=angles)
def test_the_conventions_differ_only_in_the_signs_of_ap2_and_ap3(a):
    """``literal`` is ``beam`` with Ap2 and Ap3 negated, and Ap1 is the same in both (an independent route:
    the matrices themselves)."""
    assert np.abs(dicom.positioner_matrix(a[0], -a[1], -a[2]) - dicom.positioner_matrix(*a, convention="literal")).max() <= 1e-15
    beam, literal = (dicom.positioner_angles(dicom.positioner_matrix(*a), convention=c) for c in ("beam", "literal"))
    assert angle_difference(beam[0], literal[0]) <= ROUND_TRIP
    assert abs(beam[1] + literal[1]) <= ROUND_TRIP and angle_difference(beam[2], -literal[2]) <= ROUND_TRIP


def test_each_convention_says_what_it_reads():
    """The words of docs/interop.md, checked on the vectors: ``beam`` — Ap2 > 0 tilts the detector (−Yp) to +Z
    and Ap3 > 0 turns Xp, Zp clockwise as seen from behind the detector looking towards the source (right-handed
    about +Yp); ``literal`` — Ap2 > 0 tilts the source (+Yp) to +Z, Ap3 > 0 clockwise as seen from the source."""
    for convention, sign in (("beam", 1.0), ("literal", -1.0)):
        M = dicom.positioner_matrix(0.0, 30.0, 0.0, convention=convention)
        assert -M[1] @ [0, 0, 1] == pytest.approx(sign * 0.5)  # detector direction's Z component
        Zp0 = dicom.positioner_matrix(20.0, 10.0, 0.0, convention=convention)[2]
        M = dicom.positioner_matrix(20.0, 10.0, 15.0, convention=convention)
        turn = np.cross(Zp0, M[2]) @ M[1]  # > 0: right-handed about +Yp, i.e. clockwise looking along +Yp
        assert np.sign(turn) == sign and abs(turn) == pytest.approx(math.sin(math.radians(15.0)))


# --- one image: Isocenter Reference System ----------------------------------------------------------------
@pytest.mark.parametrize("convention", CONVENTIONS)
@given(data=st.data())
def test_isocenter_reference_system_round_trip(convention, data):
    system = data.draw(systems())
    q = data.draw(configurations(system, beyond=0.3))
    iso = data.draw(st.floats(0.2, 1.2, **finite))
    geometry = dicom.isocenter_geometry(system, q, iso, convention=convention)
    assert geometry.convention == convention
    assume(abs(abs(geometry.positioner_secondary_deg) - 90) > 1e-3)
    assert abs(geometry.source_to_isocenter_mm - iso * 1000) <= ROUND_TRIP * 1000
    assert pose_error(geometry.source_pose(), system.fk(q)) <= ROUND_TRIP


def test_isocenter_reference_system_on_the_motorized_table():
    rng = np.random.default_rng(5)
    for _ in range(30):
        q = MOTORIZED.lower + rng.random(MOTORIZED.nq) * (MOTORIZED.upper - MOTORIZED.lower)
        assert pose_error(dicom.isocenter_geometry(MOTORIZED, q).source_pose(), MOTORIZED.fk(q)) <= ROUND_TRIP


def test_the_presets_table_is_level_and_the_beam_vertical_at_rest():
    """The preset puts the table frame on the C-arm's axes at rest (§4.6.1): table angles 0, beam up."""
    q = np.where(PRESET.prismatic, 0.5 * (PRESET.lower + PRESET.upper), 0.0)
    g = dicom.isocenter_geometry(PRESET, q)
    assert max(abs(g.table_rotation_deg), abs(g.table_head_tilt_deg), abs(g.table_cradle_tilt_deg)) <= ROUND_TRIP
    assert max(abs(g.positioner_primary_deg), abs(g.positioner_secondary_deg)) <= ROUND_TRIP


def test_table_joints_appear_as_the_table_angles():
    q = 0.5 * (MOTORIZED.lower + MOTORIZED.upper)
    names = MOTORIZED.joint_names
    base = dicom.isocenter_geometry(MOTORIZED, q)
    for joint, attribute in (("table_rotation", "table_rotation_deg"), ("table_trendelenburg", "table_head_tilt_deg"),
                             ("table_tilt", "table_cradle_tilt_deg")):
        moved = q.copy()
        moved[names.index(joint)] += math.radians(7)
        g = dicom.isocenter_geometry(MOTORIZED, moved)
        assert abs(abs(getattr(g, attribute) - getattr(base, attribute)) - 7.0) <= 1e-9, joint


# --- patient-based XA angles -----------------------------------------------------------------------------
@pytest.mark.parametrize("convention", CONVENTIONS)
@pytest.mark.parametrize("code", sorted(PATIENT_POSITIONS))
@given(data=st.data())
def test_xa_angles_round_trip(code, convention, data):
    """pose → XA angles → pose for every Patient Position code and both conventions; the primary and
    secondary angles (patient-based, unambiguous) are the same in both conventions."""
    system = data.draw(systems())
    q = data.draw(configurations(system, beyond=0.3))
    origin = data.draw(st.tuples(*[st.floats(-0.5, 0.5, **finite)] * 3))
    patient = dicom.patient_pose(code, origin)
    T = system.fk(q)
    primary, secondary, rotation = dicom.xa_angles(T, patient, convention=convention)
    assume(abs(abs(secondary) - 90) > 1e-3)
    assert (primary, secondary) == dicom.xa_angles(T, patient)[:2]
    iso = data.draw(st.floats(0.2, 1.2, **finite))
    T_again = dicom.pose_from_xa_angles(primary, secondary, T[:3, 3] + iso * T[:3, 2], iso, patient, rotation,
                                        convention=convention)
    assert pose_error(T_again, T) <= ROUND_TRIP


def beam(direction):
    """A source pose whose beam (source → detector) runs along ``direction`` (table frame)."""
    z = np.asarray(direction, dtype=float)
    x = np.cross([0.3, 0.2, 1.0], z)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack((x, np.cross(z, x), z))
    return T


@pytest.mark.parametrize("direction, position, expected", [
    ((0, -1, 0), "HFS", (0, 0)),       # source under the table, detector above the chest: AP
    ((1, 0, 0), "HFS", (90, 0)),       # detector at the table's left = the patient's left: LAO 90
    ((1, 0, 0), "FFS", (-90, 0)),      # the same beam with the patient turned: RAO 90
    ((0, 0, 1), "HFS", (0, 90)),       # detector towards the head: CRA 90
    ((0, 0, 1), "FFS", (0, -90)),      # ... towards the feet of a feet-first patient: CAU 90
    ((0, 1, 0), "HFP", (0, 0)),        # prone: detector under the table faces the chest
    ((0, 1, 0), "HFDL", (90, 0)),      # lying on the left side: the left is down
])
def test_xa_angles_are_patient_based(direction, position, expected):
    primary, secondary, _ = dicom.xa_angles(beam(direction), position)
    assert angle_difference(primary, expected[0]) <= 1e-9 or abs(abs(secondary) - 90) < 1e-9
    assert abs(secondary - expected[1]) <= 1e-9


# --- operator-relative table terms -------------------------------------------------------------------------
def test_longitudinal_and_lateral_are_the_operators_terms():
    """A table translation along its long axis is a *lateral* increment; moving the table top sideways is a
    *longitudinal* one (PS3.3 C.8.7.4.1.2–3: an operator beside the table facing the patient)."""
    q = 0.5 * (MOTORIZED.lower + MOTORIZED.upper)
    names = MOTORIZED.joint_names

    def moved(joint, delta):
        q2 = q.copy()
        q2[names.index(joint)] += delta
        return dicom.table_increments(MOTORIZED, q, q2)

    along = moved("table_translation", 0.010)  # the C-arm moves +10 mm along Z0: the table −10 mm
    assert along["TableLateralIncrement"] == pytest.approx(-10.0) and abs(along["TableLongitudinalIncrement"]) < 1e-9
    across = moved("table_lateral", 0.010)
    assert across["TableLongitudinalIncrement"] == pytest.approx(10.0) and abs(across["TableLateralIncrement"]) < 1e-9
    up = moved("table_height", 0.010)
    assert up["TableVerticalIncrement"] == pytest.approx(-10.0)  # downwards is positive
    for joint in ("vertical", "horizontal", "angular", "orbital"):  # C-arm joints do not move the table
        assert max(abs(v) for v in moved(joint, 0.05).values()) < 1e-9


# --- datasets through pydicom ----------------------------------------------------------------------------
def through_a_file(ds):
    pydicom = pytest.importorskip("pydicom")
    buffer = io.BytesIO()
    ds.save_as(buffer, enforce_file_format=True)
    buffer.seek(0)
    return pydicom.dcmread(buffer)


@pytest.mark.parametrize("convention", CONVENTIONS)
@settings(max_examples=15)
@given(data=st.data())
def test_enhanced_xa_dataset_round_trip(convention, data):
    pytest.importorskip("pydicom")
    from carmkin.interop import dicom_io

    system = data.draw(systems())
    q = data.draw(configurations(system))
    ds = through_a_file(dicom_io.write_enhanced_xa(system, q, convention=convention))
    assert ds.SharedFunctionalGroupsSequence[0].IsocenterReferenceSystemSequence[0].TableHeadTiltAngle is not None
    view = dicom_io.view_from_dataset(ds, convention=convention)
    assert view.source == "isocenter reference system"
    assert pose_error(view.pose, system.fk(q)) <= FILE_ROUND_TRIP


@settings(max_examples=15)
@given(st.data())
def test_xa_dataset_round_trip(data):
    pytest.importorskip("pydicom")
    from carmkin.interop import dicom_io

    system = data.draw(systems())
    q = data.draw(configurations(system))
    code = data.draw(st.sampled_from(sorted(PATIENT_POSITIONS)))
    ds = through_a_file(dicom_io.write_xa(system, q, code))
    assert ds.PatientPosition == code
    T = system.fk(q)
    assume(abs(abs(float(ds.PositionerSecondaryAngle)) - 90) > 1e-3)
    view = dicom_io.view_from_dataset(ds, isocenter=T[:3, 3] + system.carm.orbital_offset * T[:3, 2])
    # XA leaves the rotation about the beam open: compare the beam (source position and direction).
    assert np.linalg.norm(view.pose[:3, 3] - T[:3, 3]) <= FILE_ROUND_TRIP
    assert np.linalg.norm(view.pose[:3, 2] - T[:3, 2]) <= FILE_ROUND_TRIP


def test_missing_geometry_is_reported():
    pydicom = pytest.importorskip("pydicom")
    from carmkin.interop import dicom_io

    ds = pydicom.Dataset()
    with pytest.raises(dicom.DicomGeometryError, match=r"no geometry: .*PositionerPrimaryAngle \(0018,1510\)"):
        dicom_io.view_from_dataset(ds)
    ds.PositionerPrimaryAngle = 10.0
    with pytest.raises(dicom.DicomGeometryError, match=r"PatientPosition \(0018,5100\) is required"):
        dicom_io.view_from_dataset(ds)
    with pytest.raises(dicom.DicomGeometryError, match=r"PositionerSecondaryAngle \(0018,1511\) is required"):
        dicom_io.view_from_dataset(ds, patient_position="HFS")
    ds.SOPClassUID = dicom_io.ENHANCED_XA_SOP_CLASS
    with pytest.raises(dicom.DicomGeometryError, match=r"SharedFunctionalGroupsSequence \(5200,9229\) is required"):
        dicom_io.view_from_dataset(ds)


def test_moves_reproduce_the_view_of_a_dicom_image():
    """An image taken after moving the orbital joint and the table (translation, lateral): its Enhanced XA
    geometry, read back, gives joints with the same view (closed form on the plain chain, QP with the
    motorized table)."""
    pytest.importorskip("pydicom")
    from carmkin.interop import dicom_io
    from carmkin.reposition.dicom import moves_for_dataset

    for system in (PRESET, MOTORIZED):
        q_now = 0.5 * (system.lower + system.upper)
        q_image = q_now.copy()
        for joint, delta in (("orbital", 0.2), ("table_translation", 0.05), ("table_lateral", 0.02)):
            if joint in system.joint_names:
                q_image[system.joint_names.index(joint)] += delta
        ds = through_a_file(dicom_io.write_enhanced_xa(system, q_image))
        view, result = moves_for_dataset(system, ds, q_current=q_now)
        assert result.success, result.reason
        assert pose_error(system.fk(result.q), system.fk(q_image)) <= FILE_ROUND_TRIP


def test_moves_reproduce_the_beam_of_an_xa_image():
    """XA angles + the isocentre fix the source and the beam; the rotation about the beam is left free."""
    pytest.importorskip("pydicom")
    from carmkin.interop import dicom_io
    from carmkin.reposition.dicom import moves_for_dataset

    q_now = 0.5 * (PRESET.lower + PRESET.upper)
    q_image = q_now + np.array([0.05, 0.0, 0.0, 0.0, 0.1, 0.2])
    T = PRESET.fk(q_image)
    ds = through_a_file(dicom_io.write_xa(PRESET, q_image, "FFS", (0.05, 0.0, -0.1)))
    view, result = moves_for_dataset(PRESET, ds, q_current=q_now, patient_origin=(0.05, 0.0, -0.1),
                                     isocenter=T[:3, 3] + PRESET.carm.orbital_offset * T[:3, 2])
    assert not view.full_pose and result.success, result.reason
    reached = PRESET.fk(result.q)
    assert np.linalg.norm(reached[:3, 3] - T[:3, 3]) <= FILE_ROUND_TRIP
    assert np.linalg.norm(reached[:3, 2] - T[:3, 2]) <= FILE_ROUND_TRIP


def test_the_two_readings_of_ap2_and_ap3_are_independent():
    """Issue 31: "literal" once flipped Ap2 and Ap3 together; the two ambiguities of the standard's text are
    independent (PySkinDose flips only Ap2). Each reading applies to its own angle: the matrix of (a1, a2, a3)
    read one way is the beam reading's matrix of (a1, ±a2, ±a3), and every convention round-trips."""
    rng = np.random.default_rng(31)
    for _ in range(50):
        a1, a2, a3 = rng.uniform(-170, 170), rng.uniform(-80, 80), rng.uniform(-170, 170)
        for convention, (s2, s3) in {"literal-ap2": (-1, 1), "pyskindose": (-1, 1), "literal-ap3": (1, -1),
                                     "literal": (-1, -1), ("literal", "beam"): (-1, 1),
                                     ("beam", "literal"): (1, -1)}.items():
            M = dicom.positioner_matrix(a1, a2, a3, convention=convention)
            np.testing.assert_allclose(M, dicom.positioner_matrix(a1, s2 * a2, s3 * a3), atol=1e-12)
            np.testing.assert_allclose(dicom.positioner_angles(M, convention=convention), (a1, a2, a3), atol=1e-9)
    for bad in ("beam-ish", ("beam",), ("beam", "beam", "beam"), ("beam", 1), None):
        with pytest.raises(dicom.DicomGeometryError, match="convention"):
            dicom.positioner_matrix(10.0, 10.0, convention=bad)
