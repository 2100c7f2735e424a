"""What the camera at the X-ray source sees of the pattern, as corner lists (ideal or with pixel noise).

The camera shares the X-ray source's frame and intrinsics (§3.3.1: camera and mirror construction, one
calibration for both), so its pose is the source pose and ``K = system.carm.intrinsics()``. A marker counts
as visible when its printed side faces the camera and its four corners project inside the image by at least
:data:`BORDER_PX` (a detector finds only whole markers). Poses are 4x4 camera-to-frame transforms
(:meth:`CArmSystem.fk` convention); lengths in m, pixels in px (OpenCV: pixel centres at integers).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from carmkin.errors import (
    CameraError,  # noqa: F401 (defined there, raised here)
    )
from carmkin.transforms import check_rigid_transform, inverse
from carmkin.validation import intrinsics, point_array, real_scalar

from . import _checks
from .pattern import MarkerBoard

#: A visible marker's corners lie at least this far inside the image edges (px).
BORDER_PX = 3.0


@dataclass(frozen=True)
class CornerView:
    """Corners of the visible markers: ``ids`` (M,), ``object_points`` (4M, 3) m in the marker frame,
    ``image_points`` (4M, 2) px, marker by marker in OpenCV's corner order."""

    ids: np.ndarray
    object_points: np.ndarray
    image_points: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)


def check_intrinsics(K, name: str = "K") -> np.ndarray:
    """``K`` as a float (3, 3) pinhole matrix ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` (px), else a
    :class:`CameraError`: :func:`carmkin.validation.intrinsics`, the one way in for intrinsics."""
    return intrinsics(K, name, error=CameraError)


def project_points(K, T_frame_camera, points) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (N, 2) and depths (N,) (m) of ``points`` (N, 3) of a frame seen by a camera at ``T_frame_camera``."""
    T = check_rigid_transform(T_frame_camera, "T_frame_camera")
    K = check_intrinsics(K)
    Xc = (point_array(points, "points", error=CameraError) - T[:3, 3]) @ T[:3, :3]
    depth = Xc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        pixels = (Xc @ K.T)[:, :2] / depth[:, None]
    return pixels, depth


def visible_corners(board: MarkerBoard, K, image_size, T_marker_camera) -> CornerView:
    """Ideal corners of every marker of ``board`` fully in view of the camera at ``T_marker_camera``.

    ``image_size`` = (columns, rows) in px. Empty when the camera sees the back of the board.
    """
    _checks.instance(board, MarkerBoard, "board", CameraError)
    columns, rows = check_image_size(image_size)
    T = check_rigid_transform(T_marker_camera, "T_marker_camera")
    corners = board.corners
    if T[2, 3] >= 0.0:  # the board's Z points away from its printed side: the camera must be at Z < 0
        return CornerView(np.zeros(0, int), np.zeros((0, 3)), np.zeros((0, 2)))
    pixels, depth = project_points(K, T, corners.reshape(-1, 3))
    pixels, depth = pixels.reshape(-1, 4, 2), depth.reshape(-1, 4)
    with np.errstate(invalid="ignore"):
        inside = (depth > 0) & (pixels[..., 0] >= BORDER_PX - 0.5) & (pixels[..., 0] <= columns - 0.5 - BORDER_PX) \
            & (pixels[..., 1] >= BORDER_PX - 0.5) & (pixels[..., 1] <= rows - 0.5 - BORDER_PX)
    ids = np.flatnonzero(inside.all(axis=1))
    return CornerView(ids, corners[ids].reshape(-1, 3), pixels[ids].reshape(-1, 2))


def with_noise(view: CornerView, sigma_px: float, rng: np.random.Generator) -> CornerView:
    """The view with independent Gaussian noise of ``sigma_px`` (px) on each corner coordinate."""
    _checks.instance(view, CornerView, "view", CameraError)
    sigma_px = real_scalar(sigma_px, "sigma_px", error=CameraError, low=0.0, unit="px")
    _checks.generator(rng, "rng", CameraError)
    noisy = view.image_points + rng.normal(0.0, sigma_px, view.image_points.shape) if sigma_px else view.image_points
    return CornerView(view.ids, view.object_points, noisy)


def camera_in_marker(T_table_marker, T_table_camera) -> np.ndarray:
    """Camera pose in the marker frame, ``mT_table · tableT_camera`` (4, 4)."""
    return inverse(check_rigid_transform(T_table_marker, "T_table_marker")) @ check_rigid_transform(
        T_table_camera, "T_table_camera")


def check_image_size(image_size) -> tuple[int, int]:
    """``image_size`` as (columns, rows) positive ints (px), else a :class:`CameraError` (a float size is
    refused, never truncated)."""
    from carmkin.validation import integer

    if isinstance(image_size, (str, bytes, dict)) or not hasattr(image_size, "__len__") or len(image_size) != 2:
        raise CameraError(f"image_size must be (columns, rows) in px, got {image_size!r:.80}")
    columns, rows = (integer(v, f"image_size[{k}]", low=1, error=CameraError, unit="px") for k, v in enumerate(image_size))
    return columns, rows
