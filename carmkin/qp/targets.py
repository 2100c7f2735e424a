"""Targets of the C-arm's X-ray source and the closed-form seed pose of each.

A target is a 4x4 pose of ``xray_source`` in the table frame 0, an :class:`AxisTarget` (source position and
principal-axis direction, roll free: the 5-DOF aim of §4.6.1) or an :class:`AimTarget` (the principal axis
passes through a point at a source distance within a range). :func:`make_task` turns a target into its
differential-IK task (:mod:`carmkin.qp.tasks`); :func:`closed_form_pose` gives the full pose the closed
forms need for it. Lengths in metres, angles in radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from carmkin.errors import CarmkinError
from carmkin.transforms import check_rigid_transform, rotation_between
from carmkin.validation import real_array

from .options import SOURCE_FRAME, QPIKError
from .tasks import AimTask, AxisTask, FrameTask, PoseTask

#: Below this distance (m) from the source an aim point gives no direction; the reference axis is kept.
AIM_POINT_TOLERANCE = 1e-12


@dataclass(frozen=True)
class AxisTarget:
    """Source position (m) and principal-axis direction in the table frame; roll about the axis free."""

    position: tuple[float, float, float]
    direction: tuple[float, float, float]

    def __post_init__(self) -> None:
        position = real_array(self.position, "AxisTarget.position", (3,), error=QPIKError, unit="m")
        direction = real_array(self.direction, "AxisTarget.direction", (3,), error=QPIKError)
        if not np.linalg.norm(direction) > AIM_POINT_TOLERANCE:
            raise QPIKError(f"AxisTarget.direction must be a non-zero 3-vector, got {self.direction!r}")
        object.__setattr__(self, "position", tuple(position.tolist()))
        object.__setattr__(self, "direction", tuple(direction.tolist()))


@dataclass(frozen=True)
class AimTarget:
    """The principal axis passes through ``point`` (m, table frame) at a source distance in ``distance_range``."""

    point: tuple[float, float, float]
    distance_range: tuple[float, float]

    def __post_init__(self) -> None:
        point = real_array(self.point, "AimTarget.point", (3,), error=QPIKError, unit="m")
        lo, hi = real_array(self.distance_range, "AimTarget.distance_range", (2,), error=QPIKError, unit="m").tolist()
        if not 0.0 <= lo <= hi:
            raise QPIKError(f"AimTarget.distance_range must be (lower, upper) with 0 <= lower <= upper (m), got {(lo, hi)}")
        object.__setattr__(self, "point", tuple(point.tolist()))
        object.__setattr__(self, "distance_range", (lo, hi))


def make_task(model: pin.Model, target, frame: str = SOURCE_FRAME) -> FrameTask:
    """The task of a target: a 4x4 pose → :class:`PoseTask`, :class:`AxisTarget`, :class:`AimTarget`."""
    if isinstance(target, AxisTarget):
        return AxisTask(model, frame, target.position, target.direction)
    if isinstance(target, AimTarget):
        return AimTask(model, frame, target.point, target.distance_range)
    try:
        return PoseTask(model, frame, target)
    except CarmkinError as exc:
        raise QPIKError(f"target must be a 4x4 pose, an AxisTarget or an AimTarget: {exc}") from exc


def closed_form_pose(target, T_ref: np.ndarray) -> np.ndarray:
    """A full pose (4, 4) for the closed forms: the target itself, or for axis/aim targets the pose reached
    from the reference source pose ``T_ref`` (4, 4) with the least rotation (roll kept)."""
    if not isinstance(target, (AxisTarget, AimTarget)):
        return check_rigid_transform(target, "target")
    if isinstance(target, AxisTarget):
        position, direction = np.asarray(target.position, float), np.asarray(target.direction, float)
        direction = direction / np.linalg.norm(direction)
    else:
        point = np.asarray(target.point, float)
        w = point - T_ref[:3, 3]
        direction = w / np.linalg.norm(w) if np.linalg.norm(w) > AIM_POINT_TOLERANCE else T_ref[:3, 2]
        lo, hi = target.distance_range
        distance = float(np.clip(np.linalg.norm(w), lo, hi))  # a seed pose only: the QP enforces the range
        position = point - distance * direction
    T = np.eye(4)
    T[:3, :3] = rotation_between(T_ref[:3, 2], direction) @ T_ref[:3, :3]
    T[:3, 3] = position
    return T
