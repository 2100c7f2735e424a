"""DICOM X-ray angiography geometry ↔ the toolkit's frames (numpy only; reading/writing datasets is in
:mod:`carmkin.interop.dicom_io`). Angles in degrees and lengths in mm where DICOM attributes are meant,
SI elsewhere, as the names say.

Frames (DICOM PS3.3 C.8.19.6.13.1 and PS3.17 Z / FFF.1.2):

- **Table coordinate system** (Ot, Xt, Yt, Zt): +Xt to the table's left, +Yt down, +Zt to the table's head —
  the toolkit's table frame 0 with the table head at +Z0; the Table Reference Point Ot is its origin.
- **Isocenter coordinate system** (O, X, Y, Z), fixed to the equipment: with all table angles 0 its axes
  are the table's (X left, Y down, Z head). We fix it to the C-arm base (DH frame 2) with the table's axes at
  rest (all joints 0), :func:`isocenter_in_frame2`: for a mobile C-arm beside the table (the siremobile and
  cios-spin presets) Y = down the vertical column (−Z2), X = the horizontal arm direction (+Y2), Z = X × Y
  (−X2); for an angiography stand at the head end (angio-floor, angio-ceiling), whose arm lies along the
  table, X = across the table (−X2), Y = down, Z = towards the stand (−Y2). A mobile, non-isocentric C-arm has
  no fixed isocentre: each image
  carries its own, the point of the principal axis at the source-to-isocentre distance ``ISO`` from the
  source (default: the orbital offset l2, the preset's "beam centre").
- **Positioner coordinate system** (Op = O, Xp, Yp, Zp): Yp from the isocentre to the source, Xp along the
  detector rows and Zp along its columns (left→right, bottom→top, looking towards the source). Points map
  as ``P_p = R3(Ap3) R2(Ap2) R1(Ap1) P_iso`` (PS3.17 eq. Z.2-2); at zero angles Yp = +Y, the source below.
  Ap1 (about Z, "from −Y to +X is positive"): −Y is the beam's direction (source → detector) at rest, so the
  detector moves towards +X as Ap1 grows. The signs of Ap2 and Ap3 have two readings of the standard's text
  (:data:`CONVENTIONS`; docs/interop.md quotes the text): every function that turns angles into a matrix or
  back takes ``convention`` — ``"beam"`` (default), ``"literal"``, or either reading for Ap2 and Ap3 apart
  (``"literal-ap2"`` = ``"pyskindose"``, ``"literal-ap3"``, or a pair of readings).
- **Our source frame in positioner axes**: x = −Xp, y = −Zp, z = −Yp (z from source to detector). A DICOM
  image, viewed towards the source, is the mirror of our pinhole image: DICOM column ``c = (W − 1) − u``,
  row ``r = v``; with Ap3 = 0, an AP view of an HFS patient shows the patient's left on the image right and
  the head at the top.

Table angles (PS3.3 C.8.19.6.11 / .13.1.3): ``P_t = R3(At3) R2(At2) R1(At1) (P_iso − T)`` (PS3.17 FFF.1.2.3.2)
with At1 the horizontal rotation (+Z towards +X positive, clockwise seen from above), At2 the head tilt
(head up positive), At3 the cradle tilt (table left up positive); T = Table X/Y/Z Position to Isocenter.

XA (non-enhanced) Positioner Primary/Secondary Angle (PS3.3 C.8.7.5.1.2) are patient-based: the same two
rotations, applied to the patient's LPS axes instead of the isocentre axes (primary: +90° at the patient's
left = LAO, secondary: +90° cranial), giving the direction from the isocentre to the detector — unambiguous,
so ``convention`` only changes the rotation about the beam that :func:`xa_angles` reports (Ap3's rule).

Operator-relative table terms (PS3.3 C.8.7.4.1.2–3, C.8.19.6.11): "longitudinal" and "lateral" are seen by
an operator standing beside the table facing the patient — *longitudinal* is across the table (towards the
+90° primary position, LAO), *lateral* along it (towards +90° secondary, CRA); vertical is positive down.

Every public function refuses junk (``None``, strings, bools, complex, NaN, wrong shapes, angles outside the
standard's ranges, a matrix that is not a rotation) with :class:`carmkin.errors.DicomGeometryError` naming
the argument; joint vectors are refused by the system's own check (:class:`InvalidConfigurationError`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from carmkin import validation
from carmkin.errors import DicomGeometryError
from carmkin.imaging.projection import patient_pose
from carmkin.interop.simulators import MM
from carmkin.transforms import inverse

#: Our source axes (columns x, y, z) in positioner axes (Xp, Yp, Zp): x = −Xp, y = −Zp, z = −Yp.
SOURCE_IN_POSITIONER = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, -1.0, 0.0]])


#: The two readings of the signs of Ap2 and Ap3 (PS3.3 C.8.19.6.13.1.2), as the signs applied to the
#: angles before the rotations of :func:`positioner_matrix` (the ``"beam"`` matrices):
#:
#: - ``"beam"`` (default): "the X-Ray center beam" is the beam's direction, source → isocentre → detector,
#:   as it must be in Ap1's "from −Y to +X" (at rest the beam runs along −Y): Ap2 > 0 tilts the detector
#:   towards +Z (for HFS at table angles 0: cranial, the sign of the patient-based secondary angle); Ap3 > 0
#:   turns the detector clockwise as seen from behind it looking towards the source — the view in which
#:   the standard defines Xp and Zp ("looking towards the source").
#: - ``"literal"``: "(i.e., Yp)" taken as the vector isocentre → source: Ap2 > 0 tilts the *source* towards
#:   +Z (PySkinDose since commit 0876162); Ap3 > 0 turns the detector clockwise as seen from the source,
#:   facing on to the detector's entrance plane.
#:
#: The two ambiguities are independent (one is about Ap2's direction, the other about the side Ap3 is seen
#: from), so every combination has a name: ``"literal-ap2"`` reads Ap2 literally and Ap3 as the beam does
#: (PySkinDose's reading, also named ``"pyskindose"``), ``"literal-ap3"`` the other way round; a pair of
#: readings ``(ap2, ap3)``, each ``"beam"`` or ``"literal"``, is accepted too.
READINGS: dict[str, float] = {"beam": 1.0, "literal": -1.0}
CONVENTIONS: dict[str, tuple[float, float]] = {"beam": (1.0, 1.0), "literal": (-1.0, -1.0),
                                               "literal-ap2": (-1.0, 1.0), "literal-ap3": (1.0, -1.0),
                                               "pyskindose": (-1.0, 1.0)}
DEFAULT_CONVENTION = "beam"

#: Valid ranges (deg) of the angles, PS3.3 C.8.7.5.1.2 and C.8.19.6.13.1.2 (primary −180…180, secondary
#: −90…90). The detector rotation and the table angles are accepted over their whole decomposition range
#: (rotation and cradle tilt −180…180, head tilt −90…90).
PRIMARY_RANGE = (-180.0, 180.0)
SECONDARY_RANGE = (-90.0, 90.0)
ROTATION_RANGE = (-180.0, 180.0)
HEAD_TILT_RANGE = (-90.0, 90.0)
#: Largest |table position to isocentre| and source-to-isocentre distance (mm): validation's 10 m.
MAX_DISTANCE_MM = validation.MAX_DISTANCE * MM
#: Below this, the beam is along ±Z (Ap2 = ±90°) and Ap1 is reported as 0 (gimbal lock; dimensionless).
GIMBAL_TOLERANCE = 1e-12


def check_convention(convention) -> tuple[float, float]:
    """The signs (Ap2, Ap3) of a convention name or of a pair of readings ``(ap2, ap3)``, or
    :class:`DicomGeometryError` naming the choices."""
    if isinstance(convention, str) and convention in CONVENTIONS:
        return CONVENTIONS[convention]
    if (isinstance(convention, tuple) and len(convention) == 2
            and all(isinstance(r, str) and r in READINGS for r in convention)):
        return READINGS[convention[0]], READINGS[convention[1]]
    raise DicomGeometryError(f"convention must be one of {', '.join(map(repr, CONVENTIONS))} or a pair of readings "
                             f"(ap2, ap3) of {', '.join(map(repr, READINGS))}, got {validation._describe(convention)}")


def angle(value, name: str, bounds: tuple[float, float]) -> float:
    """``value`` as an angle (deg) within ``bounds``, or :class:`DicomGeometryError` naming ``name``."""
    return validation.real_scalar(value, name, error=DicomGeometryError, low=bounds[0], high=bounds[1], unit="deg")


def _c_s(angle_deg: float) -> tuple[float, float]:
    a = math.radians(angle_deg)
    return math.cos(a), math.sin(a)


def positioner_matrix(primary_deg, secondary_deg, rotation_deg=0.0, *, convention: str = DEFAULT_CONVENTION) -> np.ndarray:
    """``R3 R2 R1`` (3, 3): rows are Xp, Yp, Zp in the reference frame (isocentre or patient axes).

    With the ``"beam"`` signs ``R1 = [[c, s, 0], [−s, c, 0], [0, 0, 1]]`` (the detector −Yp from −Y towards
    +X), ``R2 = [[1, 0, 0], [0, c, −s], [0, s, c]]`` (−Yp towards +Z), ``R3 = [[c, 0, −s], [0, 1, 0],
    [s, 0, c]]`` (Xp, Zp turned right-handed about +Yp); ``"literal"`` negates Ap2 and Ap3.
    """
    s2, s3 = check_convention(convention)
    c1, s1 = _c_s(angle(primary_deg, "primary_deg", PRIMARY_RANGE))
    c2, sn2 = _c_s(s2 * angle(secondary_deg, "secondary_deg", SECONDARY_RANGE))
    c3, sn3 = _c_s(s3 * angle(rotation_deg, "rotation_deg", ROTATION_RANGE))
    R1 = np.array([[c1, s1, 0.0], [-s1, c1, 0.0], [0.0, 0.0, 1.0]])
    R2 = np.array([[1.0, 0.0, 0.0], [0.0, c2, -sn2], [0.0, sn2, c2]])
    R3 = np.array([[c3, 0.0, -sn3], [0.0, 1.0, 0.0], [sn3, 0.0, c3]])
    return R3 @ R2 @ R1


def _wrap(angle_deg: float) -> float:
    """An angle (deg) folded into (−180, 180]."""
    folded = math.fmod(angle_deg, 360.0)
    folded = folded - 360.0 if folded > 180.0 else folded + 360.0 if folded <= -180.0 else folded
    return folded


def positioner_angles(M, *, convention: str = DEFAULT_CONVENTION) -> tuple[float, float, float]:
    """``(Ap1, Ap2, Ap3)`` (deg) of a positioner matrix (inverse of :func:`positioner_matrix`).

    ``M`` must be a rotation (orthonormal, det +1, to :data:`carmkin.validation.RIGID_TOLERANCE`): a scaled
    matrix, a reflection or zeros is refused. Ranges: Ap1, Ap3 in (−180, 180], Ap2 in [−90, 90]; at Ap2 = ±90°
    (beam along Z) Ap1 is not defined and is reported as 0 with the in-plane rotation carried by Ap3.
    """
    s2, s3 = check_convention(convention)
    M = validation.rotation(M, "M (positioner matrix)", error=DicomGeometryError)
    yp = M[1]  # (−s1 c2, c1 c2, −s2) with the "beam" signs
    a2 = math.degrees(math.asin(max(-1.0, min(1.0, -yp[2]))))
    a1 = math.degrees(math.atan2(-yp[0], yp[1])) if math.hypot(yp[0], yp[1]) > GIMBAL_TOLERANCE else 0.0
    R3 = M @ positioner_matrix(_wrap(a1), a2).T
    a3 = math.degrees(math.atan2(R3[2, 0], R3[0, 0]))
    return _wrap(a1), s2 * a2 + 0.0, _wrap(s3 * a3)


def table_matrix(rotation_deg, head_tilt_deg, cradle_tilt_deg) -> np.ndarray:
    """``R3 R2 R1`` (3, 3) of the table angles: rows are Xt, Yt, Zt in isocentre axes."""
    c1, s1 = _c_s(angle(rotation_deg, "rotation_deg", ROTATION_RANGE))
    c2, s2 = _c_s(angle(head_tilt_deg, "head_tilt_deg", HEAD_TILT_RANGE))
    c3, s3 = _c_s(angle(cradle_tilt_deg, "cradle_tilt_deg", ROTATION_RANGE))
    R1 = np.array([[c1, 0.0, -s1], [0.0, 1.0, 0.0], [s1, 0.0, c1]])  # +Z towards +X
    R2 = np.array([[1.0, 0.0, 0.0], [0.0, c2, s2], [0.0, -s2, c2]])  # head (+Zt) up (−Y)
    R3 = np.array([[c3, -s3, 0.0], [s3, c3, 0.0], [0.0, 0.0, 1.0]])  # left (+Xt) up (−Y)
    return R3 @ R2 @ R1


def table_angles(M) -> tuple[float, float, float]:
    """``(At1, At2, At3)`` (deg) of a table matrix (inverse of :func:`table_matrix`; At2 in [−90, 90]).

    ``M`` must be a rotation, as for :func:`positioner_angles`."""
    M = validation.rotation(M, "M (table matrix)", error=DicomGeometryError)
    zt = M[2]  # R3 leaves row 2 alone: (s1 c2, −s2, c1 c2)
    a2 = math.degrees(math.asin(max(-1.0, min(1.0, -zt[1]))))
    a1 = math.degrees(math.atan2(zt[0], zt[2])) if math.hypot(zt[0], zt[2]) > GIMBAL_TOLERANCE else 0.0
    R3 = M @ table_matrix(_wrap(a1), a2, 0.0).T
    a3 = math.degrees(math.atan2(-R3[0, 1], R3[0, 0]))
    return _wrap(a1), a2, _wrap(a3)


# --- one image's geometry ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class IsocenterGeometry:
    """The X-Ray Isocenter Reference System attributes of one image (PS3.3 C.8.19.6.13), degrees and mm,
    with the ``convention`` its positioner angles are read in. Checked on construction (ranges, finite,
    source-to-isocentre > 0): :class:`DicomGeometryError` naming the field."""

    positioner_primary_deg: float
    positioner_secondary_deg: float
    detector_rotation_deg: float
    table_position_mm: tuple[float, float, float]
    table_rotation_deg: float
    table_head_tilt_deg: float
    table_cradle_tilt_deg: float
    source_to_isocenter_mm: float
    convention: str = DEFAULT_CONVENTION

    def __post_init__(self):
        check_convention(self.convention)
        for name, bounds in (("positioner_primary_deg", PRIMARY_RANGE), ("positioner_secondary_deg", SECONDARY_RANGE),
                             ("detector_rotation_deg", ROTATION_RANGE), ("table_rotation_deg", ROTATION_RANGE),
                             ("table_head_tilt_deg", HEAD_TILT_RANGE), ("table_cradle_tilt_deg", ROTATION_RANGE)):
            object.__setattr__(self, name, angle(getattr(self, name), name, bounds))
        position = validation.real_array(self.table_position_mm, "table_position_mm", (3,), error=DicomGeometryError,
                                         limit=MAX_DISTANCE_MM, unit="mm")
        object.__setattr__(self, "table_position_mm", tuple(float(v) for v in position))
        object.__setattr__(self, "source_to_isocenter_mm", validation.distance(
            self.source_to_isocenter_mm, "source_to_isocenter_mm", error=DicomGeometryError,
            low=validation.MIN_DISTANCE * MM, high=MAX_DISTANCE_MM, unit="mm"))

    def source_pose(self) -> np.ndarray:
        """Pose (4, 4) of our source frame in the table frame (m), from the attributes alone."""
        M = positioner_matrix(self.positioner_primary_deg, self.positioner_secondary_deg, self.detector_rotation_deg,
                              convention=self.convention)
        T_iso_source = np.eye(4)
        T_iso_source[:3, :3] = M.T @ SOURCE_IN_POSITIONER
        T_iso_source[:3, 3] = M[1] * self.source_to_isocenter_mm / MM  # on +Yp at ISO
        T_iso_table = np.eye(4)
        T_iso_table[:3, :3] = table_matrix(self.table_rotation_deg, self.table_head_tilt_deg,
                                           self.table_cradle_tilt_deg).T
        T_iso_table[:3, 3] = np.asarray(self.table_position_mm, dtype=float) / MM
        return inverse(T_iso_table) @ T_iso_source


def _system(system):
    from carmkin.model.system import CArmSystem

    if not isinstance(system, CArmSystem):
        raise DicomGeometryError(f"system must be a carmkin CArmSystem (carmkin.load_preset), got "
                                 f"{type(system).__name__}")
    return system


def _configuration(system, q, name: str = "q") -> np.ndarray:
    from carmkin.errors import InvalidConfigurationError
    from carmkin.model.kinematics import check_configuration

    q = check_configuration(q, _system(system).nq, name)
    if q.ndim != 1:
        raise InvalidConfigurationError(f"{name} must be one configuration of shape ({system.nq},), got {q.shape}")
    return q


def isocenter_in_frame2(system) -> np.ndarray:
    """Isocentre axes (3, 3, columns X, Y, Z) in DH frame 2 of the chain: the table axes at rest (all joints 0)
    seen from frame 2, so that the table angles are 0 at rest. For the mobile presets X = Y2, Y = −Z2, Z = −X2;
    for the angiography presets (arm along the table) X = −X2, Y = −Z2, Z = −Y2."""
    return system.dh_frames(np.zeros(_system(system).nq))[1][:3, :3].T


def equipment_axes(system, q) -> np.ndarray:
    """Isocentre axes (3, 3, columns X, Y, Z) in the table frame, fixed to the C-arm base (DH frame 2); on a
    mount (a robot holding the C) to that frame with the mount at rest, so that they stay fixed to the room."""
    q = _configuration(system, q)
    if system.mount.joints:
        q = q.copy()
        q[1 + len(system.table.joints):system.nq - 5] = 0.0
    return system.dh_frames(q)[1][:3, :3] @ isocenter_in_frame2(system)


def isocenter_frame(system, q, source_to_isocenter: float | None = None) -> np.ndarray:
    """Pose (4, 4, m) of the image's isocentre coordinate system in the table frame: the equipment axes, the
    origin on the principal axis at ``source_to_isocenter`` (m, default the orbital offset) from the source."""
    q = _configuration(system, q)
    iso = system.carm.orbital_offset if source_to_isocenter is None else validation.distance(
        source_to_isocenter, "source_to_isocenter", error=DicomGeometryError)
    T_source = system.fk(q)
    T = np.eye(4)
    T[:3, :3] = equipment_axes(system, q)
    T[:3, 3] = T_source[:3, 3] + iso * T_source[:3, 2]
    return T


def isocenter_geometry(system, q, source_to_isocenter: float | None = None, *,
                       convention: str = DEFAULT_CONVENTION) -> IsocenterGeometry:
    """The Isocenter Reference System attributes of the image taken at configuration ``q``."""
    T_table_iso = isocenter_frame(system, q, source_to_isocenter)
    T_iso_source = inverse(T_table_iso) @ system.fk(q)
    M = (T_iso_source[:3, :3] @ SOURCE_IN_POSITIONER.T).T  # rows Xp, Yp, Zp in isocentre axes
    T_iso_table = inverse(T_table_iso)
    at1, at2, at3 = table_angles(T_iso_table[:3, :3].T)
    ap1, ap2, ap3 = positioner_angles(M, convention=convention)
    return IsocenterGeometry(ap1, ap2, ap3, tuple(float(v) for v in T_iso_table[:3, 3] * MM), at1, at2, at3,
                             float(np.linalg.norm(T_iso_source[:3, 3]) * MM), convention)


# --- patient-based XA angles --------------------------------------------------------------------------------
def _patient(patient) -> np.ndarray:
    if isinstance(patient, str):
        return patient_pose(patient)
    return validation.rigid_transform(patient, "patient (pose of the patient frame)", error=DicomGeometryError)


def xa_angles(T_source, patient="HFS", *, convention: str = DEFAULT_CONVENTION) -> tuple[float, float, float]:
    """``(primary, secondary, rotation)`` (deg): XA Positioner Primary Angle (LAO +, RAO −) and Secondary
    Angle (CRA +, CAU −) of a source pose (4, 4, table frame) for a patient (position code or LPS pose in the
    table frame), and the rotation of the detector about the beam (not an XA attribute; Ap3's rule in
    ``convention`` — the primary and secondary angles do not depend on it)."""
    T_patient = _patient(patient)
    T = inverse(T_patient) @ validation.rigid_transform(T_source, "T_source (source pose)", error=DicomGeometryError)
    _, s3 = check_convention(convention)
    primary, secondary, rotation = positioner_angles((T[:3, :3] @ SOURCE_IN_POSITIONER.T).T)
    return primary, secondary, _wrap(s3 * rotation)


def pose_from_xa_angles(primary_deg, secondary_deg, isocenter, source_to_isocenter, patient="HFS",
                        rotation_deg=0.0, *, convention: str = DEFAULT_CONVENTION) -> np.ndarray:
    """Source pose (4, 4) in the table frame for XA angles (deg), the isocentre (3,) in the table frame (m)
    and the source-to-isocentre distance (m) (DICOM Distance Source to Patient, 0018,1111); ``rotation_deg``
    about the beam in Ap3's rule of ``convention``."""
    isocenter = validation.real_array(isocenter, "isocenter", (3,), error=DicomGeometryError, unit="m")
    sid = validation.distance(source_to_isocenter, "source_to_isocenter", error=DicomGeometryError)
    angle(primary_deg, "primary_deg", PRIMARY_RANGE)
    angle(secondary_deg, "secondary_deg", SECONDARY_RANGE)
    s2, _ = check_convention(convention)
    M = positioner_matrix(primary_deg, s2 * float(secondary_deg), rotation_deg, convention=convention)
    T = np.eye(4)
    T[:3, :3] = _patient(patient)[:3, :3] @ M.T @ SOURCE_IN_POSITIONER
    T[:3, 3] = isocenter - sid * T[:3, 2]
    return T


# --- operator-relative table motion ---------------------------------------------------------------------
def table_position(system, q) -> dict[str, float]:
    """Table Top Vertical / Longitudinal / Lateral Position (mm) of configuration ``q``: the table origin
    relative to the C-arm base (DH frame 1, the equipment's arbitrary reference) along the equipment axes:
    vertical = +Y (down), longitudinal = +X (across the table, towards LAO), lateral = +Z (along it, towards
    CRA) — the terms of an operator standing beside the table."""
    q = _configuration(system, q)
    frame1 = system.dh_frames(q)[0]
    axes = equipment_axes(system, q)
    p = axes.T @ (np.zeros(3) - frame1[:3, 3]) * MM
    return {"TableTopVerticalPosition": float(p[1]), "TableTopLongitudinalPosition": float(p[0]),
            "TableTopLateralPosition": float(p[2])}


def table_increments(system, q_first, q) -> dict[str, float]:
    """XA Table Vertical / Longitudinal / Lateral Increment (mm) of ``q`` relative to ``q_first``."""
    _configuration(system, q_first, "q_first")
    a, b = table_position(system, q_first), table_position(system, q)
    return {name.replace("TableTop", "Table").replace("Position", "Increment"): b[name] - a[name] for name in a}
