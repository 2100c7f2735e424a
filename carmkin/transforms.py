"""Rigid-transform helpers, the one home of them: DH link matrices (scalar and batched), elementary motions,
inverse, pose error, skew, angle wrapping, the minimal rotation between directions, the segment-vs-box slab
test, validation (:func:`check_rigid_transform`) and the projection of a nearly rigid matrix onto SE(3)
(:func:`nearest_rigid`).

All transforms are 4x4 homogeneous matrices mapping coordinates of a child frame into its parent frame;
lengths in metres, angles in radians.
"""

from __future__ import annotations

import math

import numpy as np

from carmkin.errors import CarmkinError, InvalidParameterError, InvalidPoseError
from carmkin.validation import (
    JOINT_VALUE_LIMIT,
    MAGNITUDE_LIMIT,
    RIGID_TOLERANCE,
    real_array,
    real_scalar,
    rigid_transform,
)

# RIGID_TOLERANCE (1e-9, on ||R^T R - I|| and |det R - 1|) is defined once in carmkin.validation.
#: Largest ``||R^T R - I||_F`` (and deviation of the last row from [0, 0, 0, 1]) that :func:`nearest_rigid`
#: accepts as "nearly rigid": a pose typed with 4 decimals has ~2e-4, a float32 pose ~1e-7; beyond 1e-3
#: (an angle error of ~0.06°) the matrix is more likely wrong than rounded, so it is refused, not projected.
NEARLY_RIGID_TOLERANCE = 1e-3
#: Below this |direction component| a segment counts as parallel to a slab in :func:`segment_box_interval`.
PARALLEL_TOLERANCE = 1e-15


def _real(value, name: str, limit: float | None = JOINT_VALUE_LIMIT,
          error: type[CarmkinError] = InvalidParameterError, shape=None) -> np.ndarray:
    """``value`` as a finite float array within ``limit``: a float64 array passes with two vectorized checks
    (these helpers sit on hot paths), anything else through :func:`carmkin.validation.real_array`. The default
    bound is the overflow guard :data:`~carmkin.validation.JOINT_VALUE_LIMIT`, not a physical one: the IK
    evaluates (FK, residual, validity) branches whose joint values near a singular pose reach ~1e6 m."""
    if (type(value) is np.ndarray and value.dtype == np.float64 and (shape is None or value.shape == tuple(shape))
            and (limit is None or np.max(np.abs(value), initial=0.0) <= limit)):  # NaN compares False
        return value
    return real_array(value, name, shape, error=error, limit=limit, finite=limit is not None)


def dh_matrix(theta, d, a, alpha) -> np.ndarray:
    """Standard DH link transform ``Rz(theta) Tz(d) Tx(a) Rx(alpha)``.

    Arguments (finite reals, m and rad) broadcast against each other; the result has shape
    ``broadcast_shape + (4, 4)``. Junk (strings, complex, bool, NaN) or shapes that do not broadcast raise
    :class:`~carmkin.errors.InvalidParameterError`.
    """
    values = [_real(v, k, JOINT_VALUE_LIMIT) for k, v in zip(("theta", "d", "a", "alpha"), (theta, d, a, alpha))]
    try:
        theta, d, a, alpha = np.broadcast_arrays(*values)
    except ValueError:
        raise InvalidParameterError("dh_matrix: theta, d, a and alpha must broadcast, got shapes "
                                    f"{[v.shape for v in values]}") from None
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    out = np.zeros(theta.shape + (4, 4))
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 2], out[..., 0, 3] = ct, -st * ca, st * sa, a * ct
    out[..., 1, 0], out[..., 1, 1], out[..., 1, 2], out[..., 1, 3] = st, ct * ca, -ct * sa, a * st
    out[..., 2, 1], out[..., 2, 2], out[..., 2, 3] = sa, ca, d
    out[..., 3, 3] = 1.0
    return out


def rot_x(angle: float) -> np.ndarray:
    """4x4 rotation about X by ``angle`` (rad)."""
    angle = real_scalar(angle, "angle", limit=JOINT_VALUE_LIMIT, unit="rad")
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def rot_y(angle: float) -> np.ndarray:
    """4x4 rotation about Y by ``angle`` (rad)."""
    angle = real_scalar(angle, "angle", limit=JOINT_VALUE_LIMIT, unit="rad")
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def translation(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    """4x4 pure translation (m)."""
    x, y, z = (real_scalar(v, k, unit="m") for k, v in (("x", x), ("y", y), ("z", z)))
    out = np.eye(4)
    out[:3, 3] = (x, y, z)
    return out


def inverse(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms of shape (..., 4, 4), using R^T rather than a general inverse.

    ``T`` is checked as :func:`check_rigid_transform` does (a non-rigid matrix has no such inverse):
    :class:`~carmkin.errors.InvalidPoseError` otherwise.
    """
    if type(T) is np.ndarray and T.shape == (4, 4):
        T = rigid_transform(T, "T", error=InvalidPoseError)  # one pose: the plain-float fast path
    else:
        T = real_array(T, "T", error=InvalidPoseError, unit="m")
        if T.ndim < 2 or T.shape[-2:] != (4, 4):
            raise InvalidPoseError(f"T must have shape (..., 4, 4), got {T.shape}")
        rigid_transform(T.reshape(-1, 4, 4), "T", error=InvalidPoseError, batch=True)
    out = np.zeros_like(T)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def check_rigid_transform(T, name: str = "pose", batch: bool = False) -> np.ndarray:
    """Return ``T`` as a float array after checking it is a rigid transform (or a stack of them).

    :func:`carmkin.validation.rigid_transform` with :class:`InvalidPoseError`: shape (4, 4) (or (N, 4, 4)
    with ``batch``), finite real entries within :data:`~carmkin.validation.MAGNITUDE_LIMIT`, last row
    [0, 0, 0, 1], ``||R^T R - I|| <= 1e-9`` and ``|det R - 1| <= 1e-9``.
    """
    return rigid_transform(T, name, error=InvalidPoseError, batch=batch)


def rotation_between(a, b, error: type[CarmkinError] = InvalidParameterError) -> np.ndarray:
    """The minimal rotation R (3, 3) taking the direction of ``a`` to that of ``b`` (non-zero 3-vectors).

    Rodrigues' formula with the unit axis ``a × b`` and the angle ``atan2(|a × b|, a·b)``, which stays
    orthonormal to machine precision up to antiparallel vectors (where the axis, and so how exactly a maps
    onto b, is only known to ~1e-16 / |a × b|); for exactly antiparallel ones, the half turn about the axis
    perpendicular to both ``a`` and Y (``a × e_y``; ``a × e_x`` when ``a`` is nearly along Y). A zero,
    non-finite or non-real vector raises ``error``.
    """
    a, b = _unit(a, "a", error), _unit(b, "b", error)
    v, c = np.cross(a, b), float(a @ b)
    s = float(np.linalg.norm(v))
    if s < 1e-15:
        if c > 0:
            return np.eye(3)
        axis = np.cross(a, (0.0, 1.0, 0.0)) if abs(a[1]) < 0.9 else np.cross(a, (1.0, 0.0, 0.0))
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    K = skew(v / s)
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


def _unit(v, name: str, error: type[CarmkinError]) -> np.ndarray:
    """``v`` (3,) divided by its norm, computed after scaling by max|v| (no underflow or overflow)."""
    v = _real(v, name, error=error, shape=(3,))
    big = float(np.max(np.abs(v)))
    if big == 0.0:
        raise error(f"{name} must be a non-zero vector, got {v}")
    v = v / big
    return v / np.linalg.norm(v)


def skew(v) -> np.ndarray:
    """The cross-product matrix ``[v]x`` (3, 3) of a 3-vector, ``[v]x w = v x w``."""
    x, y, z = (float(c) for c in _real(v, "v", shape=(3,)))
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def wrap_angle(angle):
    """Angles (rad) wrapped to (−π, π]; values already there are returned unchanged (so it is idempotent)."""
    if type(angle) is float:  # the scalar IK path calls this per joint: plain floats, no numpy overhead
        if -math.pi < angle <= math.pi:
            return angle
        if math.isinf(angle):
            raise InvalidParameterError(f"angle must be finite (NaN passes through as NaN), got {angle}")
        wrapped = math.pi - (math.pi - angle) % (2.0 * math.pi)
        return wrapped + 2.0 * math.pi if wrapped <= -math.pi else wrapped
    a = real_array(angle, "angle", finite=False, limit=None, unit="rad")
    if np.any(np.isinf(a)):
        raise InvalidParameterError(f"angle must be finite (NaN passes through as NaN), got {angle!r}")
    wrapped = np.pi - np.mod(np.pi - a, 2.0 * np.pi)
    wrapped = np.where(wrapped <= -np.pi, wrapped + 2.0 * np.pi, wrapped)  # mod rounding up to 2π
    out = np.where((a > -np.pi) & (a <= np.pi), a, wrapped)
    return float(out) if out.ndim == 0 else out


def rotation_angle(Ra, Rb):
    """Angle (rad, in [0, π]) of the rotation ``Raᵀ Rb`` for rotations (..., 3, 3): a float for one pair.

    ``atan2(sin, cos)`` with ``sin`` from the skew part and ``cos`` from the trace, accurate over the whole
    range (arccos of the trace alone loses half the digits near 0, the chord's arcsin near π).
    """
    Ra, Rb = _real(Ra, "Ra", limit=1.0 + 1e-6), _real(Rb, "Rb", limit=1.0 + 1e-6)  # rotations: entries in [-1, 1]
    if Ra.ndim < 2 or Ra.shape[-2:] != (3, 3) or Rb.ndim < 2 or Rb.shape[-2:] != (3, 3):
        raise InvalidParameterError(f"Ra and Rb must have shape (..., 3, 3), got {Ra.shape} and {Rb.shape}")
    try:
        M = np.swapaxes(Ra, -1, -2) @ Rb
    except ValueError:
        raise InvalidParameterError(f"Ra and Rb must broadcast, got {Ra.shape} and {Rb.shape}") from None
    vee = np.stack((M[..., 2, 1] - M[..., 1, 2], M[..., 0, 2] - M[..., 2, 0], M[..., 1, 0] - M[..., 0, 1]), -1)
    angle = np.arctan2(0.5 * np.linalg.norm(vee, axis=-1), 0.5 * (np.trace(M, axis1=-2, axis2=-1) - 1.0))
    return float(angle) if angle.ndim == 0 else angle


def pose_error(Ta, Tb):
    """``(position error m, rotation angle rad)`` between poses (..., 4, 4): ``‖pa − pb‖`` and the angle of
    ``Raᵀ Rb`` (:func:`rotation_angle`). Floats for one pair of (4, 4), arrays (...) for stacks; symmetric.

    Junk types and shapes raise :class:`~carmkin.errors.InvalidPoseError`; magnitudes are not bounded and a
    NaN/inf pose gives a NaN/inf error (never a finite number): the IK takes the residual of branches that
    ran off to huge values or have no solution."""
    # types and shapes only: the IK takes the residual of branches that may have run off to huge values
    Ta, Tb = _real(Ta, "Ta", None, InvalidPoseError), _real(Tb, "Tb", None, InvalidPoseError)
    if Ta.ndim < 2 or Ta.shape[-2:] != (4, 4) or Tb.ndim < 2 or Tb.shape[-2:] != (4, 4):
        raise InvalidPoseError(f"Ta and Tb must have shape (..., 4, 4), got {Ta.shape} and {Tb.shape}")
    dp = np.linalg.norm(Ta[..., :3, 3] - Tb[..., :3, 3], axis=-1)
    angle = rotation_angle(Ta[..., :3, :3], Tb[..., :3, :3])
    return (float(dp), angle) if np.ndim(dp) == 0 else (dp, angle)


def pose_residual(T, T_target) -> float:
    """max(position error (m), rotation angle (rad)) between two rigid poses (4, 4) (:func:`pose_error`);
    a non-rigid one raises :class:`~carmkin.errors.InvalidPoseError` naming it (``T`` or ``T_target``)."""
    return max(pose_error(check_rigid_transform(T, "T"), check_rigid_transform(T_target, "T_target")))


def segment_box_interval(p0, d, center, size, t_min: float = 0.0, t_max: float = 1.0):
    """``(t_enter, t_exit)`` of the part of ``p0 + t d`` (t in [t_min, t_max]) inside the axis-aligned box of
    ``center`` and full ``size`` (slab test; same units as the points), or ``None`` when it misses the box.

    ``t_min = -inf``/``t_max = inf`` give the infinite line. A component of ``d`` below
    :data:`PARALLEL_TOLERANCE` counts as parallel to that slab (inside it or missing the box).
    """
    p0, d = _real(p0, "p0", shape=(3,)), _real(d, "d", shape=(3,))
    center, half = _real(center, "center", shape=(3,)), 0.5 * _real(size, "size", shape=(3,))
    if np.any(half < 0):
        raise InvalidParameterError(f"size must be >= 0 (a box's full size), got {2 * half}")
    for name, value in (("t_min", t_min), ("t_max", t_max)):
        if not (isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, (bool, np.bool_))
                and not math.isnan(value)):
            raise InvalidParameterError(f"{name} must be a real number (±inf allowed), got {value!r}")
    lo, hi = center - half, center + half
    t0, t1 = t_min, t_max
    for k in range(3):
        if abs(d[k]) < PARALLEL_TOLERANCE:
            if p0[k] < lo[k] or p0[k] > hi[k]:
                return None
            continue
        a, b = (lo[k] - p0[k]) / d[k], (hi[k] - p0[k]) / d[k]
        t0, t1 = max(t0, min(a, b)), min(t1, max(a, b))
        if t0 > t1:
            return None
    return float(t0), float(t1)


def segment_hits_box(p0, p1, center, size) -> bool:
    """True when the segment p0→p1 meets the axis-aligned box of ``center`` and full ``size`` (slab test)."""
    p0, p1 = _real(p0, "p0", shape=(3,)), _real(p1, "p1", shape=(3,))
    return segment_box_interval(p0, p1 - p0, center, size) is not None


def nearest_rigid(T, name: str = "pose"):
    """The rigid transform nearest to a nearly rigid ``T`` (4, 4) or (N, 4, 4), and how far it moved it.

    The rotation block is replaced by ``U diag(1, 1, det(U Vᵀ)) Vᵀ`` from its SVD ``U S Vᵀ`` (the nearest
    rotation in the Frobenius norm, det +1), the last row by [0, 0, 0, 1]; the translation is kept.
    Returns ``(T_rigid, correction)`` with ``correction = ‖T_rigid − T‖_F`` (dimensionless; a float, or (N,)).
    Raises :class:`InvalidPoseError` naming ``name`` for a bad shape, NaN/Inf, a reflection, or a matrix
    farther from rigid than :data:`NEARLY_RIGID_TOLERANCE` (``‖RᵀR − I‖_F`` or the last row).
    """
    T = real_array(T, name, error=InvalidPoseError, unit="m")
    if T.ndim not in (2, 3) or T.shape[-2:] != (4, 4):
        raise InvalidPoseError(f"{name} must have shape (4, 4) or (N, 4, 4), got {T.shape}")
    R = T[..., :3, :3]
    ortho = np.linalg.norm(np.swapaxes(R, -1, -2) @ R - np.eye(3), axis=(-2, -1))
    last = np.abs(T[..., 3, :] - (0.0, 0.0, 0.0, 1.0)).max(axis=-1)
    worst = float(np.maximum(ortho, last).max(initial=0.0))
    if worst > NEARLY_RIGID_TOLERANCE:
        raise InvalidPoseError(
            f"{name} is not nearly rigid: ||R^T R - I|| = {float(ortho.max(initial=0.0)):.3g}, last row off by "
            f"{float(last.max(initial=0.0)):.3g} (at most {NEARLY_RIGID_TOLERANCE:g} is projected onto a rotation)")
    if np.any(np.linalg.det(R) <= 0.0):
        raise InvalidPoseError(f"{name}: rotation block has det <= 0 (a reflection), expected a rotation")
    U, _, Vt = np.linalg.svd(R)
    D = np.ones(R.shape[:-1])
    D[..., 2] = np.sign(np.linalg.det(U @ Vt))
    out = T.copy()
    out[..., :3, :3] = (U * D[..., None, :]) @ Vt
    out[..., 3, :] = (0.0, 0.0, 0.0, 1.0)
    correction = np.linalg.norm(out - T, axis=(-2, -1))
    return out, (float(correction) if correction.ndim == 0 else correction)
