"""DICOM X-ray angiography geometry ↔ the toolkit's frames (numpy only; reading/writing datasets is in
:mod:`carmkin.interop.dicom_io`). Angles in degrees and lengths in mm where DICOM attributes are meant,
SI elsewhere, as the names say.

Frames (DICOM PS3.3 C.8.19.6.13.1 and PS3.17 Z / FFF.1.2):

- **Table coordinate system** (Ot, Xt, Yt, Zt): +Xt to the table's left, +Yt down, +Zt to the table's head —
  the toolkit's table frame 0 with the table head at +Z0; the Table Reference Point Ot is its origin.
- **Isocenter coordinate system** (O, X, Y, Z), fixed to the equipment: with all table angles 0 its axes
  are the table's (X left, Y down, Z head). For the mobile C-arm we fix it to the C-arm base: Y = down the
  vertical column (−Z of DH frame 2), X = the horizontal arm direction (+Y2), Z = X × Y (−X2); for the
  preset's setup these are the table axes. A mobile, non-isocentric C-arm has no fixed isocentre: each image
  carries its own, the point of the principal axis at the source-to-isocentre distance ``ISO`` from the
  source (default: the orbital offset l2, the preset's "beam centre").
- **Positioner coordinate system** (Op = O, Xp, Yp, Zp): Yp from the isocentre to the source, Xp along the
  detector rows and Zp along its columns (left→right, bottom→top, looking towards the source). Points map
  as ``P_p = R3(Ap3) R2(Ap2) R1(Ap1) P_iso`` (PS3.17 eq. Z.2-2) with Ap1 the primary angle about Z (from −Y
  to +X positive), Ap2 the secondary angle about the rotated X (from −Y to +Z positive), Ap3 the detector
  rotation about Yp. The matrices R1–R3 are printed as images in the standard and transcriptions disagree
  in sign (PySkinDose's ``beam_class.py`` flipped R1 between versions), so R1 and R2 are derived from the
  text's rules — the detector (−Yp) moves from −Y towards +X as Ap1 grows (LAO for HFS) and towards +Z
  (CRA) as Ap2 grows: ``R1 = [[c, s, 0], [−s, c, 0], [0, 0, 1]]``, ``R2 = [[1, 0, 0], [0, c, −s], [0, s, c]]``.
  The sign of Ap3 (``R3 = [[c, 0, −s], [0, 1, 0], [s, 0, c]]``, as transcribed) is not checked against the
  standard's text here.
- **Our source frame in positioner axes**: x = −Xp, y = −Zp, z = −Yp (z from source to detector). A DICOM
  image, viewed towards the source, is the mirror of our pinhole image: DICOM column ``c = (W − 1) − u``,
  row ``r = v``; with Ap3 = 0, an AP view of an HFS patient shows the patient's left on the image right and
  the head at the top.

Table angles (PS3.3 C.8.19.6.11 / .13.1.3): ``P_t = R3(At3) R2(At2) R1(At1) (P_iso − T)`` (PS3.17 FFF.1.2.3.2)
with At1 the horizontal rotation (+Z towards +X positive, clockwise seen from above), At2 the head tilt
(head up positive), At3 the cradle tilt (table left up positive); T = Table X/Y/Z Position to Isocenter.

XA (non-enhanced) Positioner Primary/Secondary Angle (PS3.3 C.8.7.5.1.2) are patient-based: the same two
rotations, applied to the patient's LPS axes instead of the isocentre axes (primary: +90° at the patient's
left = LAO, secondary: +90° cranial), giving the direction from the isocentre to the detector.

Operator-relative table terms (PS3.3 C.8.7.4.1.2–3, C.8.19.6.11): "longitudinal" and "lateral" are seen by
an operator standing beside the table facing the patient — *longitudinal* is across the table (towards the
+90° primary position, LAO), *lateral* along it (towards +90° secondary, CRA); vertical is positive down.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import (
    DicomGeometryError,  # noqa: F401 (defined there, raised here)
)
from carmkin.imaging.projection import patient_pose
from carmkin.interop.simulators import MM
from carmkin.transforms import check_rigid_transform, inverse

#: Our source axes (columns x, y, z) in positioner axes (Xp, Yp, Zp): x = −Xp, y = −Zp, z = −Yp.
SOURCE_IN_POSITIONER = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, -1.0, 0.0]])

#: Isocentre axes (columns X, Y, Z) in DH frame 2 of the chain: X = Y2, Y = −Z2, Z = −X2.
ISOCENTER_IN_FRAME2 = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def _c_s(angle_deg: float) -> tuple[float, float]:
    a = math.radians(angle_deg)
    return math.cos(a), math.sin(a)


def positioner_matrix(primary_deg: float, secondary_deg: float, rotation_deg: float = 0.0) -> np.ndarray:
    """``R3 R2 R1`` (3, 3): rows are Xp, Yp, Zp in the reference frame (isocentre or patient axes)."""
    c1, s1 = _c_s(primary_deg)
    c2, s2 = _c_s(secondary_deg)
    c3, s3 = _c_s(rotation_deg)
    R1 = np.array([[c1, s1, 0.0], [-s1, c1, 0.0], [0.0, 0.0, 1.0]])
    R2 = np.array([[1.0, 0.0, 0.0], [0.0, c2, -s2], [0.0, s2, c2]])
    R3 = np.array([[c3, 0.0, -s3], [0.0, 1.0, 0.0], [s3, 0.0, c3]])
    return R3 @ R2 @ R1


def positioner_angles(M) -> tuple[float, float, float]:
    """``(Ap1, Ap2, Ap3)`` (deg) of a positioner matrix (inverse of :func:`positioner_matrix`).

    Ranges: Ap1, Ap3 in (−180, 180], Ap2 in [−90, 90]; at Ap2 = ±90° (beam along Z) Ap1 is not defined and
    is reported as 0 with the in-plane rotation carried by Ap3.
    """
    M = np.asarray(M, dtype=float)
    yp = M[1]  # (−s1 c2, c1 c2, −s2)
    a2 = math.degrees(math.asin(max(-1.0, min(1.0, -yp[2]))))
    a1 = math.degrees(math.atan2(-yp[0], yp[1])) if math.hypot(yp[0], yp[1]) > 1e-12 else 0.0
    R3 = M @ positioner_matrix(a1, a2).T
    a3 = math.degrees(math.atan2(R3[2, 0], R3[0, 0]))
    return a1, a2, a3


def table_matrix(rotation_deg: float, head_tilt_deg: float, cradle_tilt_deg: float) -> np.ndarray:
    """``R3 R2 R1`` (3, 3) of the table angles: rows are Xt, Yt, Zt in isocentre axes."""
    c1, s1 = _c_s(rotation_deg)
    c2, s2 = _c_s(head_tilt_deg)
    c3, s3 = _c_s(cradle_tilt_deg)
    R1 = np.array([[c1, 0.0, -s1], [0.0, 1.0, 0.0], [s1, 0.0, c1]])  # +Z towards +X
    R2 = np.array([[1.0, 0.0, 0.0], [0.0, c2, s2], [0.0, -s2, c2]])  # head (+Zt) up (−Y)
    R3 = np.array([[c3, -s3, 0.0], [s3, c3, 0.0], [0.0, 0.0, 1.0]])  # left (+Xt) up (−Y)
    return R3 @ R2 @ R1


def table_angles(M) -> tuple[float, float, float]:
    """``(At1, At2, At3)`` (deg) of a table matrix (inverse of :func:`table_matrix`; At2 in [−90, 90])."""
    M = np.asarray(M, dtype=float)
    zt = M[2]  # R3 leaves row 2 alone: (s1 c2, −s2, c1 c2)
    a2 = math.degrees(math.asin(max(-1.0, min(1.0, -zt[1]))))
    a1 = math.degrees(math.atan2(zt[0], zt[2])) if math.hypot(zt[0], zt[2]) > 1e-12 else 0.0
    R3 = M @ table_matrix(a1, a2, 0.0).T
    a3 = math.degrees(math.atan2(-R3[0, 1], R3[0, 0]))
    return a1, a2, a3


# --- one image's geometry ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class IsocenterGeometry:
    """The X-Ray Isocenter Reference System attributes of one image (PS3.3 C.8.19.6.13), degrees and mm."""

    positioner_primary_deg: float
    positioner_secondary_deg: float
    detector_rotation_deg: float
    table_position_mm: tuple[float, float, float]
    table_rotation_deg: float
    table_head_tilt_deg: float
    table_cradle_tilt_deg: float
    source_to_isocenter_mm: float

    def source_pose(self) -> np.ndarray:
        """Pose (4, 4) of our source frame in the table frame (m), from the attributes alone."""
        M = positioner_matrix(self.positioner_primary_deg, self.positioner_secondary_deg, self.detector_rotation_deg)
        T_iso_source = np.eye(4)
        T_iso_source[:3, :3] = M.T @ SOURCE_IN_POSITIONER
        T_iso_source[:3, 3] = M[1] * self.source_to_isocenter_mm / MM  # on +Yp at ISO
        T_iso_table = np.eye(4)
        T_iso_table[:3, :3] = table_matrix(self.table_rotation_deg, self.table_head_tilt_deg,
                                           self.table_cradle_tilt_deg).T
        T_iso_table[:3, 3] = np.asarray(self.table_position_mm, dtype=float) / MM
        return inverse(T_iso_table) @ T_iso_source


def equipment_axes(system, q) -> np.ndarray:
    """Isocentre axes (3, 3, columns X, Y, Z) in the table frame, fixed to the C-arm base (DH frame 2)."""
    return system.dh_frames(q)[1][:3, :3] @ ISOCENTER_IN_FRAME2


def isocenter_frame(system, q, source_to_isocenter: float | None = None) -> np.ndarray:
    """Pose (4, 4, m) of the image's isocentre coordinate system in the table frame: the equipment axes, the
    origin on the principal axis at ``source_to_isocenter`` (m, default the orbital offset) from the source."""
    iso = system.carm.orbital_offset if source_to_isocenter is None else float(source_to_isocenter)
    if not np.isfinite(iso) or iso <= 0:
        raise DicomGeometryError(f"source_to_isocenter must be > 0 (m), got {source_to_isocenter}")
    T_source = system.fk(q)
    T = np.eye(4)
    T[:3, :3] = equipment_axes(system, q)
    T[:3, 3] = T_source[:3, 3] + iso * T_source[:3, 2]
    return T


def isocenter_geometry(system, q, source_to_isocenter: float | None = None) -> IsocenterGeometry:
    """The Isocenter Reference System attributes of the image taken at configuration ``q``."""
    T_table_iso = isocenter_frame(system, q, source_to_isocenter)
    T_iso_source = inverse(T_table_iso) @ system.fk(q)
    M = (T_iso_source[:3, :3] @ SOURCE_IN_POSITIONER.T).T  # rows Xp, Yp, Zp in isocentre axes
    T_iso_table = inverse(T_table_iso)
    at1, at2, at3 = table_angles(T_iso_table[:3, :3].T)
    ap1, ap2, ap3 = positioner_angles(M)
    return IsocenterGeometry(ap1, ap2, ap3, tuple(float(v) for v in T_iso_table[:3, 3] * MM), at1, at2, at3,
                             float(np.linalg.norm(T_iso_source[:3, 3]) * MM))


# --- patient-based XA angles --------------------------------------------------------------------------------
def _patient(patient) -> np.ndarray:
    return patient_pose(patient) if isinstance(patient, str) else check_rigid_transform(patient, "patient pose")


def xa_angles(T_source, patient="HFS") -> tuple[float, float, float]:
    """``(primary, secondary, rotation)`` (deg): XA Positioner Primary Angle (LAO +, RAO −) and Secondary
    Angle (CRA +, CAU −) of a source pose (4, 4, table frame) for a patient (position code or LPS pose in the
    table frame), and the rotation of the detector about the beam (not an XA attribute; Ap3's rule)."""
    T = inverse(_patient(patient)) @ check_rigid_transform(T_source, "source pose")
    return positioner_angles((T[:3, :3] @ SOURCE_IN_POSITIONER.T).T)


def pose_from_xa_angles(primary_deg, secondary_deg, isocenter, source_to_isocenter, patient="HFS",
                        rotation_deg: float = 0.0) -> np.ndarray:
    """Source pose (4, 4) in the table frame for XA angles (deg), the isocentre (3,) in the table frame (m)
    and the source-to-isocentre distance (m) (DICOM Distance Source to Patient, 0018,1111)."""
    isocenter = np.asarray(isocenter, dtype=float)
    if isocenter.shape != (3,) or not np.all(np.isfinite(isocenter)):
        raise DicomGeometryError(f"isocenter must be three finite coordinates (m), got {isocenter!r}")
    if not np.isfinite(source_to_isocenter) or source_to_isocenter <= 0:
        raise DicomGeometryError(f"source_to_isocenter must be > 0 (m), got {source_to_isocenter}")
    if not -90.0 <= secondary_deg <= 90.0:
        raise DicomGeometryError(f"secondary angle must be in [-90, 90] deg, got {secondary_deg}")
    R_patient = _patient(patient)[:3, :3]
    M = positioner_matrix(primary_deg, secondary_deg, rotation_deg)
    T = np.eye(4)
    T[:3, :3] = R_patient @ M.T @ SOURCE_IN_POSITIONER
    T[:3, 3] = isocenter - source_to_isocenter * T[:3, 2]
    return T


# --- operator-relative table motion ---------------------------------------------------------------------
def table_position(system, q) -> dict[str, float]:
    """Table Top Vertical / Longitudinal / Lateral Position (mm) of configuration ``q``: the table origin
    relative to the C-arm base (DH frame 1, the equipment's arbitrary reference) along the equipment axes:
    vertical = +Y (down), longitudinal = +X (across the table, towards LAO), lateral = +Z (along it, towards
    CRA) — the terms of an operator standing beside the table."""
    frame1 = system.dh_frames(q)[0]
    axes = equipment_axes(system, q)
    p = axes.T @ (np.zeros(3) - frame1[:3, 3]) * MM
    return {"TableTopVerticalPosition": float(p[1]), "TableTopLongitudinalPosition": float(p[0]),
            "TableTopLateralPosition": float(p[2])}


def table_increments(system, q_first, q) -> dict[str, float]:
    """XA Table Vertical / Longitudinal / Lateral Increment (mm) of ``q`` relative to ``q_first``."""
    a, b = table_position(system, q_first), table_position(system, q)
    return {name.replace("TableTop", "Table").replace("Position", "Increment"): b[name] - a[name] for name in a}
