"""Extra degrees of freedom of a motorized operating table (dissertation §4.7), beyond the paper's d0.

A table joint moves the table top relative to the floor: ``T_floor_top(q) = e^{ξ1 q1} ··· e^{ξk qk}``
with twists ξ defined at rest in the table frame 0 (which coincides with the floor-fixed frame when every
table joint is zero). The order from the floor is :data:`CHAIN_ORDER`; the paper's table translation d0
(``table_translation``) comes last, on top, and keeps its convention (displacement of the C-arm relative
to the table along Z0). The model is rooted at the table top, so the chain runs backwards through the
inverse motions, ``T_top_floor = Tz(d0) e^{-ξk qk} ··· e^{-ξ1 q1}``, and the joint vector is ordered from
the top: ``[table_translation, table_tilt, table_trendelenburg, table_lateral, table_height,
table_rotation, vertical, wigwag, horizontal, angular, orbital]`` restricted to the joints present.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from carmkin.errors import InvalidParameterError
from carmkin.transforms import skew

from .params import JointRange

#: Extra table joints in their order from the floor up (the paper's longitudinal d0 sits above them all).
CHAIN_ORDER = ("table_rotation", "table_height", "table_lateral", "table_trendelenburg", "table_tilt")
#: Prismatic (True) or revolute (False), and the rest-frame axis: "up", "x" (X0, lateral) or "z" (Z0).
KINDS = {
    "table_rotation": (False, "up"),
    "table_height": (True, "up"),
    "table_lateral": (True, "x"),
    "table_trendelenburg": (False, "x"),
    "table_tilt": (False, "z"),
}


@dataclass(frozen=True)
class TableJoint:
    """One extra table joint: motion of the table top relative to the floor, in the rest table frame 0.

    Attributes:
        name: one of :data:`CHAIN_ORDER`.
        prismatic: translation along ``axis`` (m) if True, rotation about it (rad) otherwise.
        axis: unit direction in frame 0 at rest. point: a point of a rotation axis, frame 0 (m).
        range: joint range (m or rad).
    """

    name: str
    prismatic: bool
    axis: tuple[float, float, float]
    point: tuple[float, float, float]
    range: JointRange

    def __post_init__(self) -> None:
        axis = np.asarray(self.axis, dtype=float)
        if axis.shape != (3,) or not np.all(np.isfinite(axis)) or abs(np.linalg.norm(axis) - 1.0) > 1e-9:
            raise InvalidParameterError(f"{self.name}: axis must be a unit 3-vector, got {self.axis}")
        point = np.asarray(self.point, dtype=float)
        if point.shape != (3,) or not np.all(np.isfinite(point)):
            raise InvalidParameterError(f"{self.name}: point must be a finite 3-vector, got {self.point}")
        object.__setattr__(self, "axis", tuple(float(v) for v in axis))
        object.__setattr__(self, "point", tuple(float(v) for v in point))

    def inverse_motion(self, value: float) -> np.ndarray:
        """``e^{-ξ q}`` (4, 4): the floor seen from the table top after this joint moved by ``value``."""
        u, c = np.asarray(self.axis), np.asarray(self.point)
        out = np.eye(4)
        if self.prismatic:
            out[:3, 3] = -value * u
            return out
        K = skew(u)
        R = np.eye(3) - math.sin(value) * K + (1 - math.cos(value)) * K @ K  # rotation by -value about u
        out[:3, :3] = R
        out[:3, 3] = c - R @ c
        return out

    @cached_property
    def _coordinate_axis(self) -> tuple[int, int, float, float, float] | None:
        """``(4 j, 4 k, point_j, point_k, σ)`` when the axis is exactly σ·e_i, (i, j, k) a cyclic order of
        0, 1, 2 (the rows j and k turn, offsets in a row-major 4x4), else None."""
        for i in range(3):
            j, k = (i + 1) % 3, (i + 2) % 3
            if abs(self.axis[i]) == 1.0 and self.axis[j] == 0.0 and self.axis[k] == 0.0:
                return 4 * j, 4 * k, self.point[j], self.point[k], self.axis[i]
        return None  # (a unit axis may have a component that rounds to ±1 beside tiny others: not this case)

    def apply_inverse_motion(self, rows: list[float], value: float) -> list[float]:
        """``e^{-ξ q} · B`` in place for a rigid transform B given row-major (its first 12 Python floats,
        the top three rows, are read and written): the scalar FK path of :meth:`inverse_motion`, on plain floats. A rotation about a
        coordinate axis (the standard joints) turns two rows only."""
        if self.prismatic:  # the origin moves by −q u
            ux, uy, uz = self.axis
            rows[3] -= value * ux
            rows[7] -= value * uy
            rows[11] -= value * uz
            return rows
        c, s = math.cos(value), math.sin(value)
        plane = self._coordinate_axis
        if plane is not None:  # rotation by −σ q about e_i through the point: rows j and k turn
            j, k, pj, pk, sign = plane
            s = -sign * s
            a0, a1, a2, a3 = rows[j:j + 4]
            b0, b1, b2, b3 = rows[k:k + 4]
            a3, b3 = a3 - pj, b3 - pk
            rows[j:j + 4] = c * a0 - s * b0, c * a1 - s * b1, c * a2 - s * b2, c * a3 - s * b3 + pj
            rows[k:k + 4] = s * a0 + c * b0, s * a1 + c * b1, s * a2 + c * b2, s * a3 + c * b3 + pk
            return rows
        # any axis: R = I − s K + (1 − cos) K², K = skew(u), K² = u uᵀ − I, written out
        ux, uy, uz = self.axis
        cx, cy, cz = self.point
        rows[3] -= cx
        rows[7] -= cy
        rows[11] -= cz
        v = 1.0 - c
        xy, xz, yz = v * ux * uy, v * ux * uz, v * uy * uz
        R = (c + v * ux * ux, s * uz + xy, -s * uy + xz,
             -s * uz + xy, c + v * uy * uy, s * ux + yz,
             s * uy + xz, -s * ux + yz, c + v * uz * uz)
        for m in range(4):
            b0, b1, b2 = rows[m], rows[4 + m], rows[8 + m]
            rows[m] = R[0] * b0 + R[1] * b1 + R[2] * b2
            rows[4 + m] = R[3] * b0 + R[4] * b1 + R[5] * b2
            rows[8 + m] = R[6] * b0 + R[7] * b1 + R[8] * b2
        rows[3] += cx
        rows[7] += cy
        rows[11] += cz
        return rows


def standard_joints(ranges: dict[str, JointRange], up, pivot) -> tuple[TableJoint, ...]:
    """The extra joints named in ``ranges`` with their standard axes, ordered from the table top down.

    ``up`` is the upward unit vector in frame 0 (the preset's Y0 points down: up = (0, -1, 0)); rotations
    turn about axes through ``pivot`` (m, frame 0), e.g. the column head under the table top.
    """
    unknown = set(ranges) - set(CHAIN_ORDER)
    if unknown:
        raise InvalidParameterError(f"unknown table joint(s) {sorted(unknown)}; known: {', '.join(CHAIN_ORDER)}")
    axes = {"up": tuple(up), "x": (1.0, 0.0, 0.0), "z": (0.0, 0.0, 1.0)}
    joints = [
        TableJoint(name, KINDS[name][0], axes[KINDS[name][1]], tuple(pivot), ranges[name])
        for name in CHAIN_ORDER if name in ranges
    ]
    return tuple(reversed(joints))


def inverse_chain(joints: tuple[TableJoint, ...], values) -> np.ndarray:
    """``e^{-ξk qk} ··· e^{-ξ1 q1}`` for joints ordered from the top down and their values (4, 4)."""
    out = np.eye(4)
    for joint, value in zip(joints, values):
        out = out @ joint.inverse_motion(float(value))
    return out


def xacro_spec(joints: tuple[TableJoint, ...], forward: bool = False) -> str:
    """The joints as the ``table_joints`` xacro argument: ``name:type:axis:point:lower:upper`` separated by
    spaces (axis of the URDF joint = −axis, since the chain runs from the top to the floor; +axis with
    ``forward``, for the mount joints of :mod:`carmkin.model.mount_joints`, which run from the floor up)."""
    def vec(v) -> str:
        return ",".join(repr(float(x)) for x in v)

    sign = 1.0 if forward else -1.0
    return " ".join(
        f"{j.name}:{'prismatic' if j.prismatic else 'revolute'}:{vec(sign * np.asarray(j.axis))}:{vec(j.point)}:"
        f"{j.range.lower!r}:{j.range.upper!r}"
        for j in joints
    )
