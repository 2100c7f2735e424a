"""Synthetic camera images of the pattern at any pose: OpenCV warp, blur, noise.

The board is drawn once by ``GridBoard.generateImage`` as a texture at :data:`TEXTURE_PX_PER_MM`; an image
is its perspective warp (``cv2.warpPerspective`` with the board-plane homography ``K [r1 r2 t]`` of eq. 3.3)
at :data:`SUPERSAMPLING` times the image resolution, averaged down (``cv2.resize``, ``INTER_AREA``: the
anti-aliasing of a pixel's area), blurred by a Gaussian of ``blur_px`` (optics) and given Gaussian gray-level
noise of ``noise_gray`` (sensor). Pixel convention: OpenCV's, pixel centres at integer coordinates. Outside
the board the table's underside shows as a uniform gray.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from carmkin.extras import require
from carmkin.transforms import check_rigid_transform, inverse
from carmkin.validation import real_scalar

from . import _checks
from .camera import CameraError, check_image_size, check_intrinsics
from .pattern import MarkerBoard

#: Resolution of the board texture (px per mm): ~1:1 with the image at the working distance (~8 px/mm).
TEXTURE_PX_PER_MM = 8
#: The warp is done at this multiple of the image resolution, then averaged down.
SUPERSAMPLING = 2
#: Gray level of the table's underside around the board.
BACKGROUND_GRAY = 110


@lru_cache(maxsize=4)
def board_texture(board: MarkerBoard) -> tuple[np.ndarray, np.ndarray]:
    """The board image (uint8) and the map ``S`` (3, 3) from board-plane metres to its pixels."""
    scale = TEXTURE_PX_PER_MM * 1000.0
    width, height = board.size
    texture = board.cv2_board.generateImage((round(width * scale), round(height * scale)), marginSize=0, borderBits=1)
    # generateImage fills pixel i with [i, i + 1) of the board: pixel centres at (x·scale − 0.5)
    S = np.array([[scale, 0.0, -0.5], [0.0, scale, -0.5], [0.0, 0.0, 1.0]])
    texture.setflags(write=False)
    return texture, S


def board_homography(K, T_marker_camera) -> np.ndarray:
    """``H = K [r1 r2 t]`` (3, 3): board-plane points (X, Y, 1) in metres to pixels, for the camera pose
    ``T_marker_camera`` (camera-to-marker transform)."""
    T = inverse(check_rigid_transform(T_marker_camera, "T_marker_camera"))  # marker → camera
    return check_intrinsics(K) @ np.column_stack((T[:3, 0], T[:3, 1], T[:3, 3]))


def render(board: MarkerBoard, K, image_size, T_marker_camera, blur_px: float = 0.8, noise_gray: float = 2.0,
           rng: np.random.Generator | None = None) -> np.ndarray:
    """Grayscale image (rows, columns) uint8 of ``board`` seen by the camera at ``T_marker_camera``.

    ``image_size`` = (columns, rows) px; ``blur_px``: σ of the Gaussian blur (px, 0 = none);
    ``noise_gray``: σ of the additive noise (gray levels, 0 = none; needs ``rng``).
    """
    cv2 = require("cv2", "reposition")

    _checks.instance(board, MarkerBoard, "board", CameraError)
    columns, rows = check_image_size(image_size)
    blur_px = real_scalar(blur_px, "blur_px", error=CameraError, low=0.0, unit="px")
    noise_gray = real_scalar(noise_gray, "noise_gray", error=CameraError, low=0.0, unit="gray levels")
    if rng is not None:
        _checks.generator(rng, "rng", CameraError)
    if noise_gray > 0 and rng is None:
        raise CameraError("noise_gray > 0 needs an rng (numpy Generator)")
    texture, S = board_texture(board)
    n = SUPERSAMPLING
    # supersampled pixel U of image pixel u: U = n u + (n − 1) / 2 (same pixel-centre convention)
    A = np.array([[n, 0.0, (n - 1) / 2], [0.0, n, (n - 1) / 2], [0.0, 0.0, 1.0]])
    M = A @ board_homography(K, T_marker_camera) @ np.linalg.inv(S)
    big = cv2.warpPerspective(texture, M, (columns * n, rows * n), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=BACKGROUND_GRAY)
    image = cv2.resize(big, (columns, rows), interpolation=cv2.INTER_AREA).astype(np.float32)
    if blur_px > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur_px)
    if noise_gray > 0:
        image += rng.normal(0.0, noise_gray, image.shape).astype(np.float32)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)
