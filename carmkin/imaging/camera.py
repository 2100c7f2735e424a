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
from carmkin.validation import MAGNITUDE_LIMIT, real_array, real_scalar


def _points(X, dim: int, name: str) -> np.ndarray:
    # pixels may be far out of the image (a point near the source plane): no magnitude bound for them
    X = real_array(X, name, error=ImagingError, limit=None if "pixels" in name else MAGNITUDE_LIMIT)
    if X.ndim == 1:
        X = X[None, :]
    if X.ndim != 2 or X.shape[1] != dim:
        raise ImagingError(f"{name} must have shape ({dim},) or (N, {dim}), got {X.shape}")
    return X


def _matrix3(M, name: str) -> np.ndarray:
    return real_array(M, name, (3, 3), error=ImagingError)


def _plane(n, d, name: str = "plane") -> tuple[np.ndarray, float]:
    n = real_array(n, f"{name} normal", (3,), error=ImagingError)
    d = real_scalar(d, f"{name} distance", error=ImagingError, unit="m")
    norm = np.linalg.norm(n)
    if abs(norm - 1.0) > 1e-9:
        raise ImagingError(f"{name}: normal must be a unit vector, |n| = {norm}")
    return n, float(d)


def homogeneous(m) -> np.ndarray:
    """Pixels (N, 2) -> homogeneous pixels (N, 3) with last coordinate 1."""
    m = _points(m, 2, "pixels")
    return np.column_stack((m, np.ones(len(m))))


def dehomogenize(m) -> np.ndarray:
    """Homogeneous pixels (N, 3) -> pixels (N, 2); raises for points at infinity."""
    m = _points(m, 3, "homogeneous pixels")
    if np.any(np.abs(m[:, 2]) < 1e-300):
        raise ImagingError("a homogeneous pixel is at infinity (last coordinate 0)")
    return m[:, :2] / m[:, 2:]


def project(K, T, X, allow_behind: bool = False) -> np.ndarray:
    """Pixels (N, 2) of world points ``X`` (N, 3) (m) seen from the source pose ``T`` (4, 4, world frame).

    Points behind the source (depth ≤ 0) raise :class:`ImagingError` unless ``allow_behind``.
    """
    K = _matrix3(K, "K")
    T = check_rigid_transform(T, "source pose T")
    X = _points(X, 3, "points X")
    Xc = (X - T[:3, 3]) @ T[:3, :3]  # T⁻¹ X, row-wise
    if not allow_behind and np.any(Xc[:, 2] <= 0):
        raise ImagingError(f"{int(np.sum(Xc[:, 2] <= 0))} point(s) behind the X-ray source (depth <= 0)")
    return dehomogenize(Xc @ K.T)


def apply_homography(H, m) -> np.ndarray:
    """Pixels (N, 2) mapped by the homography ``H`` (3, 3)."""
    return dehomogenize(homogeneous(m) @ _matrix3(H, "H").T)


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
    K = _matrix3(K, "K")
    R = _matrix3(R, "R")
    t = _points(t, 3, "t")[0]
    n, d = _plane(n, d)
    if abs(d) < 1e-15:
        raise ImagingError("plane passes through the source (d = 0): no homography")
    Kinv = np.linalg.inv(K)
    return K @ R @ Kinv + K @ np.outer(t, n) @ Kinv / d


def rotation_homography(K, R) -> np.ndarray:
    """``H = K R K⁻¹``: image 2 onto image 1 when view 2 is view 1 rotated by ``R`` about the source."""
    K = _matrix3(K, "K")
    return K @ _matrix3(R, "R") @ np.linalg.inv(K)


def homography_between(K, T1, T2, n=None, d=None) -> np.ndarray:
    """Homography mapping image 2 onto image 1 for source poses ``T1``, ``T2`` (world frame).

    ``n, d``: the stitching plane ``nᵀ X = d`` in the world frame; ``None`` uses only the rotation
    (:func:`rotation_homography`), exact for every point when both views share the source position.
    """
    rel = relative_pose(T1, T2)
    if n is None:
        return rotation_homography(K, rel[:3, :3])
    n2, d2 = plane_in_frame(T2, n, d)
    return plane_homography(K, rel[:3, :3], rel[:3, 3], n2, d2)


def back_project(K, m, n, d) -> np.ndarray:
    """Eq. 3.17: points ``P = d K⁻¹m / (nᵀ K⁻¹m)`` (N, 3) (m, source frame) on the plane ``nᵀ P = d``.

    ``m``: pixels (N, 2); ``n, d``: the plane in the source frame (unit normal, m).
    """
    n, d = _plane(n, d)
    rays = homogeneous(m) @ np.linalg.inv(_matrix3(K, "K")).T
    denominator = rays @ n
    if np.any(np.abs(denominator) < 1e-12):
        raise ImagingError("a pixel's ray is parallel to the measurement plane")
    P = d * rays / denominator[:, None]
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
    a = _points(a, 3, "a")[0]
    b = _points(b, 3, "b")[0]
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if na < 1e-15 or nb < 1e-15:
        raise ImagingError("rotation_between needs non-zero vectors")
    return transforms.rotation_between(a, b)


def image_border(columns: int, rows: int, per_edge: int = 16) -> np.ndarray:
    """Closed outline (4·per_edge + 1, 2) of the detector in pixels, along the pixel edges (−0.5 … size−0.5)."""
    if per_edge < 1:
        raise ImagingError(f"per_edge must be >= 1, got {per_edge}")
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
    return (m[:, 0] >= -0.5) & (m[:, 0] <= columns - 0.5) & (m[:, 1] >= -0.5) & (m[:, 1] <= rows - 0.5)
