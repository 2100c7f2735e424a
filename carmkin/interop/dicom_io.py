"""Read and write the geometry of XA and Enhanced XA datasets with pydicom (the ``dicom`` extra). The joint
and table moves that give the view of a DICOM image are the repositioning planner's
(:func:`carmkin.reposition.dicom.moves_for_dataset`).

Written datasets are synthetic and carry geometry only (no pixel data): enough for a reader of the geometry
attributes and for round-trip tests. Attribute keywords are pydicom's (PS3.6 names without spaces).
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass

import numpy as np

from carmkin import validation
from carmkin.extras import require
from carmkin.interop import dicom
from carmkin.errors import DicomAttributeError
from carmkin.interop.dicom import MM, DicomGeometryError
from carmkin.interop.dicom_attributes import (
    _error,
    check_dataset,
    read_number,
    read_patient_position,
    sequence_item,
    sequence_items,
)

XA_SOP_CLASS = "1.2.840.10008.5.1.4.1.1.12.1"  # X-Ray Angiographic Image Storage
ENHANCED_XA_SOP_CLASS = "1.2.840.10008.5.1.4.1.1.12.1.1"  # Enhanced XA Image Storage


def require_pydicom():
    return require("pydicom", "dicom")


def _base(sop_class: str, system):
    pydicom = require_pydicom()
    from pydicom.dataset import FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian, generate_uid

    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = sop_class
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = pydicom.Dataset()
    ds.file_meta = meta
    ds.SOPClassUID, ds.SOPInstanceUID = sop_class, meta.MediaStorageSOPInstanceUID
    ds.Modality = "XA"
    carm = system.carm
    ds.Rows, ds.Columns = int(carm.detector_rows), int(carm.detector_columns)
    sx, sy = carm.pixel_spacing
    ds.ImagerPixelSpacing = [sy * MM, sx * MM]  # row spacing, column spacing
    ds.DistanceSourceToDetector = carm.source_to_detector * MM
    return ds


def _position_code(patient_position) -> str:
    from carmkin.imaging.projection import PATIENT_POSITIONS

    if not isinstance(patient_position, str) or patient_position.upper() not in PATIENT_POSITIONS:
        raise DicomGeometryError(f"patient_position must be one of {', '.join(PATIENT_POSITIONS)}, "
                                 f"got {validation._describe(patient_position)}")
    return patient_position.upper()


def write_xa(system, q, patient_position: str = "HFS", patient_origin=(0.0, 0.0, 0.0),
             source_to_isocenter: float | None = None):
    """A synthetic XA dataset of the image at ``q``: Positioner Primary/Secondary Angle (patient-based, for
    the patient placed by ``patient_position`` and ``patient_origin`` (m, table frame)), Patient Position,
    Distance Source to Detector / to Isocenter (default the orbital offset, m), pixel spacing. Distance Source to
    Patient (0018,1111) is not written: the standard defines it as the distance to the table or support nearest
    the patient, which the model does not know."""
    code = _position_code(patient_position)
    origin = validation.real_array(patient_origin, "patient_origin", (3,), error=DicomGeometryError, unit="m")
    q = dicom._configuration(system, q)
    iso = system.carm.orbital_offset if source_to_isocenter is None else validation.distance(
        source_to_isocenter, "source_to_isocenter", error=DicomGeometryError)
    primary, secondary, _ = dicom.xa_angles(system.fk(q), dicom.patient_pose(code, origin))
    ds = _base(XA_SOP_CLASS, system)
    ds.PatientPosition = code
    ds.PositionerPrimaryAngle = round(primary, 6)
    ds.PositionerSecondaryAngle = round(secondary, 6)
    ds.DistanceSourceToIsocenter = iso * MM
    return ds


def write_enhanced_xa(system, q, source_to_isocenter: float | None = None, patient_position: str = "HFS", *,
                      convention: str = dicom.DEFAULT_CONVENTION):
    """A synthetic Enhanced XA dataset of the image at ``q`` with the X-Ray Isocenter Reference System (its
    positioner angles written in ``convention``) and the Table Position macros in its Shared Functional
    Groups (angles deg, positions mm)."""
    pydicom = require_pydicom()
    code = _position_code(patient_position)
    g = dicom.isocenter_geometry(system, q, source_to_isocenter, convention=convention)
    ds = _base(ENHANCED_XA_SOP_CLASS, system)
    ds.PatientPosition = code
    iso = pydicom.Dataset()
    iso.PositionerIsocenterPrimaryAngle = g.positioner_primary_deg
    iso.PositionerIsocenterSecondaryAngle = g.positioner_secondary_deg
    iso.PositionerIsocenterDetectorRotationAngle = g.detector_rotation_deg
    iso.TableXPositionToIsocenter, iso.TableYPositionToIsocenter, iso.TableZPositionToIsocenter = g.table_position_mm
    iso.TableHorizontalRotationAngle = g.table_rotation_deg
    iso.TableHeadTiltAngle = g.table_head_tilt_deg
    iso.TableCradleTiltAngle = g.table_cradle_tilt_deg
    table = pydicom.Dataset()
    for name, value in dicom.table_position(system, q).items():
        setattr(table, name, value)
    table.TableHorizontalRotationAngle = g.table_rotation_deg
    table.TableHeadTiltAngle = g.table_head_tilt_deg
    table.TableCradleTiltAngle = g.table_cradle_tilt_deg
    shared = pydicom.Dataset()
    shared.IsocenterReferenceSystemSequence = [iso]
    shared.TablePositionSequence = [table]
    detector = pydicom.Dataset()
    detector.DistanceSourceToIsocenter = g.source_to_isocenter_mm
    shared.XRayGeometrySequence = [detector]
    ds.SharedFunctionalGroupsSequence = [shared]
    return ds


def read_file(path):
    """``pydicom.dcmread(path)``, or :class:`DicomGeometryError` ("cannot read PATH: ...") for a file that is
    missing, not DICOM or malformed; pydicom's warnings while reading are not passed on."""
    pydicom = require_pydicom()
    if not isinstance(path, (str, os.PathLike)):
        raise DicomGeometryError(f"path must be a file path, got {validation._describe(path)}")
    if not os.path.isfile(path):
        raise DicomGeometryError(f"cannot read {os.fspath(path)}: no such file")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return pydicom.dcmread(path)
        except Exception as exc:  # OSError, InvalidDicomError, and whatever a truncated file raises
            raise DicomGeometryError(f"cannot read {os.fspath(path)}: {type(exc).__name__}: {exc}") from None


def read_isocenter_geometry(ds, frame: int = 0, *, convention: str = dicom.DEFAULT_CONVENTION) -> dicom.IsocenterGeometry:
    """The Isocenter Reference System of an Enhanced XA dataset: from the per-frame functional group
    ``frame`` (0-based) where the dataset has per-frame groups and that group carries the macro, else from the
    shared group; its positioner angles read in ``convention`` (:data:`carmkin.interop.dicom.CONVENTIONS`).
    Every attribute goes through :mod:`carmkin.interop.dicom_attributes` (present, one finite number, within
    the standard's range; DistanceSourceToIsocenter > 0)."""
    check_dataset(ds)
    dicom.check_convention(convention)
    if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)) or frame < 0:
        raise DicomGeometryError(f"frame must be a frame index >= 0 (an integer), got {frame!r}")
    groups = []
    per_frame = sequence_items(ds, "PerFrameFunctionalGroupsSequence")
    if per_frame and frame >= len(per_frame):
        raise DicomGeometryError(f"frame must be < {len(per_frame)} (the items of PerFrameFunctionalGroupsSequence "
                                 f"(5200,9230)), got {frame}")
    groups.extend(per_frame[frame:frame + 1])
    groups.extend(sequence_items(ds, "SharedFunctionalGroupsSequence")[:1])
    if not groups:
        raise DicomAttributeError("SharedFunctionalGroupsSequence (5200,9229) is required (Enhanced XA), the dataset "
                                  "has no functional groups", "SharedFunctionalGroupsSequence", "(5200,9229)")
    iso = sequence_item(groups, "IsocenterReferenceSystemSequence")
    geometry = sequence_item(groups, "XRayGeometrySequence")
    values = {keyword: read_number(iso, keyword) for keyword in (
        "PositionerIsocenterPrimaryAngle", "PositionerIsocenterSecondaryAngle",
        "PositionerIsocenterDetectorRotationAngle", "TableXPositionToIsocenter", "TableYPositionToIsocenter",
        "TableZPositionToIsocenter", "TableHorizontalRotationAngle", "TableHeadTiltAngle", "TableCradleTiltAngle")}
    return dicom.IsocenterGeometry(
        values["PositionerIsocenterPrimaryAngle"], values["PositionerIsocenterSecondaryAngle"],
        values["PositionerIsocenterDetectorRotationAngle"],
        (values["TableXPositionToIsocenter"], values["TableYPositionToIsocenter"], values["TableZPositionToIsocenter"]),
        values["TableHorizontalRotationAngle"], values["TableHeadTiltAngle"], values["TableCradleTiltAngle"],
        read_number(geometry, "DistanceSourceToIsocenter"), convention)


@dataclass
class DicomView:
    """The source pose (4, 4, table frame, m) that a dataset's geometry asks for, where it came from, and
    whether the dataset fixes the rotation about the beam (``full_pose``; XA angles leave it free)."""

    pose: np.ndarray
    source: str
    full_pose: bool = True

    def __post_init__(self):
        self.pose = validation.rigid_transform(self.pose, "pose (source pose)", error=DicomGeometryError)
        if not isinstance(self.source, str) or not isinstance(self.full_pose, bool):
            raise DicomGeometryError(f"source must be a str and full_pose a bool, got {self.source!r}, {self.full_pose!r}")


def view_from_dataset(ds, isocenter=None, patient_origin=(0.0, 0.0, 0.0), *, frame: int = 0,
                      patient_position: str | None = None, convention: str = dicom.DEFAULT_CONVENTION,
                      source_to_isocenter: float | None = None) -> DicomView:
    """The source pose of a dataset: from the Isocenter Reference System when the dataset has functional
    groups (Enhanced XA; ``frame`` and ``convention`` as in :func:`read_isocenter_geometry`), else from the
    patient-based XA angles, which need the ``isocenter`` (3,) in the table frame (m) — the point the beam
    passed through, e.g. the anatomy of interest; default: the patient origin — and the Patient Position: the
    dataset's, or ``patient_position`` where the dataset has none (never assumed) — and the source–isocentre
    distance: Distance Source to Isocenter (0018,9402), or ``source_to_isocenter`` (m) where the dataset has
    none (never Distance Source to Patient (0018,1111): the standard defines it as the distance to the table or
    support nearest the patient)."""
    check_dataset(ds)
    enhanced = str(ds.get("SOPClassUID", "")) == ENHANCED_XA_SOP_CLASS
    if enhanced or "SharedFunctionalGroupsSequence" in ds or "PerFrameFunctionalGroupsSequence" in ds:
        geometry = read_isocenter_geometry(ds, frame, convention=convention)
        return DicomView(geometry.source_pose(), "isocenter reference system")
    if "PositionerPrimaryAngle" not in ds:
        raise DicomAttributeError(
            "the dataset has no geometry: neither functional groups with an Isocenter Reference System (Enhanced "
            "XA, SharedFunctionalGroupsSequence (5200,9229)) nor PositionerPrimaryAngle (0018,1510) (XA)",
            "PositionerPrimaryAngle", "(0018,1510)")
    origin = validation.real_array(patient_origin, "patient_origin", (3,), error=DicomGeometryError, unit="m")
    T_patient = dicom.patient_pose(read_patient_position(ds, patient_position), origin)
    isocenter = T_patient[:3, 3] if isocenter is None else isocenter
    primary, secondary = read_number(ds, "PositionerPrimaryAngle"), read_number(ds, "PositionerSecondaryAngle")
    distance = _source_to_isocenter(ds, source_to_isocenter)
    pose = dicom.pose_from_xa_angles(primary, secondary, isocenter, distance, T_patient, convention=convention)
    return DicomView(pose, "XA positioner angles", full_pose=False)


def _source_to_isocenter(ds, given) -> float:
    """The source–isocentre distance (m) of a plain XA dataset: its Distance Source to Isocenter, else ``given``."""
    if "DistanceSourceToIsocenter" in ds:
        return read_number(ds, "DistanceSourceToIsocenter") / MM
    if given is not None:
        return validation.distance(given, "source_to_isocenter", error=DicomGeometryError)
    raise _error("DistanceSourceToIsocenter", "is required, the dataset has none (Distance Source to Patient "
                 "(0018,1111) is the distance to the table or support nearest the patient, not to the isocentre: "
                 "pass source_to_isocenter= in m)")

