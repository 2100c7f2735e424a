"""Camera (= X-ray source) pose from the marker pattern (§3.3.2), on OpenCV: right or refused.

The seed solves ``s m = K [r1 r2 t] [X Y 1]ᵀ`` by normalized DLT, orthogonalises the rotation and refines by
Levenberg–Marquardt on the reprojection error (eq. 3.9). Here, every start a library offers is gathered —
both solutions of ``cv2.solvePnPGeneric`` with ``SOLVEPNP_IPPE`` (planar points: the two sides of the planar
ambiguity), ``SOLVEPNP_SQPNP`` (always: a global solver, right where IPPE's candidates are degenerate but
finite, e.g. an exactly fronto-parallel regular grid at an in-plane rotation of 180°, and LM from them
stalls 0.24 m / 12° off at 0.14 px RMS) and the previous pose when tracking — then:

1. **cheirality**: a start or a refined pose with any point at depth ≤ 0 is dropped (the mirror pose, with
   the board behind the source, reprojects exactly as well);
2. each start is refined by Levenberg–Marquardt (:mod:`.reprojection`: MINPACK with the analytic Jacobian);
3. the smallest reprojection error wins;
4. **refusal**: no start in front → :class:`PoseError`; a winner whose RMS residual exceeds
   :data:`MAX_RESIDUAL_RATIO` times the stated corner noise → :class:`PoseError` (no pose explains the
   corners: wrong correspondences, wrong K, lens distortion); a Jacobian whose condition number exceeds
   :data:`MAX_CONDITION` → :class:`PoseError` (the points do not determine the pose in floating point).

The result, :class:`PoseEstimate`, carries the pose, the residuals, the covariance ``σ² (JᵀJ)⁻¹`` over the
perturbation ``R = exp([ω]) R̂``, ``p = p̂ + δp`` (``ω`` rad, ``δp`` m, marker frame; ``σ`` the stated
corner noise or the residual's estimate ``sqrt(SSR / (2N − 6))``) and the condition number of the
column-scaled Jacobian, flagged above :data:`ILL_CONDITIONED` (a planar board seen fronto-parallel from
afar, nearly collinear points: the covariance is then large and its linearisation less trustworthy).
Detection uses ``cv2.aruco.ArucoDetector`` with sub-pixel corner refinement.

Returned poses are camera-to-marker transforms (4, 4): ``X_marker = T @ X_camera``, the convention of
:meth:`CArmSystem.fk`. Lengths in m, angles in rad, pixels in px.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from carmkin.errors import (
    PoseError,  # noqa: F401 (defined there, raised here)
)
from carmkin.extras import require
from carmkin.validation import pixel_array, point_array, real_scalar, rigid_transform

from .camera import CornerView, check_intrinsics
from .pattern import MarkerBoard
from .reprojection import REFINERS, refine_minpack, refine_opencv, reprojection_jacobian  # noqa: F401
from .reprojection import _camera_pose, _depths, _jacobian, _residuals

#: Fewest correspondences accepted (PnP with IPPE / SQPNP needs 4 / 3; 4 keeps a redundancy check).
MIN_POINTS = 4
#: Object points whose smallest principal extent is below this fraction of the largest count as planar (and
#: as one line when the second is).
PLANARITY_TOLERANCE = 1e-9
#: Two starts whose rotations differ by less than this (Frobenius norm) and whose positions differ by less
#: than this fraction of the distance to the points are the same start: refined once.
SAME_START = 1e-6
#: The corner noise (px, σ per coordinate) assumed by the residual test when ``sigma_px`` is not given: an
#: upper bound for a sub-pixel corner detector (ArUco with sub-pixel refinement: ~0.15 px here).
ASSUMED_NOISE_PX = 1.0
#: Smallest σ (px) the residual test uses, for ``sigma_px=0`` (exact corners): floating-point rounding of
#: the projection leaves ~1e-12 px.
NOISE_FLOOR_PX = 1e-6
#: Refuse a pose whose RMS reprojection residual (px) exceeds this multiple of σ. With Gaussian corner noise
#: the RMS is below √2 σ for any N ≥ 4 (its square is σ² χ²(2N − 6) / N): 5 σ is far above any noise.
MAX_RESIDUAL_RATIO = 5.0
#: Condition number of the reprojection Jacobian with unit-norm columns above which an estimate is flagged
#: ill-conditioned. It grows as (distance / board extent)² for a fronto-parallel board (643 for the
#: Siremobile's camera at 415 mm, 12 markers; ~200–350 at the experiment's reference views; 4.8e3 for a
#: 12 × 9 cm grid at 2 m) and as 1 / (offset from a line) for nearly collinear points.
ILL_CONDITIONED = 1e4
#: Beyond this condition number the points do not determine the pose: :class:`PoseError`. Measured on
#: nearly collinear boards with exact corners (``tests/reposition/test_pose_degenerate.py``): below 1.1e7
#: every estimate was right to 1e-9, above it Levenberg–Marquardt may stall in the flat valley (0.3 rad off
#: at 4e-6 px RMS); 1e6 keeps a tenfold margin.
MAX_CONDITION = 1e6


@dataclass(frozen=True)
class PoseEstimate:
    """One pose estimate.

    ``T`` (4, 4): camera pose in the marker frame; ``rms_px``: reprojection RMS (px, per point);
    ``covariance`` (6, 6): of (ω, δp) in rad and m, marker frame (see the module docstring); ``n_points``;
    ``residuals_px`` (N, 2): projected minus measured corners (px); ``condition``: condition number of the
    column-scaled Jacobian; ``sigma_px``: the σ behind the covariance (stated or estimated).
    """

    T: np.ndarray
    rms_px: float
    covariance: np.ndarray
    n_points: int
    residuals_px: np.ndarray
    condition: float
    sigma_px: float

    @property
    def ill_conditioned(self) -> bool:
        """The condition number exceeds :data:`ILL_CONDITIONED`."""
        return bool(self.condition > ILL_CONDITIONED)

    @property
    def sd(self) -> np.ndarray:
        """Standard deviations (6,) of (ω rad, δp m)."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def expressed_in(self, T_frame_marker) -> "PoseEstimate":
        """The same estimate in another frame: ``T`` becomes ``T_frame_marker @ T`` and both blocks of the
        covariance rotate with ``T_frame_marker``'s rotation (ω and δp are vectors of the marker frame)."""
        from .model import to_table_frame

        A = rigid_transform(T_frame_marker, "T_frame_marker", error=PoseError)
        return replace(self, T=A @ self.T, covariance=to_table_frame(self.covariance, A[:3, :3]))


def _correspondences(object_points, image_points) -> tuple[np.ndarray, np.ndarray]:
    obj = point_array(object_points, "object_points", error=PoseError, unit="m, marker frame")
    img = pixel_array(image_points, "image_points", error=PoseError)
    if img.shape != obj.shape[:1] + (2,):
        raise PoseError(f"image_points must have shape ({len(obj)}, 2) (px) to match object_points, got {img.shape}")
    if len(obj) < MIN_POINTS:
        raise PoseError(f"pose estimation needs at least {MIN_POINTS} correspondences, got {len(obj)}")
    return obj, img


def _is_planar(obj: np.ndarray) -> bool:
    s = np.linalg.svd(obj - obj.mean(axis=0), compute_uv=False)
    if s[0] == 0.0 or s[1] <= PLANARITY_TOLERANCE * s[0]:
        raise PoseError("object_points are all on one point or one line: the pose is not determined")
    return s[2] <= PLANARITY_TOLERANCE * s[0]


def _starts(obj: np.ndarray, img: np.ndarray, K: np.ndarray, T_previous) -> list[np.ndarray]:
    """Every start (camera poses (4, 4)) the solvers offer, each once, all points in front of it."""
    cv2 = require("cv2", "reposition")
    methods = (cv2.SOLVEPNP_SQPNP, cv2.SOLVEPNP_ITERATIVE)
    methods = (cv2.SOLVEPNP_IPPE,) + methods if _is_planar(obj) else methods
    # The solvers see the points centred and scaled to unit RMS radius (SQPNP asserts an absolute minimum
    # spread of the points; a 1 cm board fails it): the camera position scales back, the rotation is the same.
    centre = obj.mean(axis=0)
    scale = float(np.sqrt(np.mean(np.sum((obj - centre) ** 2, axis=1))))
    unit = (obj - centre) / scale
    starts = [] if T_previous is None else [T_previous]
    for method in methods:
        try:
            count, rvecs, tvecs, _ = cv2.solvePnPGeneric(unit, img, K, None, flags=method)
        except cv2.error:  # a solver that cannot handle these points offers nothing
            continue
        for r, t in zip(rvecs[:count], tvecs[:count]):
            if np.all(np.isfinite(r)) and np.all(np.isfinite(t)):
                T = _camera_pose(r, t)
                T[:3, 3] = centre + scale * T[:3, 3]
                starts.append(T)
    # cheirality: a start with a point behind the camera (the mirror pose) is dropped; of near-equal starts
    # the one with the smaller reprojection error is kept
    starts = [T for T in starts if np.all(_depths(T, obj) > 0)]
    starts.sort(key=lambda T: float(np.sum(_residuals(K, T, obj, img) ** 2)))
    kept: list[np.ndarray] = []
    for T in starts:
        if any(np.linalg.norm(T[:3, :3] - U[:3, :3]) < SAME_START
               and np.linalg.norm(T[:3, 3] - U[:3, 3]) < SAME_START * (scale + abs(_depths(U, obj)).max()) for U in kept):
            continue
        kept.append(T)
    return kept


def _refuse_residual(rms: float, sigma_px: float | None, n: int) -> None:
    sigma = max(ASSUMED_NOISE_PX if sigma_px is None else sigma_px, NOISE_FLOOR_PX)
    if rms > MAX_RESIDUAL_RATIO * sigma:
        stated = "assumed (ASSUMED_NOISE_PX)" if sigma_px is None else "stated"
        raise PoseError(f"no pose explains the {n} corners: the best reprojection RMS is {rms:.4g} px, more than "
                        f"{MAX_RESIDUAL_RATIO:g} × the {stated} corner noise {sigma:.3g} px (wrong "
                        f"correspondences, wrong K or lens distortion?)")


def _covariance(J: np.ndarray, variance: float) -> tuple[np.ndarray, float]:
    """``variance (JᵀJ)⁻¹`` computed through the column-scaled Jacobian, and its condition number."""
    scale = np.linalg.norm(J, axis=0)
    if not np.all(scale > 0):
        return np.full((6, 6), np.nan), np.inf
    _, s, Vt = np.linalg.svd(J / scale, full_matrices=False)
    condition = float(s[0] / s[-1]) if s[-1] > 0 else np.inf
    if not condition <= MAX_CONDITION:
        return np.full((6, 6), np.nan), condition
    inverse = (Vt.T / s**2) @ Vt  # (JnᵀJn)⁻¹ from the SVD, without forming JnᵀJn
    return variance * inverse / np.outer(scale, scale), condition


def solve_pose(object_points, image_points, K, sigma_px: float | None = None, refine: str = "minpack",
               T_previous=None) -> PoseEstimate:
    """Camera pose from N ≥ 4 correspondences, or :class:`PoseError` (see the module docstring).

    ``object_points`` (N, 3) m in the marker frame, ``image_points`` (N, 2) px, intrinsics ``K`` (3, 3) px
    (no lens distortion). ``sigma_px``: the corner noise σ (px, per coordinate) for the covariance and the
    residual test (default: the covariance from the residual's estimate, the test against
    :data:`ASSUMED_NOISE_PX`). ``refine``: ``"minpack"`` or ``"opencv"``. ``T_previous`` (4, 4): the last
    pose when tracking, an extra start.
    """
    obj, img = _correspondences(object_points, image_points)
    K = check_intrinsics(K)
    if sigma_px is not None:
        sigma_px = real_scalar(sigma_px, "sigma_px", error=PoseError, low=0.0, unit="px")
    if not isinstance(refine, str) or refine not in REFINERS:
        raise PoseError(f"refine must be one of {REFINERS}, got {refine!r}")
    if T_previous is not None:
        T_previous = rigid_transform(T_previous, "T_previous", error=PoseError)
    best = None
    for start in _starts(obj, img, K, T_previous):
        refined = refine_minpack(K, start, obj, img) if refine == "minpack" else refine_opencv(K, start, obj, img)
        for T in (refined, start):  # the start too: OpenCV's LM may end a hair above an exact start (1e-9 rad)
            r = _residuals(K, T, obj, img)
            if not (np.all(np.isfinite(r)) and np.all(np.isfinite(T)) and np.all(_depths(T, obj) > 0)):
                continue  # the refinement crossed to the mirror side or diverged
            ssr = float(np.sum(r**2))
            if best is None or ssr < best[1]:
                best = (T, ssr, r)
    if best is None:
        raise PoseError(f"no pose with every one of the {len(obj)} points in front of the camera explains the "
                        "corners (cheirality): check that object_points and image_points correspond")
    T, ssr, r = best
    n = len(obj)
    rms = float(np.sqrt(ssr / n))
    _refuse_residual(rms, sigma_px, n)
    sigma = sigma_px if sigma_px is not None else float(np.sqrt(ssr / (2 * n - 6)))
    covariance, condition = _covariance(_jacobian(K, T, obj), sigma**2)
    if not condition <= MAX_CONDITION:
        raise PoseError(f"the {n} points do not determine the pose: condition number {condition:.3g} of the "
                        f"reprojection Jacobian > {MAX_CONDITION:g} (nearly collinear points, or a board tiny "
                        "for its distance)")
    return PoseEstimate(T, rms, covariance, n, r, condition, sigma)


def estimate_pose(object_points, image_points, K) -> np.ndarray:
    """Pose (4, 4) of the camera (= X-ray source frame) in the marker frame from ``object_points`` (N, 3)
    m, marker frame, and ``image_points`` (N, 2) px, with intrinsics ``K`` (3, 3) px: the transform taking
    camera coordinates to marker coordinates. :func:`solve_pose` returns it with the residuals,
    covariance and condition (:class:`PoseEstimate`); both raise :class:`PoseError` rather than return a
    pose they cannot stand behind."""
    return solve_pose(object_points, image_points, K).T


@lru_cache(maxsize=8)
def _detector(board: MarkerBoard):
    cv2 = require("cv2", "reposition")

    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    return cv2.aruco.ArucoDetector(board.cv2_board.getDictionary(), params)


def detect_corners(image, board: MarkerBoard) -> CornerView:
    """Markers of ``board`` found in a grayscale ``image`` (uint8, rows × columns) by
    ``cv2.aruco.ArucoDetector`` with sub-pixel corner refinement, as a :class:`CornerView`."""
    if not isinstance(board, MarkerBoard):
        raise PoseError(f"board must be a MarkerBoard, got {type(board).__name__}")
    if not isinstance(image, np.ndarray) or image.ndim != 2 or image.dtype != np.uint8 or min(image.shape) < 1:
        shape, dtype = getattr(image, "shape", None), getattr(image, "dtype", type(image).__name__)
        raise PoseError(f"image must be a non-empty 2-D uint8 grayscale array, got shape {shape}, dtype {dtype}")
    corners, ids, _ = _detector(board).detectMarkers(image)
    if ids is None:
        return CornerView(np.zeros(0, int), np.zeros((0, 3)), np.zeros((0, 2)))
    ids = ids.ravel()
    keep = ids < len(board.corners)
    order = np.argsort(ids[keep], kind="stable")
    ids = ids[keep][order]
    pixels = np.asarray(corners, dtype=float).reshape(-1, 4, 2)[keep][order]
    return CornerView(ids, board.corners[ids].reshape(-1, 3), pixels.reshape(-1, 2))


def pose_from_view(view: CornerView, K, sigma_px: float | None = None, refine: str = "minpack",
                   T_previous=None) -> PoseEstimate:
    """:func:`solve_pose` on a :class:`CornerView` (ideal, noisy or detected corners)."""
    if not isinstance(view, CornerView):
        raise PoseError(f"view must be a CornerView, got {type(view).__name__}")
    if len(view.image_points) < MIN_POINTS:
        raise PoseError(f"the camera sees {len(view)} marker(s) of the pattern: too few for a pose")
    return solve_pose(view.object_points, view.image_points, K, sigma_px, refine, T_previous)
