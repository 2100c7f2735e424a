"""Degenerate-but-valid generators of outside geometry for the fuzz (docs/fuzz.md).

Rotations include the identity, half turns and angles of 1e-12 rad; translations and depths span 1 µm to
10 m (tiny and huge but physical); cameras look at fronto-parallel, collinear and image-edge points.
"""

from __future__ import annotations

import numpy as np

#: Lengths (m) the generators draw from: 1 µm to 10 m, the physical range (validation.MIN/MAX_DISTANCE).
SCALES = (1e-6, 1e-3, 0.05, 1.0, 10.0)


def rotation(rng: np.random.Generator) -> np.ndarray:
    """A rotation: random (QR of a Gaussian), or a degenerate one (identity, a half turn, 1e-12 rad)."""
    k = rng.integers(0, 6)
    if k == 0:
        return np.eye(3)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    if k in (1, 2):
        angle = np.pi if k == 1 else 1e-12
        K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q * np.sign(np.diag(R))
    return Q if np.linalg.det(Q) > 0 else -Q


def pose(rng: np.random.Generator, scale: float | None = None) -> np.ndarray:
    """A rigid transform with a translation of length ``scale`` (default: one of :data:`SCALES`)."""
    T = np.eye(4)
    T[:3, :3] = rotation(rng)
    s = rng.choice(SCALES) if scale is None else scale
    T[:3, 3] = rng.normal(size=3) * s
    return T


def intrinsics(rng: np.random.Generator) -> np.ndarray:
    """A pinhole K (px): focal lengths 10 px to 1e5 px, principal point inside a 2000-px image, no skew."""
    fx = 10 ** rng.uniform(1, 5)
    fy = fx * rng.choice([1.0, rng.uniform(0.5, 2.0)])
    return np.array([[fx, 0.0, rng.uniform(0, 2000)], [0.0, fy, rng.uniform(0, 2000)], [0.0, 0.0, 1.0]])


def points_in_front(rng: np.random.Generator, T: np.ndarray, n: int | None = None) -> np.ndarray:
    """World points (n, 3) at positive depth from the camera at pose T: random, collinear or on a plane."""
    n = int(rng.integers(1, 8)) if n is None else n
    depth = rng.choice([1e-3, 0.1, 1.0, 10.0]) * rng.uniform(0.5, 2.0, n)
    lateral = rng.normal(size=(n, 2)) * depth[:, None] * rng.choice([0.0, 1e-6, 0.3])
    k = rng.integers(0, 3)
    if k == 1:  # collinear in the camera frame
        lateral = np.outer(np.linspace(-1, 1, n), rng.normal(size=2)) * 0.1
    Xc = np.column_stack((lateral, depth))
    return Xc @ T[:3, :3].T + T[:3, 3]


def unit(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def edge_pixels(rng: np.random.Generator, size: tuple[int, int], n: int) -> np.ndarray:
    """Pixels (n, 2) at the image corners and edges (−0.5 … size − 0.5) and inside."""
    w, h = size
    choices = np.array([[-0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5], [w - 0.5, -0.5], [0, 0], [w / 2, h / 2]])
    m = rng.uniform((-0.5, -0.5), (w - 0.5, h - 0.5), size=(n, 2))
    pick = rng.random(n) < 0.5
    m[pick] = choices[rng.integers(0, len(choices), pick.sum())]
    return m


def close(a, b, rtol: float = 1e-7, atol: float = 1e-9) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(np.all(np.isfinite(a))) and bool(np.allclose(a, b, rtol=rtol, atol=atol))


def is_rotation(R, tol: float = 1e-9) -> bool:
    R = np.asarray(R, dtype=float)
    return R.shape == (3, 3) and np.allclose(R.T @ R, np.eye(3), atol=tol) and abs(np.linalg.det(R) - 1) < tol
