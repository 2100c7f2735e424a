"""The reprojection error of a camera pose and its Levenberg–Marquardt minimisation (eq. 3.9).

Poses are camera-to-marker transforms (4, 4): ``X_marker = T @ X_camera`` (the convention of
:meth:`CArmSystem.fk`). A pose is perturbed as ``R = exp([ω]) R̂``, ``p = p̂ + δp`` with ``ω`` (rad) and
``δp`` (m) both in the marker frame; :func:`reprojection_jacobian` is the derivative of the pixels with respect
to ``(ω, δp)``. No lens distortion; pixels in px (OpenCV's convention, pixel centres at integers).

The LM is MINPACK's (``lmder`` through ``scipy.optimize.leastsq``) with that analytic Jacobian, by default:
with the X-ray intrinsics (a ~13° field of view, so tilts of the pattern are weakly observed)
``cv2.solvePnPRefineLM`` stops far from the minimum (measured: sum of squared residuals 6.46 px² where the
minimum is 3.46 px², 1.28° from the truth instead of 0.04°, for 48 corners with 0.2 px noise at 0.415 m);
:func:`refine_opencv` keeps it for comparison (``benchmarks/bench_reposition.py`` prints both).
"""

from __future__ import annotations

import numpy as np

from carmkin.errors import PoseError
from carmkin.extras import require
from carmkin.validation import pixel_array, point_array, rigid_transform

#: The refinements :func:`refine` offers.
REFINERS = ("minpack", "opencv")
#: Levenberg–Marquardt refinement: relative tolerances on the cost, the step and the gradient (MINPACK's
#: ftol, xtol, gtol) and its budget of function evaluations (it converges in ~10 from a PnP start), and
#: OpenCV's criteria for :func:`refine_opencv` (at most 100 iterations, step < 1e-14).
LM_TOLERANCE = 1e-12
LM_EVALUATIONS = 200
LM_ITERATIONS = 100
LM_EPSILON = 1e-14


def _camera_pose(rvec, tvec) -> np.ndarray:
    """The camera pose (4, 4) in the marker frame from OpenCV's marker-to-camera ``rvec, tvec``."""
    cv2 = require("cv2", "reposition")

    R, _ = cv2.Rodrigues(np.asarray(rvec, dtype=float))
    T = np.eye(4)
    T[:3, :3] = R.T
    T[:3, 3] = -R.T @ np.asarray(tvec, dtype=float).ravel()
    return T


def _depths(T: np.ndarray, obj: np.ndarray) -> np.ndarray:
    """Depth (N,) (m, along the camera's Z) of the marker-frame points ``obj`` (N, 3) seen from ``T``."""
    return (obj - T[:3, 3]) @ T[:3, 2]


def _residuals(K: np.ndarray, T: np.ndarray, obj: np.ndarray, img: np.ndarray) -> np.ndarray:
    """Projected minus measured pixels (N, 2) (px); infinite or NaN for a point at depth 0."""
    Xc = (obj - T[:3, 3]) @ T[:3, :3]
    with np.errstate(divide="ignore", invalid="ignore"):
        return (Xc @ K.T)[:, :2] / Xc[:, 2:] - img


_UNSET = object()


def _inputs(K, T, object_points, image_points=_UNSET, name: str = "T"):
    from .camera import check_intrinsics

    K = check_intrinsics(K)
    T = rigid_transform(T, name, error=PoseError)
    obj = point_array(object_points, "object_points", error=PoseError, unit="m, marker frame")
    if image_points is _UNSET:  # the Jacobian needs none
        return K, T, obj
    img = pixel_array(image_points, "image_points", error=PoseError)
    if img.shape != obj.shape[:1] + (2,):
        raise PoseError(f"image_points must have shape ({len(obj)}, 2) (px) to match object_points, got {img.shape}")
    return K, T, obj, img


def reprojection_jacobian(K, T, object_points) -> np.ndarray:
    """d(pixels)/d(ω, δp) (2N, 6) at the camera pose ``T`` (marker frame, see the module docstring), for
    ``object_points`` (N, 3) m in the marker frame and intrinsics ``K`` (3, 3) px.

    Written out rather than taken from ``cv2.projectPoints``, whose Jacobian is with respect to the
    Rodrigues vector and translation of the inverse (marker-to-camera) transform.
    """
    return _jacobian(*_inputs(K, T, object_points))


def _jacobian(K: np.ndarray, T: np.ndarray, object_points: np.ndarray) -> np.ndarray:
    R = T[:3, :3]
    a = np.asarray(object_points, float) - T[:3, 3]
    Xc = a @ R
    with np.errstate(divide="ignore", invalid="ignore"):
        iz = 1.0 / Xc[:, 2]
    fx, s, fy = K[0, 0], K[0, 1], K[1, 1]
    # pixel gradients with respect to the marker-frame point, g = (d pixel / dXc) Rᵀ; then
    # d/dω = g Rᵀ [a]× = g × a (row-wise) and d/dδp = −g
    n = len(a)
    d = np.zeros((2 * n, 3))  # rows 2i, 2i+1: d(u, v)/dXc of point i
    d[0::2, 0], d[0::2, 1], d[0::2, 2] = fx * iz, s * iz, -(fx * Xc[:, 0] + s * Xc[:, 1]) * iz * iz
    d[1::2, 1], d[1::2, 2] = fy * iz, -fy * Xc[:, 1] * iz * iz
    g = d @ R.T
    a2 = np.repeat(a, 2, axis=0)
    J = np.empty((2 * n, 6))
    J[:, 0] = g[:, 1] * a2[:, 2] - g[:, 2] * a2[:, 1]
    J[:, 1] = g[:, 2] * a2[:, 0] - g[:, 0] * a2[:, 2]
    J[:, 2] = g[:, 0] * a2[:, 1] - g[:, 1] * a2[:, 0]
    J[:, 3:] = -g
    return J


def _perturbed(T0: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``R = exp([ω]) R0``, ``p = p0 + δp`` for ``x = (ω, δp)``."""
    import cv2

    T = T0.copy()
    T[:3, :3] = cv2.Rodrigues(np.asarray(x[:3], dtype=float))[0] @ T0[:3, :3]
    T[:3, 3] = T0[:3, 3] + x[3:]
    return T


def refine(K, T0, object_points, image_points, method: str = "minpack") -> np.ndarray:
    """The camera pose (4, 4) that Levenberg–Marquardt reaches from ``T0`` (4, 4) on the reprojection error
    of ``object_points`` (N, 3) m, marker frame, against ``image_points`` (N, 2) px with intrinsics ``K``:
    ``method`` ``"minpack"`` (:func:`refine_minpack`) or ``"opencv"`` (``cv2.solvePnPRefineLM``)."""
    K, T0, obj, img = _inputs(K, T0, object_points, image_points, "T0")
    if not isinstance(method, str) or method not in REFINERS:
        raise PoseError(f"method must be one of {REFINERS}, got {method!r}")
    return refine_minpack(K, T0, obj, img) if method == "minpack" else refine_opencv(K, T0, obj, img)


def refine_minpack(K: np.ndarray, T0: np.ndarray, obj: np.ndarray, img: np.ndarray) -> np.ndarray:
    """Levenberg–Marquardt (MINPACK's lmder, through ``scipy.optimize.leastsq``, whose thin wrapper costs
    a third of ``least_squares``'s) on the reprojection error from the camera pose ``T0``. Inputs already
    checked (see :func:`refine`)."""
    from scipy.optimize import leastsq

    with np.errstate(all="ignore"):  # a poor start may put points behind the camera on the way
        x = leastsq(  # full_output: MINPACK's status is returned rather than warned about
            lambda x: _residuals(K, _perturbed(T0, x), obj, img).ravel(), np.zeros(6),
            Dfun=lambda x: _jacobian(K, _perturbed(T0, x), obj),  # left Jacobian ≈ I: same optimum
            full_output=True, ftol=LM_TOLERANCE, xtol=LM_TOLERANCE, gtol=LM_TOLERANCE, maxfev=LM_EVALUATIONS)[0]
    return _perturbed(T0, x)


def refine_opencv(K: np.ndarray, T0: np.ndarray, obj: np.ndarray, img: np.ndarray) -> np.ndarray:
    """``cv2.solvePnPRefineLM`` from the camera pose ``T0``; returns the camera pose. Inputs already checked
    (see :func:`refine`)."""
    cv2 = require("cv2", "reposition")

    R = T0[:3, :3].T  # marker → camera
    rvec, tvec = cv2.Rodrigues(R)[0], (-R @ T0[:3, 3]).reshape(3, 1)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, LM_ITERATIONS, LM_EPSILON)
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, None, rvec, tvec, criteria=criteria)
    return _camera_pose(rvec, tvec)
