"""Read and write the geometry of XA and Enhanced XA datasets with pydicom (the ``dicom`` extra), and find
the joint and table moves that give the view of a DICOM image through :func:`carmkin.qp_ik.solve`.

Written datasets are synthetic and carry geometry only (no pixel data): enough for a reader of the geometry
attributes and for round-trip tests. Attribute keywords are pydicom's (PS3.6 names without spaces).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from carmkin.extras import require
from carmkin.interop import dicom
from carmkin.interop.dicom import MM, DicomGeometryError

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


def write_xa(system, q, patient_position: str = "HFS", patient_origin=(0.0, 0.0, 0.0),
             source_to_isocenter: float | None = None):
    """A synthetic XA dataset of the image at ``q``: Positioner Primary/Secondary Angle (patient-based, for
    the patient placed by ``patient_position`` and ``patient_origin`` (m, table frame)), Patient Position,
    Distance Source to Detector / to Patient (the isocentre, default the orbital offset), pixel spacing."""
    ds = _base(XA_SOP_CLASS, system)
    T_patient = dicom.patient_pose(patient_position, patient_origin)
    primary, secondary, _ = dicom.xa_angles(system.fk(q), T_patient)
    iso = system.carm.orbital_offset if source_to_isocenter is None else float(source_to_isocenter)
    ds.PatientPosition = patient_position.upper()
    ds.PositionerPrimaryAngle = round(primary, 6)
    ds.PositionerSecondaryAngle = round(secondary, 6)
    ds.DistanceSourceToPatient = iso * MM
    return ds


def write_enhanced_xa(system, q, source_to_isocenter: float | None = None, patient_position: str = "HFS"):
    """A synthetic Enhanced XA dataset of the image at ``q`` with the X-Ray Isocenter Reference System and
    the Table Position macros in its Shared Functional Groups (angles deg, positions mm)."""
    pydicom = require_pydicom()
    ds = _base(ENHANCED_XA_SOP_CLASS, system)
    ds.PatientPosition = patient_position.upper()
    g = dicom.isocenter_geometry(system, q, source_to_isocenter)
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


def _float(ds, keyword: str) -> float:
    value = ds.get(keyword)
    if value is None:
        raise DicomGeometryError(f"the dataset has no {keyword}")
    return float(value)


def read_isocenter_geometry(ds, frame: int = 0) -> dicom.IsocenterGeometry:
    """The Isocenter Reference System of an Enhanced XA dataset (per-frame group ``frame`` if it has one,
    else the shared group)."""
    groups = []
    if "PerFrameFunctionalGroupsSequence" in ds and len(ds.PerFrameFunctionalGroupsSequence) > frame:
        groups.append(ds.PerFrameFunctionalGroupsSequence[frame])
    if "SharedFunctionalGroupsSequence" in ds:
        groups.append(ds.SharedFunctionalGroupsSequence[0])

    def find(sequence: str):
        for group in groups:
            if sequence in group and len(group[sequence].value):
                return group[sequence][0]
        raise DicomGeometryError(f"the dataset has no {sequence} (Enhanced XA functional group)")

    iso = find("IsocenterReferenceSystemSequence")
    geometry = find("XRayGeometrySequence")
    return dicom.IsocenterGeometry(
        _float(iso, "PositionerIsocenterPrimaryAngle"), _float(iso, "PositionerIsocenterSecondaryAngle"),
        _float(iso, "PositionerIsocenterDetectorRotationAngle"),
        (_float(iso, "TableXPositionToIsocenter"), _float(iso, "TableYPositionToIsocenter"),
         _float(iso, "TableZPositionToIsocenter")),
        _float(iso, "TableHorizontalRotationAngle"), _float(iso, "TableHeadTiltAngle"),
        _float(iso, "TableCradleTiltAngle"), _float(geometry, "DistanceSourceToIsocenter"))


@dataclass
class DicomView:
    """The source pose (4, 4, table frame, m) that a dataset's geometry asks for, where it came from, and
    whether the dataset fixes the rotation about the beam (``full_pose``; XA angles leave it free)."""

    pose: np.ndarray
    source: str
    full_pose: bool = True


def view_from_dataset(ds, isocenter=None, patient_origin=(0.0, 0.0, 0.0)) -> DicomView:
    """The source pose of a dataset: from the Isocenter Reference System when present (complete), else from
    the patient-based XA angles, which need the ``isocenter`` (3,) in the table frame (m) — the point the
    beam passed through, e.g. the anatomy of interest; default: the patient origin."""
    if "SharedFunctionalGroupsSequence" in ds or "PerFrameFunctionalGroupsSequence" in ds:
        return DicomView(read_isocenter_geometry(ds).source_pose(), "isocenter reference system")
    position = str(ds.get("PatientPosition", "") or "HFS")
    T_patient = dicom.patient_pose(position, patient_origin)
    isocenter = T_patient[:3, 3] if isocenter is None else np.asarray(isocenter, dtype=float)
    pose = dicom.pose_from_xa_angles(_float(ds, "PositionerPrimaryAngle"), _float(ds, "PositionerSecondaryAngle"),
                                     isocenter, _float(ds, "DistanceSourceToPatient") / MM, T_patient)
    return DicomView(pose, "XA positioner angles", full_pose=False)


def moves_for_dataset(system, ds, q_current=None, isocenter=None, patient_origin=(0.0, 0.0, 0.0), **solve_kwargs):
    """``(view, result)``: the dataset's view and the :func:`carmkin.qp_ik.solve` result reaching it from
    ``q_current`` (joints and table joints; ``result.q − q_current`` are the moves). An Enhanced XA view is a
    full pose; XA angles fix the source position and the beam, the rotation about the beam stays free
    (:class:`carmkin.qp_ik.AxisTarget`)."""
    from carmkin import qp_ik

    view = view_from_dataset(ds, isocenter, patient_origin)
    target = view.pose if view.full_pose else qp_ik.AxisTarget(tuple(view.pose[:3, 3]), tuple(view.pose[:3, 2]))
    return view, qp_ik.solve(system, target, q_current=q_current, **solve_kwargs)
