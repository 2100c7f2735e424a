"""Differential-IK tasks on a Pinocchio frame: full pose, position + axis direction, aim at a point.

A task linearises a residual ``r(q)`` around the current configuration: after a step ``dq`` the residual is
``r + J dq`` (first order), and the QP of :mod:`carmkin.qp_ik` minimises ``weight * |r + J dq|^2`` summed
over the tasks. Targets are expressed in the root frame of the model (for the C-arm: the table frame 0),
lengths in metres, angles in radians. All tasks read ``data`` after
:func:`pinocchio.computeJointJacobians` and :func:`pinocchio.updateFramePlacements`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from carmkin.errors import (
    TaskError,  # noqa: F401 (defined there, raised here)
)
from carmkin.transforms import check_rigid_transform, skew


def _unit(v, name: str) -> np.ndarray:
    v = np.asarray(v, dtype=float).reshape(3)
    n = np.linalg.norm(v)
    if not np.isfinite(n) or n < 1e-12:
        raise TaskError(f"{name} must be a finite non-zero 3-vector, got {v}")
    return v / n


def _point(v, name: str) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise TaskError(f"{name} must be a finite 3-vector (m), got {v!r}")
    return v


@dataclass
class TaskErrors:
    """Remaining errors of a task: ``position`` (m) and ``angle`` (rad); ``satisfied`` within tolerances."""

    position: float
    angle: float
    satisfied: bool


class FrameTask:
    """Base class: a task on frame ``frame`` of ``model`` with a positive cost ``weight``."""

    #: Number of residual rows.
    dim = 0

    def __init__(self, model: pin.Model, frame: str, weight: float = 1.0) -> None:
        if not model.existFrame(frame):
            raise TaskError(f"the model has no frame named {frame!r}")
        if not (np.isfinite(weight) and weight > 0):
            raise TaskError(f"task weight must be finite and > 0, got {weight}")
        self.frame = frame
        self.frame_id = model.getFrameId(frame)
        self.weight = float(weight)

    def residual(self, model: pin.Model, data: pin.Data) -> tuple[np.ndarray, np.ndarray]:
        """``(J (dim, nv), r (dim,))``: first-order model ``r + J dq`` of the residual."""
        raise NotImplementedError

    def inequalities(self, model: pin.Model, data: pin.Data) -> tuple[np.ndarray, np.ndarray] | None:
        """Optional rows ``G dq <= h`` the step must satisfy (first order), or ``None``."""
        return None

    def errors(self, data: pin.Data, position_tolerance: float, angle_tolerance: float) -> TaskErrors:
        """The task's remaining errors at the configuration of ``data``."""
        raise NotImplementedError


class PoseTask(FrameTask):
    """Full 6-DOF pose of ``frame``: ``target`` (4x4) in the root frame.

    Residual ``log6(target^-1 · pose)`` (local twist, [m, rad]); Jacobian ``Jlog6 · J_local``.
    """

    dim = 6

    def __init__(self, model: pin.Model, frame: str, target, weight: float = 1.0) -> None:
        super().__init__(model, frame, weight)
        self.set_target(target)

    def set_target(self, target) -> None:
        """Replace the target pose (4x4, root frame)."""
        self.target = pin.SE3(check_rigid_transform(target, "target pose"))

    @property
    def target(self) -> pin.SE3:
        """The target pose (``pin.SE3``, root frame)."""
        return self._target

    @target.setter
    def target(self, value: pin.SE3) -> None:
        self._target = value
        self._target_rows = value.homogeneous.tolist()

    def residual(self, model, data):
        tMf = self.target.actInv(data.oMf[self.frame_id])
        J = pin.Jlog6(tMf) @ pin.getFrameJacobian(model, data, self.frame_id, pin.LOCAL)
        return J, pin.log6(tMf).vector

    def errors(self, data, position_tolerance, angle_tolerance):
        position, angle = pose_errors(data.oMf[self.frame_id].homogeneous.tolist(), self._target_rows)
        return TaskErrors(position, angle, position <= position_tolerance and angle <= angle_tolerance)


def pose_errors(a: list, b: list) -> tuple[float, float]:
    """``(|p_a − p_b| m, angle of R_bᵀ R_a rad)`` of two poses given as nested lists (4x4 rows), written out on
    floats (the check of every closed-form branch); the angle as atan2(|skew part|, (trace − 1) / 2),
    accurate over the whole range (as :func:`carmkin.transforms.rotation_angle`)."""
    (a0, a1, a2, ap), (a3, a4, a5, aq), (a6, a7, a8, ar) = a[0], a[1], a[2]
    (b0, b1, b2, bp), (b3, b4, b5, bq), (b6, b7, b8, br) = b[0], b[1], b[2]
    position = math.sqrt((ap - bp) ** 2 + (aq - bq) ** 2 + (ar - br) ** 2)
    m00, m11, m22 = b0 * a0 + b3 * a3 + b6 * a6, b1 * a1 + b4 * a4 + b7 * a7, b2 * a2 + b5 * a5 + b8 * a8
    m21, m12 = b2 * a1 + b5 * a4 + b8 * a7, b1 * a2 + b4 * a5 + b7 * a8
    m02, m20 = b0 * a2 + b3 * a5 + b6 * a8, b2 * a0 + b5 * a3 + b8 * a6
    m10, m01 = b1 * a0 + b4 * a3 + b7 * a6, b0 * a1 + b3 * a4 + b6 * a7
    sine = 0.5 * math.sqrt((m21 - m12) ** 2 + (m02 - m20) ** 2 + (m10 - m01) ** 2)
    return position, math.atan2(sine, 0.5 * (m00 + m11 + m22 - 1.0))


class FrameAxisTask(FrameTask):
    """Base class of the tasks on one ``axis`` of the frame (0 X, 1 Y, 2 Z: the principal axis) with a
    target given to ``set_target`` (one validation of the axis for :class:`AxisTask` and :class:`AimTask`)."""

    def __init__(self, model: pin.Model, frame: str, target: tuple, axis: int, weight: float) -> None:
        super().__init__(model, frame, weight)
        if axis not in (0, 1, 2):
            raise TaskError(f"axis must be 0 (X), 1 (Y) or 2 (Z), got {axis!r}")
        self.axis = axis
        self.set_target(*target)

    def set_target(self, *target) -> None:
        raise NotImplementedError


class AxisTask(FrameAxisTask):
    """Position of ``frame`` and direction of its ``axis`` (default Z, the principal axis); roll free.

    The 5-DOF aim of §4.6.1: ``position`` (m) and unit ``direction`` in the root frame. Residual
    ``[p - position, a - direction]`` with ``a`` the frame axis in the root frame.
    """

    dim = 6

    def __init__(self, model, frame, position, direction, axis: int = 2, weight: float = 1.0) -> None:
        super().__init__(model, frame, (position, direction), axis, weight)

    def set_target(self, position, direction) -> None:
        """Replace the target position (m) and direction (normalised here; zero is an error)."""
        self.position = _point(position, "AxisTask position")
        self.direction = _unit(direction, "AxisTask direction")

    def residual(self, model, data):
        oMf = data.oMf[self.frame_id]
        a = oMf.rotation[:, self.axis]
        J6 = pin.getFrameJacobian(model, data, self.frame_id, pin.LOCAL_WORLD_ALIGNED)
        J = np.vstack((J6[:3], -skew(a) @ J6[3:]))
        return J, np.concatenate((oMf.translation - self.position, a - self.direction))

    def errors(self, data, position_tolerance, angle_tolerance):
        oMf = data.oMf[self.frame_id]
        a = oMf.rotation[:, self.axis]
        position = float(np.linalg.norm(oMf.translation - self.position))
        b = self.direction  # |a × b| written out: np.cross costs more than the rest of the test
        cross = (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
        angle = float(np.arctan2(np.sqrt(cross[0] ** 2 + cross[1] ** 2 + cross[2] ** 2), a @ b))
        return TaskErrors(position, angle, position <= position_tolerance and angle <= angle_tolerance)


class AimTask(FrameAxisTask):
    """The frame's ``axis`` (default Z, the principal axis) passes through ``point``, at a distance along
    the axis between ``distance_range[0]`` and ``distance_range[1]`` (m); direction and roll are free.

    Residual: the component of ``point - p`` perpendicular to the axis (m). The distance bounds are
    first-order inequality rows of the QP.
    """

    dim = 3

    def __init__(self, model, frame, point, distance_range, axis: int = 2, weight: float = 1.0) -> None:
        super().__init__(model, frame, (point, distance_range), axis, weight)

    def set_target(self, point, distance_range) -> None:
        """Replace the target point (m) and the distance range (m, lower <= upper)."""
        self.point = _point(point, "AimTask point")
        lo, hi = (float(v) for v in distance_range)
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise TaskError(f"AimTask distance_range must be finite with lower <= upper, got {(lo, hi)}")
        self.distance_range = (lo, hi)

    def _parts(self, model, data):
        oMf = data.oMf[self.frame_id]
        a = oMf.rotation[:, self.axis]
        w = self.point - oMf.translation
        J6 = pin.getFrameJacobian(model, data, self.frame_id, pin.LOCAL_WORLD_ALIGNED)
        Ja = -skew(a) @ J6[3:]  # d(axis)/dq
        return a, w, J6[:3], Ja

    def residual(self, model, data):
        a, w, Jp, Ja = self._parts(model, data)
        s = a @ w
        # r = w - a (a·w); dw = -Jp dq; da = Ja dq
        J = -(np.eye(3) - np.outer(a, a)) @ Jp - s * Ja - np.outer(a, w @ Ja)
        return J, w - s * a

    def inequalities(self, model, data):
        a, w, Jp, Ja = self._parts(model, data)
        s = a @ w
        ds = w @ Ja - a @ Jp  # d(a·w)/dq
        lo, hi = self.distance_range
        return np.vstack((ds, -ds)), np.array([hi - s, s - lo])

    def errors(self, data, position_tolerance, angle_tolerance):
        oMf = data.oMf[self.frame_id]
        a = oMf.rotation[:, self.axis]
        w = self.point - oMf.translation
        s = a @ w
        offset = float(np.linalg.norm(w - s * a))
        lo, hi = self.distance_range
        outside = max(lo - s, s - hi, 0.0)
        position = max(offset, outside)
        return TaskErrors(position, 0.0, position <= position_tolerance)
