"""Pinhole geometry of the X-ray source and detector (§3.3, §3.3.5, §4.4.1).

Camera model: the frame ``xray_source`` (origin at the source, Z = principal axis towards the detector,
X/Y along image width/height) is the camera frame; a point ``X`` (m) in that frame projects to the pixel
``m ~ K X`` with ``K = system.carm.intrinsics()`` (pixels). Poses ``T`` (4, 4) are poses of the source in
some world frame (usually the table frame 0), so world points enter the camera frame as ``T⁻¹ X``.

Homography conventions (see ``docs/errata/panorama.md``): for two views 1 and 2 with ``R, t`` the pose of
view 2 in view 1 (``X1 = R X2 + t``) and a plane ``nᵀ X2 = d`` in view 2,
``H = K R K⁻¹ + (1/d) K t nᵀ K⁻¹`` (eq. 4.17) maps pixels of image 2 onto image 1. With ``t = 0`` it is
``K R K⁻¹`` for every plane (the pure-rotation homography).
"""

from __future__ import annotations

import numpy as np

from carmkin import transforms
from carmkin.errors import (
    ImagingError,  # noqa: F401 (defined there, raised here)
)
from carmkin.transforms import check_rigid_transform
from carmkin.validation import (
    MAGNITUDE_LIMIT,
    MIN_DISTANCE,
    integer,
    intrinsics,
    point_array,
    real_array,
    real_scalar,
    rotation,
)

#: Tolerance on ``|‖n‖ − 1|`` of a plane's unit normal (dimensionless).
UNIT_TOLERANCE = 1e-9
#: Below this ``|nᵀ K⁻¹ m|`` (dimensionless) a pixel's ray counts as parallel to a plane (no intersection).
PARALLEL_RAY_TOLERANCE = 1e-12
#: Smallest |d| (m) of a plane ``nᵀ X = d`` for a plane-induced homography: below it the plane passes through
#: the source (1 µm, :data:`carmkin.validation.MIN_DISTANCE`).
MIN_PLANE_DISTANCE = MIN_DISTANCE
#: Largest pixel count of an image side (px): bounds the outline and the in-image test.
MAX_IMAGE_SIDE = 1_000_000


def _points(X, dim: int, name: str) -> np.ndarray:
    # pixels may be far out of the image (a point near the source plane): no magnitude bound for them
    return point_array(X, name, dim, error=ImagingError, unit="px" if dim == 2 else "m",
                       limit=None if "pixels" in name else MAGNITUDE_LIMIT)


def _matrix3(M, name: str) -> np.ndarray:
    """A general real 3x3 matrix (a homography): finite, entries within MAGNITUDE_LIMIT."""
    return real_array(M, name, (3, 3), error=ImagingError)


def _intrinsics(K, name: str = "K") -> np.ndarray:
    """Camera intrinsics through the one way in (:func:`carmkin.validation.intrinsics`)."""
    return intrinsics(K, name, error=ImagingError)


def _size(columns, rows) -> tuple[int, int]:
    """An image size in pixels: two integers in [1, MAX_IMAGE_SIDE] (no bool, no float)."""
    return (integer(columns, "columns", low=1, high=MAX_IMAGE_SIDE, error=ImagingError, unit="px"),
            integer(rows, "rows", low=1, high=MAX_IMAGE_SIDE, error=ImagingError, unit="px"))


def _plane(n, d, name: str = "plane") -> tuple[np.ndarray, float]:
    n = real_array(n, f"{name} normal", (3,), error=ImagingError)
    d = real_scalar(d, f"{name} distance", error=ImagingError, unit="m")
    norm = np.linalg.norm(n)
    if abs(norm - 1.0) > UNIT_TOLERANCE:
        raise ImagingError(f"{name}: normal must be a unit vector (to {UNIT_TOLERANCE:g}), |n| = {norm}")
    return n, float(d)


def _finite(values: np.ndarray, what: str) -> np.ndarray:
    if not np.all(np.isfinite(values)):
        raise ImagingError(f"{what} overflows (a point at or too near infinity in the image)")
    return values


def homogeneous(m) -> np.ndarray:
    """Pixels (N, 2) -> homogeneous pixels (N, 3) with last coordinate 1."""
    m = _points(m, 2, "pixels")
    return np.column_stack((m, np.ones(len(m))))


def dehomogenize(m) -> np.ndarray:
    """Homogeneous pixels (N, 3) -> pixels (N, 2); raises for points at infinity."""
    m = _points(m, 3, "homogeneous pixels")
    if np.any(m[:, 2] == 0.0):
        raise ImagingError("a homogeneous pixel is at infinity (last coordinate 0)")
    with np.errstate(all="ignore"):
        return _finite(m[:, :2] / m[:, 2:], "dehomogenized pixel")


def project(K, T, X, allow_behind: bool = False) -> np.ndarray:
    """Pixels (N, 2) of world points ``X`` (N, 3) (m) seen from the source pose ``T`` (4, 4, world frame).

    Points behind the source (depth ≤ 0) raise :class:`ImagingError` unless ``allow_behind``.
    """
    K = _intrinsics(K)
    T = check_rigid_transform(T, "source pose T")
    X = _points(X, 3, "points X")
    Xc = (X - T[:3, 3]) @ T[:3, :3]  # T⁻¹ X, row-wise
    if not allow_behind and np.any(Xc[:, 2] <= 0):
        raise ImagingError(f"{int(np.sum(Xc[:, 2] <= 0))} point(s) behind the X-ray source (depth <= 0)")
    if np.any(Xc[:, 2] == 0):
        raise ImagingError("a point lies in the source plane (depth 0): its pixel is at infinity")
    return dehomogenize(Xc @ K.T)


def apply_homography(H, m) -> np.ndarray:
    """Pixels (N, 2) mapped by the homography ``H`` (3, 3)."""
    H = _matrix3(H, "H")
    with np.errstate(all="ignore"):
        mapped = _finite(homogeneous(m) @ H.T, "homography image")
    return dehomogenize(mapped)


def relative_pose(T1, T2) -> np.ndarray:
    """Pose of view 2 in view 1, ``T1⁻¹ T2`` (4, 4), from both source poses in one world frame."""
    T1 = check_rigid_transform(T1, "T1")
    T2 = check_rigid_transform(T2, "T2")
    R1, p1 = T1[:3, :3], T1[:3, 3]
    out = np.eye(4)
    out[:3, :3] = R1.T @ T2[:3, :3]
    out[:3, 3] = R1.T @ (T2[:3, 3] - p1)
    return out


def plane_in_frame(T, n, d) -> tuple[np.ndarray, float]:
    """Plane ``nᵀ X = d`` of the world expressed in the frame of pose ``T``: ``(Rᵀ n, d − nᵀ p)``."""
    T = check_rigid_transform(T, "T")
    n, d = _plane(n, d)
    return T[:3, :3].T @ n, d - float(n @ T[:3, 3])


def plane_homography(K, R, t, n, d) -> np.ndarray:
    """Eq. 4.17: ``H = K R K⁻¹ + (1/d) K t nᵀ K⁻¹``, mapping image 2 onto image 1.

    ``R, t``: pose of view 2 in view 1 (``X1 = R X2 + t``, m); ``n, d``: the plane ``nᵀ X2 = d`` in view 2
    (unit normal, m). Exact for points of that plane; ``d`` must not be 0 (plane through the source).
    """
    K = _intrinsics(K)
    R = rotation(R, "R", error=ImagingError)
    t = real_array(t, "t", (3,), error=ImagingError, unit="m")
    n, d = _plane(n, d)
    if abs(d) < MIN_PLANE_DISTANCE:
        raise ImagingError("plane passes through the source (d = 0): no homography")
    Kinv = np.linalg.inv(K)
    return K @ R @ Kinv + K @ np.outer(t, n) @ Kinv / d


def rotation_homography(K, R) -> np.ndarray:
    """``H = K R K⁻¹``: image 2 onto image 1 when view 2 is view 1 rotated by ``R`` about the source."""
    K = _intrinsics(K)
    return K @ rotation(R, "R", error=ImagingError) @ np.linalg.inv(K)


def homography_between(K, T1, T2, n=None, d=None) -> np.ndarray:
    """Homography mapping image 2 onto image 1 for source poses ``T1``, ``T2`` (world frame).

    ``n, d``: the stitching plane ``nᵀ X = d`` in the world frame; ``None`` uses only the rotation
    (:func:`rotation_homography`), exact for every point when both views share the source position.
    """
    rel = relative_pose(T1, T2)
    if n is None and d is not None:
        raise ImagingError(f"plane distance d = {d!r} given without the plane normal n: give both, or neither "
                           "for the rotation-only homography")
    if n is None:
        return rotation_homography(K, rel[:3, :3])
    n2, d2 = plane_in_frame(T2, n, d)
    return plane_homography(K, rel[:3, :3], rel[:3, 3], n2, d2)


def back_project(K, m, n, d) -> np.ndarray:
    """Eq. 3.17: points ``P = d K⁻¹m / (nᵀ K⁻¹m)`` (N, 3) (m, source frame) on the plane ``nᵀ P = d``.

    ``m``: pixels (N, 2); ``n, d``: the plane in the source frame (unit normal, m).
    """
    n, d = _plane(n, d)
    m = point_array(m, "pixels m", 2, error=ImagingError, unit="px")
    rays = homogeneous(m) @ np.linalg.inv(_intrinsics(K)).T
    denominator = rays @ n / np.linalg.norm(rays, axis=1)  # cosine of the ray to the plane's normal
    if np.any(np.abs(denominator) < PARALLEL_RAY_TOLERANCE):
        raise ImagingError("a pixel's ray is parallel to the measurement plane")
    with np.errstate(all="ignore"):
        P = _finite(d * (rays / np.linalg.norm(rays, axis=1)[:, None]) / denominator[:, None], "back-projected point")
    if np.any(P[:, 2] <= 0):
        raise ImagingError("the plane is behind the source along a pixel's ray")
    return P


def measure_distance(K, m1, m2, n, d) -> np.ndarray:
    """Metric distances (N,) (m) between pixel pairs ``m1[i]``, ``m2[i]`` whose points lie on ``nᵀ P = d``."""
    return np.linalg.norm(back_project(K, m1, n, d) - back_project(K, m2, n, d), axis=1)


def rotation_between(a, b) -> np.ndarray:
    """The minimal rotation R (3, 3) with ``R â = b̂`` (rotation about ``a × b`` by their angle).

    Antiparallel vectors: the half turn about the axis perpendicular to ``a`` closest to image X.
    """
    a = real_array(a, "a", (3,), error=ImagingError)
    b = real_array(b, "b", (3,), error=ImagingError)
    return transforms.rotation_between(a, b, error=ImagingError)


def image_border(columns: int, rows: int, per_edge: int = 16) -> np.ndarray:
    """Closed outline (4·per_edge + 1, 2) of the detector in pixels, along the pixel edges (−0.5 … size−0.5)."""
    columns, rows = _size(columns, rows)
    per_edge = integer(per_edge, "per_edge", low=1, high=MAX_IMAGE_SIDE, error=ImagingError)
    u0, u1, v0, v1 = -0.5, columns - 0.5, -0.5, rows - 0.5
    s = np.linspace(0.0, 1.0, per_edge, endpoint=False)
    edges = [
        np.column_stack((u0 + s * (u1 - u0), np.full_like(s, v0))),
        np.column_stack((np.full_like(s, u1), v0 + s * (v1 - v0))),
        np.column_stack((u1 - s * (u1 - u0), np.full_like(s, v1))),
        np.column_stack((np.full_like(s, u0), v1 - s * (v1 - v0))),
    ]
    outline = np.vstack(edges)
    return np.vstack((outline, outline[:1]))


def in_image(m, columns: int, rows: int) -> np.ndarray:
    """Boolean mask (N,) of pixels (N, 2) inside the detector (pixel edges −0.5 … size−0.5)."""
    m = _points(m, 2, "pixels")
    columns, rows = _size(columns, rows)
    return (m[:, 0] >= -0.5) & (m[:, 0] <= columns - 0.5) & (m[:, 1] >= -0.5) & (m[:, 1] <= rows - 0.5)
