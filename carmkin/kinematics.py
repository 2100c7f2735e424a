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

from .errors import InvalidConfigurationError
from .geometry import JOINT_NAMES, PRISMATIC, CArmGeometry, TableSetup
from .transforms import dh_matrix, rot_x, rot_y, translation


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
    l1, l2, a1, a2 = carm.length_offset, carm.orbital_offset, carm.a1, carm.a2
    constants = (
        (0.0, 0.0, 0.0, 0.0),
        (0.0, 0.0, 0.0, -math.pi / 2),
        (0.0, l1 - a2, 0.0, 0.0),
        (-math.pi / 2, 0.0, a1, math.pi / 2),
        (0.0, 0.0, -(l2 + a1), 0.0),
    )
    return tuple(DHRow(name, prism, *row) for name, prism, row in zip(JOINT_NAMES[1:], PRISMATIC[1:], constants))


def dh_table(carm: CArmGeometry, setup: TableSetup) -> tuple[DHRow, ...]:
    """The six DH rows of the C-arm + table chain (see the module docstring)."""
    table = DHRow(JOINT_NAMES[0], True, setup.gamma2, setup.D2, setup.D1, setup.gamma1)
    vertical = DHRow(JOINT_NAMES[1], True, setup.gamma3, setup.D3, 0.0, 0.0)
    return (table, vertical) + carm_rows(carm)[1:]


def xray_in_flange(carm: CArmGeometry) -> np.ndarray:
    """``6T_xray`` of eq. 4.2: pose of the X-ray source frame in the end-effector frame 6."""
    return translation(y=carm.a2) @ rot_x(math.pi) @ rot_y(math.pi / 2)


def check_configuration(q, n_joints: int = 6, name: str = "q") -> np.ndarray:
    """Return ``q`` as a float array of shape (n,) or (N, n); raise a typed error otherwise."""
    try:
        q = np.asarray(q, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidConfigurationError(f"{name} must be numeric, got {type(q).__name__}") from exc
    if q.ndim not in (1, 2) or q.shape[-1] != n_joints:
        raise InvalidConfigurationError(f"{name} must have shape ({n_joints},) or (N, {n_joints}), got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise InvalidConfigurationError(f"{name} contains NaN or Inf")
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
