"""Camera (= X-ray source) pose from the marker pattern (§3.3.2), on OpenCV.

The seed solves ``s m = K [r1 r2 t] [X Y 1]ᵀ`` by normalized DLT, orthogonalises the rotation and refines by
Levenberg–Marquardt on the reprojection error (eq. 3.9). The same pipeline on libraries: the initial pose
from ``cv2.solvePnPGeneric`` with ``SOLVEPNP_IPPE`` for a planar pattern (both solutions of the planar
ambiguity; ``SOLVEPNP_SQPNP`` for non-planar points), then Levenberg–Marquardt on each, the one with the
smaller reprojection error winning. The LM is MINPACK's (``lmder`` through ``scipy.optimize.leastsq``)
with the analytic Jacobian below, by default: with the X-ray intrinsics (a ~13° field of view, so tilts of
the pattern are weakly observed) ``cv2.solvePnPRefineLM`` stops far from the minimum (measured: sum of
squared residuals 6.46 px² where the minimum is 3.46 px², 1.28° from the truth instead of 0.04°, for 48
corners with 0.2 px noise at 0.415 m); ``refine="opencv"`` selects it for comparison
(``benchmarks/bench_reposition.py`` prints both). Detection uses ``cv2.aruco.ArucoDetector`` with sub-pixel
corner refinement.

Returned poses are camera-to-marker transforms (4, 4): ``X_marker = T @ X_camera``, the convention of
:meth:`CArmSystem.fk`. The covariance is the Gauss–Newton one, ``σ² (JᵀJ)⁻¹``, over the perturbation
``R = exp([ω]) R̂``, ``p = p̂ + δp`` of the camera pose, ``ω`` (rad) and ``δp`` (m) both in the marker frame;
``σ`` is the given pixel noise or the residual's estimate ``sqrt(SSR / (2N − 6))``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from carmkin.errors import (
    PoseError,  # noqa: F401 (defined there, raised here)
)
from carmkin.validation import real_array

from .camera import CornerView, check_intrinsics
from .pattern import MarkerBoard

#: Fewest correspondences accepted (PnP with IPPE / SQPNP needs 4 / 3; 4 keeps a redundancy check).
MIN_POINTS = 4
#: Object points whose smallest principal extent is below this fraction of the largest count as planar.
PLANARITY_TOLERANCE = 1e-9
#: Levenberg–Marquardt refinement: relative tolerances on the cost, the step and the gradient (MINPACK's
#: ftol, xtol, gtol) and its budget of function evaluations (it converges in ~10 from an IPPE start; the
#: candidate with the smaller residual wins anyway), and OpenCV's criteria for ``refine="opencv"`` (at most
#: 100 iterations, step < 1e-14).
LM_TOLERANCE = 1e-12
LM_EVALUATIONS = 200
LM_ITERATIONS = 100
LM_EPSILON = 1e-14
REFINERS = ("minpack", "opencv")
#: The two IPPE solutions of a planar pattern are the two sides of its pose ambiguity, a reflection of the
#: tilt about the line of sight; when their rotations differ by less than this (Frobenius norm, ~0.6°) they
#: start in the same basin and only the first is refined.
SAME_START = 0.01


@dataclass(frozen=True)
class PoseEstimate:
    """One pose estimate.

    ``T`` (4, 4): camera pose in the marker frame; ``rms_px``: reprojection RMS (px); ``covariance`` (6, 6):
    of (ω, δp) in rad and m, marker frame (see the module docstring); ``n_points``.
    """

    T: np.ndarray
    rms_px: float
    covariance: np.ndarray
    n_points: int


def _correspondences(object_points, image_points) -> tuple[np.ndarray, np.ndarray]:
    obj = real_array(object_points, "object_points", (None, 3), error=PoseError, unit="m, marker frame")
    img = real_array(image_points, "image_points", error=PoseError, limit=None, unit="px")
    if img.shape != (len(obj), 2):
        raise PoseError(f"image_points must have shape ({len(obj)}, 2) (px) to match object_points, got {img.shape}")
    if len(obj) < MIN_POINTS:
        raise PoseError(f"pose estimation needs at least {MIN_POINTS} correspondences, got {len(obj)}")
    return obj, img


def _is_planar(obj: np.ndarray) -> bool:
    s = np.linalg.svd(obj - obj.mean(axis=0), compute_uv=False)
    if s[0] == 0.0 or s[1] <= PLANARITY_TOLERANCE * s[0]:
        raise PoseError("object_points are all on one point or one line: the pose is not determined")
    return s[2] <= PLANARITY_TOLERANCE * s[0]


def _camera_pose(rvec, tvec) -> np.ndarray:
    import cv2

    R, _ = cv2.Rodrigues(rvec)
    T = np.eye(4)
    T[:3, :3] = R.T
    T[:3, 3] = -R.T @ np.asarray(tvec, dtype=float).ravel()
    return T


def _residuals(K: np.ndarray, T: np.ndarray, obj: np.ndarray, img: np.ndarray) -> np.ndarray:
    Xc = (obj - T[:3, 3]) @ T[:3, :3]
    return (Xc @ K.T)[:, :2] / Xc[:, 2:] - img


def reprojection_jacobian(K, T, object_points) -> np.ndarray:
    """d(pixels)/d(ω, δp) (2N, 6) at the camera pose ``T`` (marker frame, see the module docstring).

    Written out rather than taken from ``cv2.projectPoints``, whose Jacobian is with respect to the
    Rodrigues vector and translation of the inverse (marker-to-camera) transform.
    """
    K, T = np.asarray(K, float), np.asarray(T, float)
    R = T[:3, :3]
    a = np.asarray(object_points, float) - T[:3, 3]
    Xc = a @ R
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
    T[:3, :3] = cv2.Rodrigues(x[:3])[0] @ T0[:3, :3]
    T[:3, 3] = T0[:3, 3] + x[3:]
    return T


def refine_minpack(K, T0, obj: np.ndarray, img: np.ndarray) -> np.ndarray:
    """Levenberg–Marquardt (MINPACK's lmder, through ``scipy.optimize.leastsq``, whose thin wrapper costs
    a third of ``least_squares``'s) on the reprojection error from the camera pose ``T0``."""
    from scipy.optimize import leastsq

    with np.errstate(divide="ignore", invalid="ignore"):  # a poor start may put points behind the camera
        x = leastsq(  # full_output: MINPACK's status is returned rather than warned about
            lambda x: _residuals(K, _perturbed(T0, x), obj, img).ravel(), np.zeros(6),
            Dfun=lambda x: reprojection_jacobian(K, _perturbed(T0, x), obj),  # left Jacobian ≈ I: same optimum
            full_output=True, ftol=LM_TOLERANCE, xtol=LM_TOLERANCE, gtol=LM_TOLERANCE, maxfev=LM_EVALUATIONS)[0]
    return _perturbed(T0, x)


def refine_opencv(K, rvec, tvec, obj: np.ndarray, img: np.ndarray) -> np.ndarray:
    """``cv2.solvePnPRefineLM`` from the marker-to-camera ``rvec, tvec``; returns the camera pose."""
    import cv2

    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, LM_ITERATIONS, LM_EPSILON)
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, None, rvec.copy(), tvec.copy(), criteria=criteria)
    return _camera_pose(rvec, tvec)


def solve_pose(object_points, image_points, K, sigma_px: float | None = None, refine: str = "minpack") -> PoseEstimate:
    """Camera pose from N ≥ 4 correspondences: ``object_points`` (N, 3) m in the marker frame, ``image_points``
    (N, 2) px, intrinsics ``K`` (3, 3) px; no lens distortion. ``sigma_px``: the corner noise for the
    covariance (default: estimated from the residual). ``refine``: ``"minpack"`` or ``"opencv"``."""
    import cv2

    obj, img = _correspondences(object_points, image_points)
    K = check_intrinsics(K)
    if sigma_px is not None and not (np.isfinite(sigma_px) and sigma_px >= 0):
        raise PoseError(f"sigma_px must be finite and >= 0 (px), got {sigma_px}")
    if refine not in REFINERS:
        raise PoseError(f"refine must be one of {REFINERS}, got {refine!r}")
    # IPPE for a planar pattern; it returns NaN for an exactly fronto-parallel view (the C-arm at its zero
    # joints looks straight at the board), where SQPNP, which also takes planar points, still solves.
    methods = (cv2.SOLVEPNP_IPPE, cv2.SOLVEPNP_SQPNP) if _is_planar(obj) else (cv2.SOLVEPNP_SQPNP,)
    for method in methods:
        count, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, img, K, None, flags=method)
        candidates = [(r, v) for r, v in zip(rvecs[:count], tvecs[:count])
                      if np.isfinite(r).all() and np.isfinite(v).all()]
        if candidates:
            break
    best, starts = None, []
    for rvec, tvec in candidates:
        start = _camera_pose(rvec, tvec)
        if any(np.linalg.norm(start[:3, :3] - other) < SAME_START for other in starts):
            continue  # both IPPE solutions in one basin (a nearly fronto-parallel view): refine once
        starts.append(start[:3, :3])
        if refine == "opencv":
            T = refine_opencv(K, rvec, tvec, obj, img)
        else:
            T = refine_minpack(K, start, obj, img)
        with np.errstate(divide="ignore", invalid="ignore"):
            residual = _residuals(K, T, obj, img)
        if not np.all(np.isfinite(residual)):
            continue
        ssr = float(np.sum(residual**2))
        if best is None or ssr < best[1]:
            best = (T, ssr)
    if best is None:
        raise PoseError("OpenCV found no pose in front of the camera for these correspondences")
    T, ssr = best
    dof = 2 * len(obj) - 6
    variance = sigma_px**2 if sigma_px is not None else (ssr / dof if dof > 0 else np.nan)
    J = reprojection_jacobian(K, T, obj)
    try:
        covariance = variance * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        covariance = np.full((6, 6), np.nan)
    return PoseEstimate(T, float(np.sqrt(ssr / len(obj))), covariance, len(obj))


def estimate_pose(object_points, image_points, K) -> np.ndarray:
    """Pose (4, 4) of the camera (= X-ray source frame) in the marker frame from ``object_points`` (N, 3)
    m, marker frame, and ``image_points`` (N, 2) px, with intrinsics ``K`` (3, 3) px: the transform taking
    camera coordinates to marker coordinates. See :func:`solve_pose` for the RMS and covariance."""
    return solve_pose(object_points, image_points, K).T


@lru_cache(maxsize=8)
def _detector(board: MarkerBoard):
    import cv2

    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    return cv2.aruco.ArucoDetector(board.cv2_board.getDictionary(), params)


def detect_corners(image, board: MarkerBoard) -> CornerView:
    """Markers of ``board`` found in a grayscale ``image`` (uint8, rows × columns) by
    ``cv2.aruco.ArucoDetector`` with sub-pixel corner refinement, as a :class:`CornerView`."""
    image = np.asarray(image)
    if image.ndim != 2 or image.dtype != np.uint8:
        raise PoseError(f"image must be a 2-D uint8 grayscale array, got shape {image.shape}, dtype {image.dtype}")
    corners, ids, _ = _detector(board).detectMarkers(image)
    if ids is None:
        return CornerView(np.zeros(0, int), np.zeros((0, 3)), np.zeros((0, 2)))
    ids = ids.ravel()
    keep = ids < len(board.corners)
    order = np.argsort(ids[keep], kind="stable")
    ids = ids[keep][order]
    pixels = np.asarray(corners, dtype=float).reshape(-1, 4, 2)[keep][order]
    return CornerView(ids, board.corners[ids].reshape(-1, 3), pixels.reshape(-1, 2))


def pose_from_view(view: CornerView, K, sigma_px: float | None = None, refine: str = "minpack") -> PoseEstimate:
    """:func:`solve_pose` on a :class:`CornerView` (ideal, noisy or detected corners)."""
    if len(view.image_points) < MIN_POINTS:
        raise PoseError(f"the camera sees {len(view)} marker(s) of the pattern: too few for a pose")
    return solve_pose(view.object_points, view.image_points, K, sigma_px, refine)
