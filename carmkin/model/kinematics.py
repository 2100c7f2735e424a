"""Closed-form forward kinematics of the 6-DOF C-arm + table chain (§4.3.1, Table 4.1, eq. 4.2–4.5).

The DH rows are not printed in the dissertation (Fig. 4.1/4.2 are missing from the text); they were
derived from the explicit ``0T6`` of Table 4.1 and are proven against it in ``tests/test_dissertation.py``.
Standard DH, ``A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``; the variable of each row is added to its
theta (revolute) or d (prismatic) offset:

===  ==================  ===============  ================  =============  =========
row  joint               theta            d                 a              alpha
===  ==================  ===============  ================  =============  =========
0    table_translation   gamma2           d0 + D2           D1             gamma1
1    vertical            gamma3           d1 + D3           0              0
2    wigwag              theta2           0                 0              -pi/2
3    horizontal          0                d3 + l1 - a2      0              0
4    angular             theta4 - pi/2    0                 a1             pi/2
5    orbital             theta5           0                 -(l2 + a1)     0
===  ==================  ===============  ================  =============  =========

``6T_xray = Tran_y(a2) Rx(180°) Ry(90°)`` (eq. 4.2): the principal axis Z_xray is X6.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from carmkin.errors import InvalidConfigurationError, InvalidParameterError
from carmkin.transforms import dh_matrix, rot_x, rot_y, translation
from carmkin.validation import JOINT_VALUE_LIMIT, real_array

from .params import CARM_JOINT_NAMES, JOINT_NAMES, PRISMATIC, CArmGeometry, TableSetup


class DHRow(NamedTuple):
    """Constant part of one DH row; the joint variable adds to ``theta`` (revolute) or ``d`` (prismatic)."""

    joint: str
    prismatic: bool
    theta: float
    d: float
    a: float
    alpha: float


def carm_rows(carm: CArmGeometry) -> tuple[DHRow, ...]:
    """DH rows of the 5-DOF C-arm alone, from its base frame (vertical axis, vertical joint at zero)."""
    constants = (
        (0.0, 0.0, 0.0, 0.0),
        (0.0, 0.0, 0.0, -math.pi / 2),
        (0.0, carm.arm_length, 0.0, 0.0),
        (-math.pi / 2, 0.0, carm.a1, math.pi / 2),
        (0.0, 0.0, -carm.source_to_orbital_axis, 0.0),
    )
    return tuple(DHRow(name, prism, *row) for name, prism, row in zip(CARM_JOINT_NAMES, PRISMATIC[1:], constants))


def dh_table(carm: CArmGeometry, setup: TableSetup) -> tuple[DHRow, ...]:
    """The six DH rows of the C-arm + table chain (see the module docstring)."""
    table = DHRow(JOINT_NAMES[0], True, setup.gamma2, setup.D2, setup.D1, setup.gamma1)
    vertical = DHRow(JOINT_NAMES[1], True, setup.gamma3, setup.D3, 0.0, 0.0)
    return (table, vertical) + carm_rows(carm)[1:]


def xray_in_flange(carm: CArmGeometry) -> np.ndarray:
    """``6T_xray`` of eq. 4.2: pose of the X-ray source frame in the end-effector frame 6."""
    return translation(y=carm.a2) @ rot_x(math.pi) @ rot_y(math.pi / 2)


#: Tolerance (dimensionless) on the unit length and orthogonality of the axes given to
#: :func:`table_pose_from_xray`.
AXIS_TOLERANCE = 1e-9


def table_pose_from_xray(carm: CArmGeometry, origin, x_axis, z_axis) -> np.ndarray:
    """Table pose (4, 4) in the C-arm base frame from its pose in the X-ray source frame at zero joints (eq. 4.3).

    ``origin`` (m), ``x_axis`` and ``z_axis`` are the table frame's origin and X0/Z0 axes expressed in the
    source frame; the axes must be orthonormal (to :data:`AXIS_TOLERANCE`), else
    :class:`~carmkin.errors.InvalidParameterError`. Feed the result to :meth:`TableSetup.from_pose`.
    """
    x_axis, z_axis = np.asarray(x_axis, float), np.asarray(z_axis, float)
    tol = AXIS_TOLERANCE
    if abs(np.linalg.norm(x_axis) - 1) > tol or abs(np.linalg.norm(z_axis) - 1) > tol or abs(x_axis @ z_axis) > tol:
        raise InvalidParameterError(
            "setup: table_x_axis_in_xray and table_z_axis_in_xray (x_axis, z_axis) must be orthonormal, got "
            f"{x_axis.tolist()} and {z_axis.tolist()}")
    T_xray_table = np.eye(4)
    T_xray_table[:3, :3] = np.column_stack((x_axis, np.cross(z_axis, x_axis), z_axis))
    T_xray_table[:3, 3] = origin
    T_base_xray = forward(carm_rows(carm), xray_in_flange(carm), np.zeros(5))
    return T_base_xray @ T_xray_table


def check_configuration(q, n_joints: int = 6, name: str = "q") -> np.ndarray:
    """Return ``q`` as a float array of shape (n,) or (N, n); raise a typed error otherwise.

    The one joint-vector check of the library: :class:`~carmkin.errors.InvalidConfigurationError` naming
    ``name`` for a non-numeric, boolean or complex value, a wrong shape, NaN, Inf or a magnitude beyond
    :data:`~carmkin.validation.JOINT_VALUE_LIMIT` (see :func:`carmkin.validation.real_array`).
    """
    q = real_array(q, name, error=InvalidConfigurationError, limit=JOINT_VALUE_LIMIT, unit="m, rad")
    if q.ndim not in (1, 2) or q.shape[-1] != n_joints:
        raise InvalidConfigurationError(f"{name} must have shape ({n_joints},) or (N, {n_joints}), got {q.shape}")
    return q


def dh_frames(rows: tuple[DHRow, ...], q) -> np.ndarray:
    """Poses ``0T1 ... 0T6`` of the DH frames in the table frame: shape (..., 6, 4, 4) for q of (..., 6)."""
    q = check_configuration(q, len(rows))
    out = np.empty(q.shape[:-1] + (len(rows), 4, 4))
    T = np.broadcast_to(np.eye(4), q.shape[:-1] + (4, 4))
    for i, row in enumerate(rows):
        theta = row.theta + (0.0 if row.prismatic else q[..., i])
        d = row.d + (q[..., i] if row.prismatic else 0.0)
        T = T @ dh_matrix(theta, d, row.a, row.alpha)
        out[..., i, :, :] = T
    return out


def forward(rows: tuple[DHRow, ...], T_flange_tool: np.ndarray, q) -> np.ndarray:
    """Pose of a tool frame in the table frame: ``0T6(q) · 6T_tool``; (4, 4) for q (6,), (N, 4, 4) for (N, 6)."""
    return dh_frames(rows, q)[..., -1, :, :] @ T_flange_tool


class ClosedFormFK:
    """Fast closed-form ``0T_xray(q)`` of the 6-DOF chain, expanded from the DH rows above.

    ``0T_xray = Tz(d0) · K · Tz(d1) · 2T_xray(θ2, d3, θ4, θ5)`` where ``K = A0(0) A1(0)`` is constant (the
    table joint translates along Z0, the vertical joint along Z1) and, with c_i = cos θi, s_i = sin θi,
    L = l2 + a1, M = l1 − a2, the C-arm part in frame 2 is (derived symbolically from rows 2–5 and eq. 4.2):

    - X_xray = (−c2 c4, −s2 c4, s4)
    - Y_xray = (c2 s4 s5 + s2 c5, s2 s4 s5 − c2 c5, c4 s5)
    - Z_xray = (c2 s4 c5 − s2 s5, s2 s4 c5 + c2 s5, c4 c5)
    - p = (M + d3)·(−s2, c2, 0) + a1·(c2 s4, s2 s4, c4) − L·Z_xray − a2·Y_xray

    The general DH product (:func:`forward`) stays the reference; tests hold both equal to 1e-15.
    Written by hand because the generic numpy product costs ~50 µs per pose in Python overhead.
    """

    def __init__(self, carm: CArmGeometry, setup: TableSetup) -> None:
        rows = dh_table(carm, setup)
        K = dh_matrix(rows[0].theta, rows[0].d, rows[0].a, rows[0].alpha) @ dh_matrix(
            rows[1].theta, rows[1].d, rows[1].a, rows[1].alpha
        )
        self.R = K[:3, :3].copy()
        self.p = K[:3, 3].copy()
        self.L = carm.source_to_orbital_axis
        self.M = carm.arm_length
        self.a1, self.a2 = carm.a1, carm.a2
        self._R_rows = tuple(tuple(float(v) for v in r) for r in self.R)
        self._p = tuple(float(v) for v in self.p)

    def rows(self, d0: float, d1: float, t2: float, d3: float, t4: float, t5: float) -> list[float]:
        """``0T_xray`` row-major as 16 Python floats (its last row 0, 0, 0, 1) for one configuration on plain
        floats (no numpy: the scalar path costs a few µs); no validation (callers validate)."""
        c2, s2, c4, s4, c5, s5 = math.cos(t2), math.sin(t2), math.cos(t4), math.sin(t4), math.cos(t5), math.sin(t5)
        c2s4, s2s4 = c2 * s4, s2 * s4
        x0, x1, x2 = -c2 * c4, -s2 * c4, s4
        y0, y1, y2 = c2s4 * s5 + s2 * c5, s2s4 * s5 - c2 * c5, c4 * s5
        z0, z1, z2 = c2s4 * c5 - s2 * s5, s2s4 * c5 + c2 * s5, c4 * c5
        m, a1, L, a2 = self.M + d3, self.a1, self.L, self.a2
        p0 = a1 * c2s4 - m * s2 - (L * z0 + a2 * y0)
        p1 = a1 * s2s4 + m * c2 - (L * z1 + a2 * y1)
        p2 = a1 * c4 + d1 - (L * z2 + a2 * y2)
        (ra, rb, rc), (rd, re, rf), (rg, rh, ri) = self._R_rows
        px, py, pz = self._p
        return [ra * x0 + rb * x1 + rc * x2, ra * y0 + rb * y1 + rc * y2, ra * z0 + rb * z1 + rc * z2,
                ra * p0 + rb * p1 + rc * p2 + px,
                rd * x0 + re * x1 + rf * x2, rd * y0 + re * y1 + rf * y2, rd * z0 + re * z1 + rf * z2,
                rd * p0 + re * p1 + rf * p2 + py,
                rg * x0 + rh * x1 + ri * x2, rg * y0 + rh * y1 + ri * y2, rg * z0 + rh * z1 + ri * z2,
                rg * p0 + rh * p1 + ri * p2 + pz + d0, 0.0, 0.0, 0.0, 1.0]

    def pose(self, q) -> np.ndarray:
        """``0T_xray`` (4, 4) for one configuration (6,), no validation (callers validate)."""
        return np.array(self.rows(*(q.tolist() if isinstance(q, np.ndarray) else q))).reshape(4, 4)

    def poses(self, q: np.ndarray) -> np.ndarray:
        """``0T_xray`` (N, 4, 4) for configurations (N, 6), vectorized."""
        d0, d1, d3 = q[:, 0], q[:, 1], q[:, 3]
        angles = np.ascontiguousarray(q[:, (2, 4, 5)].T)  # one contiguous sin/cos pass is ~2x faster
        (c2, c4, c5), (s2, s4, s5) = np.cos(angles), np.sin(angles)
        local = np.empty((len(q), 4, 3))  # rows X, Y, Z, p of the source frame, in frame 2
        X, Y, Z, p = local[:, 0], local[:, 1], local[:, 2], local[:, 3]
        c2s4, s2s4 = c2 * s4, s2 * s4
        X[:, 0], X[:, 1], X[:, 2] = -c2 * c4, -s2 * c4, s4
        Y[:, 0], Y[:, 1], Y[:, 2] = c2s4 * s5 + s2 * c5, s2s4 * s5 - c2 * c5, c4 * s5
        Z[:, 0], Z[:, 1], Z[:, 2] = c2s4 * c5 - s2 * s5, s2s4 * c5 + c2 * s5, c4 * c5
        m = self.M + d3
        p[:, 0], p[:, 1], p[:, 2] = self.a1 * c2s4 - m * s2, self.a1 * s2s4 + m * c2, self.a1 * c4 + d1
        p -= self.L * Z + self.a2 * Y
        out = np.empty((len(q), 4, 4))
        # out[:, i, :] = sum_j R[i, j] local[:, :, j]; explicit sums, as a (4N x 3)(3 x 3) BLAS product is
        # slow with the OpenBLAS settings of some machines.
        for i in range(3):
            out[:, i, :] = self.R[i, 0] * local[:, :, 0] + self.R[i, 1] * local[:, :, 1] + self.R[i, 2] * local[:, :, 2]
        out[:, :3, 3] += self.p
        out[:, 2, 3] += d0
        out[:, 3] = (0.0, 0.0, 0.0, 1.0)
        return out
