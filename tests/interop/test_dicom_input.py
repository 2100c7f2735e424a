"""DICOM geometry from outside is right or refused (issue 19): each defect reproduced (a negative
DistanceSourceToIsocenter planned to, a scaled or reflected matrix read as angles, an empty Patient Position
read as HFS), the one attribute reader (missing, empty, multi-valued, non-numeric, NaN, out of range → a
typed error naming keyword and tag), junk at every public function of carmkin.interop.dicom* (a CarmkinError
naming the argument, no warning), and `carmkin dicom --read` on bad files (exit 2, one line)."""

from __future__ import annotations

import io
import math
import warnings

import numpy as np
import pytest
from strategies import PRESET

import carmkin
from carmkin.cli import main
from carmkin.errors import CarmkinError, DicomAttributeError, DicomGeometryError
from carmkin.interop import dicom

pydicom = pytest.importorskip("pydicom")
from carmkin.interop import dicom_attributes, dicom_io  # noqa: E402  (needs pydicom)
from carmkin.reposition.dicom import moves_for_dataset  # noqa: E402

Q = 0.5 * (PRESET.lower + PRESET.upper) + np.array([0.0, 0.0, 0.0, 0.0, 0.2, 0.3])


def through_a_file(ds):
    buffer = io.BytesIO()
    ds.save_as(buffer, enforce_file_format=True)
    buffer.seek(0)
    return pydicom.dcmread(buffer)


def enhanced():
    return through_a_file(dicom_io.write_enhanced_xa(PRESET, Q))


def iso_item(ds):
    return ds.SharedFunctionalGroupsSequence[0].IsocenterReferenceSystemSequence[0]


def xa(position="HFS"):
    return through_a_file(dicom_io.write_xa(PRESET, Q, position))


# --- the defects of the issue, reproduced -------------------------------------------------------------------
def test_a_negative_source_to_isocenter_distance_is_refused_not_planned_to():
    """Today: the source 1.25 m away on the detector's side, and moves_for_dataset plans to it."""
    ds = enhanced()
    ds.SharedFunctionalGroupsSequence[0].XRayGeometrySequence[0].DistanceSourceToIsocenter = -1250.0
    message = "DistanceSourceToIsocenter (0018,9402) must be > 0 mm, got -1250"
    with pytest.raises(DicomAttributeError, match=message.replace("(", r"\(").replace(")", r"\)")) as info:
        moves_for_dataset(PRESET, ds, q_current=Q)
    assert (info.value.keyword, info.value.tag) == ("DistanceSourceToIsocenter", "(0018,9402)")
    with pytest.raises(DicomAttributeError, match="must be > 0 mm"):
        dicom_io.view_from_dataset(ds)


@pytest.mark.parametrize("function", [dicom.positioner_angles, dicom.table_angles])
def test_only_rotations_have_angles(function):
    """Today a scaled matrix reads 20° as 30.9°, a reflected one as −20°, zeros give angles."""
    R = dicom.positioner_matrix(20.0, 0.0, 0.0)
    for bad, words in ((1.5 * R, "orthonormal"), (R @ np.diag([1.0, 1.0, -1.0]), "det"),
                       (np.zeros((3, 3)), "orthonormal"), (R + 1e-6, "orthonormal")):
        with pytest.raises(DicomGeometryError, match=words):
            function(bad)
    assert function(R + 1e-12) is not None  # rounding within the stated tolerance is accepted


def test_an_empty_patient_position_is_not_read_as_hfs():
    ds = xa("FFS")
    T = PRESET.fk(Q)
    isocenter = T[:3, 3] + PRESET.carm.orbital_offset * T[:3, 2]
    expected = dicom_io.view_from_dataset(ds, isocenter).pose
    for value in ("", None):
        ds.PatientPosition = value
        with pytest.raises(DicomAttributeError, match=r"PatientPosition \(0018,5100\) is required"):
            dicom_io.view_from_dataset(ds, isocenter)
    del ds.PatientPosition
    with pytest.raises(DicomAttributeError, match="pass patient_position="):
        moves_for_dataset(PRESET, ds, q_current=Q, isocenter=isocenter)
    assert np.allclose(dicom_io.view_from_dataset(ds, isocenter, patient_position="FFS").pose, expected, atol=1e-12)
    ds.PatientPosition = "XYZ"
    with pytest.raises(DicomAttributeError, match=r"PatientPosition \(0018,5100\) must be one of"):
        dicom_io.view_from_dataset(ds, isocenter)


# --- the one attribute reader --------------------------------------------------------------------------------
ENHANCED_ATTRIBUTES = ["PositionerIsocenterPrimaryAngle", "PositionerIsocenterSecondaryAngle",
                       "PositionerIsocenterDetectorRotationAngle", "TableXPositionToIsocenter",
                       "TableYPositionToIsocenter", "TableZPositionToIsocenter", "TableHorizontalRotationAngle",
                       "TableHeadTiltAngle", "TableCradleTiltAngle"]


def tag_of(keyword):
    tag = pydicom.datadict.tag_for_keyword(keyword)
    return f"({tag >> 16:04X},{tag & 0xFFFF:04X})"


@pytest.mark.parametrize("keyword", ENHANCED_ATTRIBUTES + ["DistanceSourceToIsocenter"])
def test_every_enhanced_xa_attribute_is_required_and_checked(keyword):
    spec = dicom_attributes.ATTRIBUTES[keyword]
    item = (lambda ds: ds.SharedFunctionalGroupsSequence[0].XRayGeometrySequence[0]
            if keyword == "DistanceSourceToIsocenter" else iso_item(ds))
    pattern = f"{keyword} {tag_of(keyword)}".replace("(", r"\(").replace(")", r"\)")
    cases = [(None, "is required, the dataset has none"), ("empty", "is required, it is empty"), (math.nan, "must be finite"),
             (math.inf, "must be finite"), ([1.0, 2.0], "must hold one value"),
             (spec.high + 1.0, "must be within"), (spec.low - 1.0, "must be > 0" if spec.positive else "must be within")]
    for value, words in cases:
        ds = enhanced()
        if value is None:
            delattr(item(ds), keyword)
        elif value == "empty":
            item(ds)[keyword].value = None
        else:
            setattr(item(ds), keyword, value)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            with pytest.raises(DicomAttributeError, match=f"{pattern} {words}"):
                dicom_io.read_isocenter_geometry(through_a_file(ds) if value != "empty" else ds)


@pytest.mark.parametrize("keyword, value, words", [
    ("PositionerPrimaryAngle", 181.0, "must be within"), ("PositionerSecondaryAngle", -90.5, "must be within"),
    ("PositionerSecondaryAngle", "abcd", "cannot be read|must be a number"),
    ("DistanceSourceToIsocenter", 0.0, "must be > 0 mm"),
    ("DistanceSourceToIsocenter", -900.0, "must be > 0 mm, got -900"),
    ("PositionerSecondaryAngle", None, "is required, the dataset has none"),
    ("DistanceSourceToIsocenter", None, "is required, the dataset has none"),
])
def test_xa_attributes_are_checked_through_a_file(keyword, value, words):
    ds = xa()
    if value is None:
        delattr(ds, keyword)
    elif isinstance(value, str):  # a damaged file: the DS text replaced by letters of the same length
        setattr(ds, keyword, 12.5)
        buffer = io.BytesIO()
        ds.save_as(buffer, enforce_file_format=True)
        data = buffer.getvalue()
        assert data.count(b"12.5") == 1
        ds = pydicom.dcmread(io.BytesIO(data.replace(b"12.5", value.encode())))
    else:
        setattr(ds, keyword, value)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # pydicom's own warnings about the value must not leak either
        read = through_a_file(ds) if not isinstance(value, str) else ds
        with pytest.raises(DicomAttributeError, match=f"{keyword} {re_tag(keyword)} ({words})"):
            dicom_io.view_from_dataset(read)


def re_tag(keyword):
    return tag_of(keyword).replace("(", r"\(").replace(")", r"\)")


def test_functional_groups_and_frames():
    ds = enhanced()
    with pytest.raises(DicomAttributeError, match=r"XRayGeometrySequence \(0018,9476\) is required"):
        del ds.SharedFunctionalGroupsSequence[0].XRayGeometrySequence
        dicom_io.read_isocenter_geometry(ds)
    ds = enhanced()
    ds.PerFrameFunctionalGroupsSequence = [pydicom.Dataset(), pydicom.Dataset()]
    assert dicom_io.read_isocenter_geometry(ds, 1) == dicom_io.read_isocenter_geometry(enhanced())  # shared applies
    for frame in (2, -1, True, 0.0, "0", None):
        with pytest.raises(DicomGeometryError, match="frame must be"):
            dicom_io.read_isocenter_geometry(ds, frame)


# --- junk at every public function ---------------------------------------------------------------------------
JUNK_NUMBERS = [None, {}, "1.5", b"1", 1 + 0j, True, math.nan, math.inf, [1.0, 2.0], object()]
JUNK_MATRICES = [None, {}, "eye", b"1", np.eye(3) * (1 + 0j), np.eye(3, dtype=bool), np.full((3, 3), math.nan),
                 np.eye(4), np.eye(3)[:2], [[1, 0], [0, 1, 0]], 1.0]
JUNK_POSES = [None, {}, "HFSX", b"HFS", 1 + 0j, True, np.eye(3), np.full((4, 4), math.nan), 2 * np.eye(4), 1.0]
JUNK_POINTS = [None, {}, "0,0,0", b"0", 1 + 0j, True, [0.0, math.nan, 0.0], [0.0, 0.0], np.zeros((2, 3)), 1.0]
JUNK_DISTANCES = [{}, "1", b"1", 1 + 0j, True, math.nan, -1.0, 0.0, 1e9, [1.0]]
JUNK_SYSTEMS = [None, {}, "siremobile-iso-c3d", b"x", 1.0, object()]
JUNK_Q = [None, {}, "1,2,3,4,5,6", b"1", np.zeros(6) + 1j, np.zeros(6, dtype=bool), np.full(6, math.nan), np.zeros(5),
          np.zeros((2, 6)), 1.0]
JUNK_DATASETS = [None, {}, "ds.dcm", b"DICM", 1.0, object(), [pydicom.Dataset()]]
JUNK_NAMES = [None, {}, b"beam", 1.0, True, "nonsense"]
GOOD_DS = xa()
GOOD_T = PRESET.fk(Q)

#: (function, the good arguments, {argument: junk values}) for every public function.
CALLS = [
    (dicom.positioner_matrix, dict(primary_deg=10.0, secondary_deg=20.0, rotation_deg=5.0, convention="beam"),
     dict(primary_deg=JUNK_NUMBERS + [180.5], secondary_deg=JUNK_NUMBERS + [90.5], rotation_deg=JUNK_NUMBERS,
          convention=JUNK_NAMES)),
    (dicom.positioner_angles, dict(M=np.eye(3), convention="beam"), dict(M=JUNK_MATRICES, convention=JUNK_NAMES)),
    (dicom.table_matrix, dict(rotation_deg=1.0, head_tilt_deg=2.0, cradle_tilt_deg=3.0),
     dict(rotation_deg=JUNK_NUMBERS, head_tilt_deg=JUNK_NUMBERS + [91.0], cradle_tilt_deg=JUNK_NUMBERS)),
    (dicom.table_angles, dict(M=np.eye(3)), dict(M=JUNK_MATRICES)),
    (dicom.check_convention, dict(convention="beam"), dict(convention=JUNK_NAMES)),
    (dicom.IsocenterGeometry, dict(positioner_primary_deg=1.0, positioner_secondary_deg=2.0, detector_rotation_deg=3.0,
                                   table_position_mm=(1.0, 2.0, 3.0), table_rotation_deg=0.0, table_head_tilt_deg=0.0,
                                   table_cradle_tilt_deg=0.0, source_to_isocenter_mm=700.0, convention="beam"),
     dict(positioner_primary_deg=JUNK_NUMBERS, positioner_secondary_deg=JUNK_NUMBERS, table_position_mm=JUNK_POINTS,
          source_to_isocenter_mm=JUNK_DISTANCES + [None], convention=JUNK_NAMES)),
    (dicom.equipment_axes, dict(system=PRESET, q=Q), dict(system=JUNK_SYSTEMS, q=JUNK_Q)),
    (dicom.isocenter_frame, dict(system=PRESET, q=Q, source_to_isocenter=0.7),
     dict(system=JUNK_SYSTEMS, q=JUNK_Q, source_to_isocenter=JUNK_DISTANCES)),
    (dicom.isocenter_geometry, dict(system=PRESET, q=Q, source_to_isocenter=0.7, convention="beam"),
     dict(system=JUNK_SYSTEMS, q=JUNK_Q, source_to_isocenter=JUNK_DISTANCES, convention=JUNK_NAMES)),
    (dicom.xa_angles, dict(T_source=GOOD_T, patient="HFS", convention="beam"),
     dict(T_source=JUNK_POSES, patient=JUNK_POSES, convention=JUNK_NAMES)),
    (dicom.pose_from_xa_angles, dict(primary_deg=10.0, secondary_deg=5.0, isocenter=(0.0, 0.0, 0.0),
                                     source_to_isocenter=0.7, patient="HFS", rotation_deg=0.0, convention="beam"),
     dict(primary_deg=JUNK_NUMBERS, secondary_deg=JUNK_NUMBERS + [-91.0], isocenter=JUNK_POINTS,
          source_to_isocenter=JUNK_DISTANCES + [None], patient=JUNK_POSES, rotation_deg=JUNK_NUMBERS,
          convention=JUNK_NAMES)),
    (dicom.table_position, dict(system=PRESET, q=Q), dict(system=JUNK_SYSTEMS, q=JUNK_Q)),
    (dicom.table_increments, dict(system=PRESET, q_first=Q, q=Q), dict(system=JUNK_SYSTEMS, q_first=JUNK_Q, q=JUNK_Q)),
    (dicom_io.write_xa, dict(system=PRESET, q=Q, patient_position="HFS", patient_origin=(0.0, 0.0, 0.0),
                             source_to_isocenter=0.7),
     dict(system=JUNK_SYSTEMS, q=JUNK_Q, patient_position=JUNK_NAMES, patient_origin=JUNK_POINTS,
          source_to_isocenter=JUNK_DISTANCES)),
    (dicom_io.write_enhanced_xa, dict(system=PRESET, q=Q, source_to_isocenter=0.7, patient_position="HFS",
                                      convention="beam"),
     dict(system=JUNK_SYSTEMS, q=JUNK_Q, source_to_isocenter=JUNK_DISTANCES, patient_position=JUNK_NAMES,
          convention=JUNK_NAMES)),
    (dicom_io.read_file, dict(path=None), dict(path=[None, {}, 1.0, b"\0", "/nonexistent.dcm"])),
    (dicom_io.read_isocenter_geometry, dict(ds=None), dict(ds=JUNK_DATASETS + [GOOD_DS])),
    (dicom_io.view_from_dataset, dict(ds=GOOD_DS, isocenter=(0.0, 0.0, 0.0), patient_origin=(0.0, 0.0, 0.0),
                                      patient_position="HFS", convention="beam"),
     dict(ds=JUNK_DATASETS, isocenter=JUNK_POINTS[1:], patient_origin=JUNK_POINTS, convention=JUNK_NAMES)),
    (moves_for_dataset, dict(system=PRESET, ds=GOOD_DS, q_current=Q, isocenter=(0.0, 0.0, 0.0)),
     dict(system=JUNK_SYSTEMS, ds=JUNK_DATASETS, isocenter=JUNK_POINTS[1:])),
    (dicom_io.DicomView, dict(pose=np.eye(4), source="test", full_pose=True),
     dict(pose=JUNK_POSES[1:] + [None], source=[None, 1.0], full_pose=[None, 1.0, "yes"])),
    (dicom.angle, dict(value=1.0, name="value", bounds=(-180.0, 180.0)), dict(value=JUNK_NUMBERS + [181.0])),
    (dicom_attributes.read_number, dict(ds=GOOD_DS, keyword="PositionerPrimaryAngle"),
     dict(ds=JUNK_DATASETS, keyword=JUNK_NAMES + ["PatientName"])),
    (dicom_attributes.read_patient_position, dict(ds=pydicom.Dataset(), patient_position="HFS"),
     dict(ds=JUNK_DATASETS, patient_position=JUNK_NAMES[1:])),
    (dicom_attributes.sequence_items, dict(ds=GOOD_DS, keyword="XRayGeometrySequence"),
     dict(ds=JUNK_DATASETS, keyword=[None, 1.0, b"x"])),
    (dicom_attributes.check_dataset, dict(ds=GOOD_DS), dict(ds=JUNK_DATASETS)),
    (dicom_attributes.tag_text, dict(keyword="PatientPosition"), dict(keyword=[None, 1.0, b"x", {}])),
]


def _cases():
    for function, good, junk in CALLS:
        for argument, values in junk.items():
            for index, value in enumerate(values):
                yield pytest.param(function, good, argument, value, id=f"{function.__name__}-{argument}-{index}")


@pytest.mark.parametrize("function, good, argument, value", list(_cases()))
def test_junk_gets_a_typed_error_naming_the_argument(function, good, argument, value):
    """A CarmkinError whose message names the argument (or, for a dataset, the attribute), never a
    numpy/pydicom exception, never a warning."""
    kwargs = dict(good, **{argument: value})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(CarmkinError) as info:
            function(**kwargs)
    message = str(info.value)
    named = {"M": "M (", "ds": ("ds", "("), "path": ("path", "cannot read"), "full_pose": "source"}
    expected = named.get(argument, argument)
    assert any(word in message for word in ((expected,) if isinstance(expected, str) else expected)), message


def test_the_views_contract_names_still_work():
    """positioner_angles(M), pose_from_xa_angles(p, s, iso, sid, patient) and xa_angles, positionally."""
    primary, secondary, _ = dicom.xa_angles(GOOD_T, "HFS")
    T = dicom.pose_from_xa_angles(primary, secondary, GOOD_T[:3, 3] + 0.7 * GOOD_T[:3, 2], 0.7, "HFS")
    assert np.allclose(T[:3, 2], GOOD_T[:3, 2], atol=1e-12) and np.allclose(T[:3, 3], GOOD_T[:3, 3], atol=1e-12)
    assert len(dicom.positioner_angles(dicom.positioner_matrix(10, 20, 30))) == 3


# --- the CLI on bad files ------------------------------------------------------------------------------------
def _bad_files(tmp_path):
    good = tmp_path / "good.dcm"
    dicom_io.write_enhanced_xa(PRESET, Q).save_as(good, enforce_file_format=True)
    data = good.read_bytes()
    (tmp_path / "text.dcm").write_text("not DICOM at all")
    (tmp_path / "empty.dcm").write_bytes(b"")
    (tmp_path / "truncated.dcm").write_bytes(data[: len(data) // 2])
    (tmp_path / "preamble.dcm").write_bytes(data[:140])
    negative = dicom_io.write_enhanced_xa(PRESET, Q)
    negative.SharedFunctionalGroupsSequence[0].XRayGeometrySequence[0].DistanceSourceToIsocenter = -1250.0
    negative.save_as(tmp_path / "negative.dcm", enforce_file_format=True)
    no_position = dicom_io.write_xa(PRESET, Q)
    no_position.PatientPosition = ""
    no_position.save_as(tmp_path / "no_position.dcm", enforce_file_format=True)
    return {"text.dcm": "cannot read", "empty.dcm": "cannot read", "truncated.dcm": "", "preamble.dcm": "",
            "negative.dcm": "DistanceSourceToIsocenter (0018,9402) must be > 0 mm, got -1250",
            "no_position.dcm": "PatientPosition (0018,5100) is required", ".": "cannot read"}


def test_cli_bad_files_exit_2_with_one_line(tmp_path, capsys):
    for name, words in _bad_files(tmp_path).items():
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            code = main(["dicom", "--read", str(tmp_path / name)])
        captured = capsys.readouterr()
        assert code == 2, (name, captured)
        assert captured.out == "" and captured.err.count("\n") == 1 and "Traceback" not in captured.err, name
        assert captured.err.startswith("carmkin dicom: error: ") and words in captured.err, (name, captured.err)


def test_cli_reads_an_xa_file_without_position_when_told_one(tmp_path, capsys):
    _bad_files(tmp_path)
    assert main(["dicom", "--read", str(tmp_path / "no_position.dcm"), "--patient-position", "HFS"]) == 0
    assert "view from the XA positioner angles" in capsys.readouterr().out


def test_cli_convention_round_trip(tmp_path, capsys):
    for convention in sorted(dicom.CONVENTIONS):
        path = tmp_path / f"{convention}.dcm"
        assert main(["dicom", "--q-mm-deg", "50,200,0,100,5,15", "--write-enhanced", str(path),
                     "--positioner-convention", convention]) == 0
        assert main(["dicom", "--read", str(path), "--positioner-convention", convention]) == 0
        assert "orbital +15.000°" in capsys.readouterr().out
    assert carmkin  # the package imports without pydicom's help



def test_distance_source_to_patient_is_not_the_isocentre():
    """Issue 31: Distance Source to Patient (0018,1111) is the distance to the table or support nearest the patient
    (PS3.3), so it never places the source: Distance Source to Isocenter does, or the caller's value."""
    ds = xa()
    iso = float(ds.DistanceSourceToIsocenter)
    del ds.DistanceSourceToIsocenter
    ds.DistanceSourceToPatient = 0.5 * iso  # the table top, nearer the source than the isocentre
    with pytest.raises(DicomAttributeError, match="DistanceSourceToIsocenter .*Distance Source to Patient"):
        dicom_io.view_from_dataset(ds)
    given = dicom_io.view_from_dataset(ds, source_to_isocenter=iso / 1000.0).pose
    ds.DistanceSourceToIsocenter = iso
    np.testing.assert_allclose(given, dicom_io.view_from_dataset(ds).pose, atol=1e-12)
