"""Degenerate-but-valid boards for pose estimation, with exact corners (issue 19).

Each case is a board (marker-frame points, m), a camera pose (4, 4, camera-to-marker, every point in front)
and the intrinsics, from one of four kinds:

- ``fronto``: a regular grid seen exactly fronto-parallel (optical axis along the board's normal), at an
  in-plane rotation drawn from 0°, 90°, 180°, 270° or uniform (IPPE's candidates are degenerate there);
- ``mirrored``: the same seen from the other side of the board (camera at marker Z > 0: a board mounted the
  other way round);
- ``collinear``: two rows of points whose spacing is a tiny fraction (10^-1.5 … 1e-6) of their length, seen
  fronto-parallel or tilted;
- ``four``: four points, a 2 × 2 grid or a random quadrilateral, fronto-parallel or tilted;

with distances 0.1–3 m, pitches 5–50 mm, the board centre up to a third of the field of view off the axis,
and the intrinsics of the Siremobile preset (X-ray, ~13° field of view) or a wide camera (~56°).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

import carmkin
from carmkin.reposition import camera

KINDS = ("fronto", "mirrored", "collinear", "four")
XRAY_K = carmkin.load_preset("siremobile-iso-c3d").carm.intrinsics()
WIDE_K = np.array([[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]])


def _grid(columns: int, rows: int, pitch: float) -> np.ndarray:
    x, y = np.meshgrid(np.arange(columns) * pitch, np.arange(rows) * pitch)
    return np.column_stack((x.ravel(), y.ravel(), np.zeros(x.size)))


def _in_plane_angle(rng) -> float:
    return float(rng.choice([0.0, math.pi / 2, math.pi, 3 * math.pi / 2, rng.uniform(-math.pi, math.pi)]))


def case(kind: str, rng: np.random.Generator):
    """(object_points (N, 3) m, image_points (N, 2) px exact, K, T_true (4, 4)) of one board of ``kind``."""
    K = XRAY_K if rng.random() < 0.5 else WIDE_K
    pitch = rng.uniform(0.005, 0.05)
    tilt = np.eye(3)
    if kind in ("fronto", "mirrored"):
        X = _grid(*rng.integers(2, 9, 2), pitch)
    elif kind == "collinear":
        n = int(rng.integers(3, 9))
        length = (n - 1) * pitch
        spacing = length * 10.0 ** -rng.uniform(1.5, 6)
        X = np.vstack((_grid(n, 1, pitch), _grid(n, 1, pitch) + (0.0, spacing, 0.0)))
    else:
        X = _grid(2, 2, pitch) if rng.random() < 0.5 else np.column_stack((rng.uniform(0, 4 * pitch, (4, 2)), np.zeros(4)))
    if kind in ("collinear", "four") and rng.random() < 0.5:
        tilt = Rotation.from_rotvec(rng.normal(size=3) * 0.4).as_matrix()
    R = Rotation.from_euler("z", _in_plane_angle(rng)).as_matrix()
    if kind == "mirrored" or (kind != "fronto" and rng.random() < 0.5):
        R = R @ np.diag([1.0, -1.0, -1.0])  # looking at the board's other side
    R = tilt @ R
    distance = rng.uniform(0.1, 3.0)
    half_fov = math.atan(K[0, 2] / K[0, 0])
    off_axis = rng.uniform(-1, 1, 2) * distance * math.tan(half_fov) / 3
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = X.mean(axis=0) - R @ np.array([off_axis[0], off_axis[1], distance])
    pixels, depth = camera.project_points(K, T, X)
    assert np.all(depth > 0)
    return X, pixels, K, T
