"""Projection matrices ``P = K [R | t]`` of a configuration, relative to the table or to a patient on it.

Conventions (OpenCV, the project contract in ``DESIGN.md``): the camera frame is ``xray_source`` (origin at
the focal spot, x along image columns, y along image rows (down), z along the principal axis towards the
detector); pixel centres sit at integer pixel coordinates, so the image spans −0.5 … size − 0.5.
``P`` maps homogeneous world points in metres to homogeneous pixels: ``m ~ P [X; 1]``.

Patient frame: DICOM's patient-based frame (PS3.3 C.7.6.2.1.1) in metres: +x to the patient's Left,
+y Posterior, +z Head (LPS), with its origin at a point the user places in the table frame. The table
frame 0 of the toolkit is oriented like DICOM's table coordinate system (PS3.3 C.8.19.6.13.1.3: +Xt to the
table's left, +Yt down, +Zt to the table's head) once the table's head end is taken to be +Z0 — the one
convention stated here. The patient's axes in the table frame for each patient position are those of
PS3.17 FFF.1.2.2.2 ("Options for patient position on the X-Ray table"): e.g. HFS = identity.
"""

from __future__ import annotations

import math

import numpy as np

from carmkin.imaging.camera import ImagingError, _intrinsics
from carmkin.model.system import CArmSystem
from carmkin.transforms import check_rigid_transform, inverse
from carmkin.validation import instance, real_array, rigid_transform
from carmkin.validation import intrinsics as check_intrinsics
from carmkin.validation import projection_matrix as check_projection_matrix

#: Largest natural logarithm of ``|t|`` :func:`pose_from_projection` accepts (a tenth of float64's largest
#: number, so that ``R @ t`` and the pose's products stay finite).
MAX_LOG_TRANSLATION = math.log(np.finfo(float).max / 10)

#: Patient axes (Left, Posterior, Head) as direction cosines in the table frame, per patient position
#: (DICOM PS3.17 FFF.1.2.2.2 table; codes of Patient Position (0018,5100)).
PATIENT_POSITIONS: dict[str, tuple[tuple[int, int, int], tuple[int, int, int], tuple[int, int, int]]] = {
    "HFS": ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
    "HFP": ((-1, 0, 0), (0, -1, 0), (0, 0, 1)),
    "HFDR": ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
    "HFDL": ((0, 1, 0), (-1, 0, 0), (0, 0, 1)),
    "FFS": ((-1, 0, 0), (0, 1, 0), (0, 0, -1)),
    "FFP": ((1, 0, 0), (0, -1, 0), (0, 0, -1)),
    "FFDR": ((0, -1, 0), (-1, 0, 0), (0, 0, -1)),
    "FFDL": ((0, 1, 0), (1, 0, 0), (0, 0, -1)),
}


def intrinsics(system) -> tuple[np.ndarray, tuple[int, int]]:
    """``(K, (columns, rows))``: the intrinsic matrix (3, 3) in pixels and the image size of ``system``."""
    carm = instance(system, CArmSystem, "system", error=ImagingError).carm
    return carm.intrinsics(), (int(carm.detector_columns), int(carm.detector_rows))


def patient_pose(position: str = "HFS", origin=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Pose (4, 4) of the patient frame (LPS, m) in the table frame for a DICOM patient position.

    ``position``: one of :data:`PATIENT_POSITIONS` (HFS, HFP, HFDR, HFDL, FFS, FFP, FFDR, FFDL);
    ``origin`` (3,): the patient frame's origin in the table frame (m).
    """
    if not isinstance(position, str) or position.strip().upper() not in PATIENT_POSITIONS:
        raise ImagingError(f"patient position must be one of {', '.join(PATIENT_POSITIONS)}, got {position!r}")
    key = position.strip().upper()
    origin = real_array(origin, "patient origin", (3,), error=ImagingError, unit="m")
    T = np.eye(4)
    T[:3, :3] = np.array(PATIENT_POSITIONS[key], dtype=float).T  # columns: L, P, H in the table frame
    T[:3, 3] = origin
    return T


def projection_from_pose(K, T) -> np.ndarray:
    """``P = K [Rᵀ | −Rᵀ p]`` (3, 4) for the source pose ``T`` (4, 4) in some world frame."""
    K = _intrinsics(K)
    return K @ inverse(check_rigid_transform(T, "source pose T"))[:3, :]


def projection_matrix(system, q, patient=None) -> np.ndarray:
    """The projection matrix (3, 4) of configuration ``q`` (nq,) taking world points (m) to pixels.

    ``q`` holds model joint values (a calibrated device's readings become them through
    ``system.calibration.model_joints``); a calibrated system's detector rotation and sag enter ``K``
    (``P = H K [Rᵀ | −Rᵀ p]``, :meth:`~carmkin.model.calibration.Calibration.detector_map`;
    :func:`projection_matrices` is the batch).

    World = the table frame 0, or the patient frame when ``patient`` is given: a patient position code
    (``"HFS"``, ...; origin at the table origin) or the (4, 4) pose of the patient frame in the table frame
    (see :func:`patient_pose`).
    """
    K, _ = intrinsics(system)
    T = system.fk(q)
    if T.ndim != 2:
        raise ImagingError(f"q must be one configuration ({system.nq},), got shape {np.shape(q)}")
    if patient is not None:
        T_patient = patient_pose(patient) if isinstance(patient, str) else check_rigid_transform(
            patient, "patient pose")
        T = inverse(T_patient) @ T
    if not system.calibration.is_nominal:  # the detector's rotation and sag (carmkin.model.calibration)
        return system.calibration.detector_map(system.carm, float(np.asarray(q, dtype=float)[-1])) @ \
            projection_from_pose(K, T)
    return projection_from_pose(K, T)


def projection_matrices(system, Q) -> np.ndarray:
    """Projection matrices (N, 3, 4) of configurations ``Q`` (N, nq) (model joint values), vectorized: each
    equals :func:`projection_matrix` of its row (world = the table frame, m to px)."""
    instance(system, CArmSystem, "system", error=ImagingError)
    if np.ndim(Q) != 2:
        raise ImagingError(f"Q must be configurations (N, {system.nq}), got shape {np.shape(Q)}")
    T = system.fk(Q)
    K = view_intrinsics(system, Q)
    R_t = np.swapaxes(T[:, :3, :3], 1, 2)
    extrinsics = np.concatenate((R_t, -R_t @ T[:, :3, 3:]), axis=2)  # [Rᵀ | −Rᵀ p] per view
    return K @ extrinsics


def view_intrinsics(system, Q) -> np.ndarray:
    """The intrinsics of each view of configurations ``Q`` (N, nq): K (3, 3) of a nominal system, else the
    calibrated detector's ``H K`` (N, 3, 3) (:meth:`~carmkin.model.calibration.Calibration.detector_map`)."""
    K = system.carm.intrinsics()
    if system.calibration.is_nominal:
        return K
    return system.calibration.detector_map(system.carm, np.asarray(Q, dtype=float)[:, -1]) @ K


def pose_from_projection(P) -> tuple[np.ndarray, np.ndarray]:
    """``(K, T)`` from a projection matrix (3, 4): K (3, 3) with ``K[2, 2] = 1`` and positive focal lengths,
    and the source pose T (4, 4) in the world frame of ``P`` (inverse of :func:`projection_from_pose`).

    ``P`` may carry any non-zero scale, including a negative one; it enters through
    :func:`carmkin.validation.projection_matrix` (real, finite, rank 3 to ``MAX_PROJECTION_CONDITION``:
    strings, complex values and a P whose left block is rank-deficient in floating point are refused).
    RQ decomposition (scipy) of the normalised left 3x3 block, with the signs fixed so that K has a positive
    diagonal and R is a proper rotation; K is checked as intrinsics and T as a rigid transform on the way
    out (a P of finite entries whose K or centre is out of range raises :class:`ImagingError`).
    """
    from scipy.linalg import (
        rq,  # imported here: carmkin.imaging stays numpy-only on import
    )

    P = check_projection_matrix(P, "P", error=ImagingError)  # ||P[2, :3]|| = 1, det P[:, :3] > 0
    K, R = rq(P[:, :3])
    signs = np.diag(np.sign(np.diag(K)))
    K, R = K @ signs, signs @ R
    scale = K[2, 2]
    K = K / scale
    K[1, 0] = K[2, 0] = K[2, 1] = 0.0  # exact zeros of the triangular factor
    K[2, 2] = 1.0
    K = check_intrinsics(K, "intrinsics of P", error=ImagingError)
    T = np.eye(4)
    T[:3, :3] = R.T
    T[:3, 3] = -R.T @ _translation(K, P[:, 3], scale)
    return K, rigid_transform(T, "source pose of P", error=ImagingError)


def _translation(K: np.ndarray, column: np.ndarray, scale: float) -> np.ndarray:
    """``t = K⁻¹ column / scale`` of ``P = scale · K [R | t]``, or :class:`ImagingError` when ``|t|`` is beyond
    float64 (a finite P whose last column is ~1e300 times its left block: no pose has such a source centre).

    The solve runs on the column divided by its largest entry and the size is checked in logarithms, so no
    intermediate overflows (before: ``inf`` entries and a NaN centre with a RuntimeWarning)."""
    size = float(np.abs(column).max())
    if size == 0.0:
        return np.zeros(3)
    direction = np.linalg.solve(K, column / size)
    length = float(np.linalg.norm(direction))
    if length == 0.0:
        return np.zeros(3)
    log_length = math.log(length) + math.log(size) - math.log(abs(scale))
    if log_length > MAX_LOG_TRANSLATION:
        raise ImagingError(f"P: the source centre lies ~1e{log_length / math.log(10):.0f} "
                           "world units from the origin, beyond float64: expected a projection matrix of a pose "
                           "with a finite source position")
    return (direction * size) / scale
