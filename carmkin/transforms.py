"""Homogeneous transforms: DH link matrices (scalar and batched), elementary motions, validation.

All transforms are 4x4 homogeneous matrices mapping coordinates of a child frame into its parent frame;
lengths in metres, angles in radians.
"""

from __future__ import annotations

import numpy as np

from carmkin.errors import InvalidPoseError

#: Tolerance of :func:`check_rigid_transform` on ``||R^T R - I||`` and ``|det R - 1|``.
RIGID_TOLERANCE = 1e-9


def dh_matrix(theta, d, a, alpha) -> np.ndarray:
    """Standard DH link transform ``Rz(theta) Tz(d) Tx(a) Rx(alpha)``.

    Arguments broadcast against each other; the result has shape ``broadcast_shape + (4, 4)``.
    """
    theta, d, a, alpha = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (theta, d, a, alpha)))
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    out = np.zeros(theta.shape + (4, 4))
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 2], out[..., 0, 3] = ct, -st * ca, st * sa, a * ct
    out[..., 1, 0], out[..., 1, 1], out[..., 1, 2], out[..., 1, 3] = st, ct * ca, -ct * sa, a * st
    out[..., 2, 1], out[..., 2, 2], out[..., 2, 3] = sa, ca, d
    out[..., 3, 3] = 1.0
    return out


def rot_x(angle: float) -> np.ndarray:
    """4x4 rotation about X by ``angle`` (rad)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def rot_y(angle: float) -> np.ndarray:
    """4x4 rotation about Y by ``angle`` (rad)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def translation(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    """4x4 pure translation (m)."""
    out = np.eye(4)
    out[:3, 3] = (x, y, z)
    return out


def inverse(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms of shape (..., 4, 4), using R^T rather than a general inverse."""
    T = np.asarray(T, dtype=float)
    out = np.zeros_like(T)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def check_rigid_transform(T, name: str = "pose", batch: bool = False) -> np.ndarray:
    """Return ``T`` as a float array after checking it is a rigid transform (or a stack of them).

    Raises :class:`InvalidPoseError` naming ``name`` when the shape is not (4, 4) (or (N, 4, 4) with
    ``batch``), a value is NaN/Inf, the last row is not [0, 0, 0, 1], ``||R^T R - I|| > 1e-9`` or
    ``|det R - 1| > 1e-9``.
    """
    try:
        T = np.asarray(T, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidPoseError(f"{name} must be numeric, got {type(T).__name__}") from exc
    expected = "(N, 4, 4)" if batch else "(4, 4)"
    if T.shape[-2:] != (4, 4) or T.ndim != (3 if batch else 2):
        raise InvalidPoseError(f"{name} must have shape {expected}, got {T.shape}")
    if not np.all(np.isfinite(T)):
        raise InvalidPoseError(f"{name} contains NaN or Inf")
    if np.abs(T[..., 3, :] - (0, 0, 0, 1)).max(initial=0.0) > RIGID_TOLERANCE:
        raise InvalidPoseError(f"{name}: last row must be [0, 0, 0, 1]")
    R = T[..., :3, :3]
    ortho = np.linalg.norm(np.swapaxes(R, -1, -2) @ R - np.eye(3), axis=(-2, -1))
    if ortho.max(initial=0.0) > RIGID_TOLERANCE:
        raise InvalidPoseError(
            f"{name}: rotation is not orthonormal (||R^T R - I|| = {ortho.max():.3g} > {RIGID_TOLERANCE:g})"
        )
    det = np.linalg.det(R)
    if np.abs(det - 1.0).max(initial=0.0) > RIGID_TOLERANCE:
        raise InvalidPoseError(f"{name}: rotation has det = {det.min():.6g}, expected +1 (a reflection?)")
    return T


def rotation_between(a, b) -> np.ndarray:
    """The minimal rotation R (3, 3) taking the direction of ``a`` to that of ``b`` (non-zero 3-vectors).

    Rodrigues' formula with the unit axis ``a × b`` and the angle ``atan2(|a × b|, a·b)``, which stays
    orthonormal to machine precision up to antiparallel vectors (where the axis, and so how exactly a maps
    onto b, is only known to ~1e-16 / |a × b|); for exactly antiparallel ones, the half turn about the axis
    perpendicular to both ``a`` and Y (``a × e_y``; ``a × e_x`` when ``a`` is nearly along Y).
    """
    a = np.asarray(a, dtype=float) / np.linalg.norm(a)
    b = np.asarray(b, dtype=float) / np.linalg.norm(b)
    v, c = np.cross(a, b), float(a @ b)
    s = float(np.linalg.norm(v))
    if s < 1e-15:
        if c > 0:
            return np.eye(3)
        axis = np.cross(a, (0.0, 1.0, 0.0)) if abs(a[1]) < 0.9 else np.cross(a, (1.0, 0.0, 0.0))
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    k = v / s
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)
