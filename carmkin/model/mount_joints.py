"""Mount joints: a chain that carries the C-arm base (``carm_cart``) relative to the floor, e.g. the six axes
of an industrial robot holding the C (Siemens Artis zeego: a KUKA arm).

The mirror image of a motorized table (:mod:`carmkin.model.table_joints`): there the table top moves relative
to the floor, here the C-arm base does. A mount joint is a twist η (a unit axis and a point of it, or a
direction of translation) stated **at rest** (every mount joint zero) in the robot's base frame ``B``; the
robot base sits at the pose ``T_0B`` in the rest table frame 0 (the floor-fixed frame ``table_reference``).
In frame 0 the chain moves the C-arm base by the product of exponentials

    ``G(q_mount) = e^{η1 q1} ··· e^{ηn qn}``     (η_i = Ad(T_0B) η_i^B),

so that the source pose in the table frame is ``Tz(d0) · E(q_table) · G(q_mount) · P(q6 with d0 = 0)``, with
``P`` the closed-form 6-DOF chain of the paper and ``K = P``'s C-arm base at rest (the system's setup).

This is the form of a robot's data sheet and of its ROS-Industrial URDF whose joint origins carry no rotation
(``rpy = 0``): the axis of joint i in the base frame, and its origin, the sum of the joint origins up to i, as
a point of the axis. No DH convention to choose, no link frames to attach; a non-intersecting or a
prismatic axis is stated the same way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from carmkin.errors import InvalidParameterError
from carmkin.validation import real_array

from .bounds import MAX_LENGTH, check_length
from .table_joints import TableJoint

#: Tolerance (dimensionless) on the unit length and the orthogonality of the robot base's axes
#: (:class:`MountGeometry` ``base_x_axis`` / ``base_z_axis``): the one of the twists' axes (:class:`TableJoint`).
AXIS_TOLERANCE = 1e-9


class MountJoint(TableJoint):
    """One mount joint: a twist at rest (``axis`` unit, ``point`` m, both in the frame the owner states) and its
    range (m or rad). Validated as a :class:`~carmkin.model.table_joints.TableJoint` (a non-unit axis is an
    :class:`~carmkin.errors.InvalidParameterError` naming the joint and ``axis``); it moves forwards: ``e^{η q}``."""

    def motion(self, value: float) -> np.ndarray:
        """``e^{η q}`` (4, 4): the motion of this joint by ``value`` (m or rad)."""
        return self.inverse_motion(-value)

    def apply_motion(self, rows: list[float], value: float) -> list[float]:
        """``e^{η q} · B`` in place on the row-major floats of a rigid transform B (the scalar FK path)."""
        return self.apply_inverse_motion(rows, -value)

    def moved(self, T: np.ndarray) -> "MountJoint":
        """This joint with its axis and point carried by the rigid transform ``T`` (4, 4): its twist in the
        frame where ``T`` places the joint's frame (``Ad(T) η``)."""
        R, t = T[:3, :3], T[:3, 3]
        return MountJoint(self.name, self.prismatic, tuple(R @ np.asarray(self.axis)),
                          tuple(R @ np.asarray(self.point) + t), self.range)


def _vector(name: str, value, unit: str) -> np.ndarray:
    """``MountGeometry.<name>``: three real numbers (no bool, complex, string), or InvalidParameterError."""
    return real_array(value, f"MountGeometry.{name}", (3,), unit=unit)


def _direction(name: str, value) -> np.ndarray:
    v = _vector(name, value, "unit vector")
    if abs(np.linalg.norm(v) - 1.0) > AXIS_TOLERANCE:
        raise InvalidParameterError(f"MountGeometry.{name} must be a unit 3-vector, got {value!r}")
    return v


@dataclass(frozen=True)
class MountGeometry:
    """What carries the C-arm base: a robot (or any chain of revolute and prismatic joints) on the floor.

    Attributes:
        joints: the mount joints (:class:`MountJoint`) from the floor up, each twist stated at rest in the robot
            base frame B (axis unit, point in m); empty for a C-arm on its own cart.
        base_origin: origin of B in the rest table frame 0 (m).
        base_x_axis, base_z_axis: the axes X_B and Z_B in frame 0 (orthonormal unit vectors; Z_B up for a
            floor-standing robot).
        link_width: side (m) of the square cross-section of the boxes drawn and checked for collision along
            the robot: from B's origin to the first joint's point (the pedestal, fixed), from each joint's
            point to the next one's, from the last one's to the C-arm base (moving).
        carm_base: the C-arm base frame at rest in B as a preset stated it, ``(origin (m), x axis, z axis)``, or
            None. The kinematics read the system's setup (whose rest pose the loader derives from this); it is
            kept so that :func:`carmkin.presets.to_toml` writes the preset back as it was read.
    """

    joints: tuple = ()
    base_origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    base_x_axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    base_z_axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    link_width: float = 0.25
    carm_base: tuple | None = None

    def __post_init__(self) -> None:
        if isinstance(self.joints, (str, bytes)) or not hasattr(self.joints, "__iter__"):
            raise InvalidParameterError(f"MountGeometry.joints must be a tuple of MountJoint, got {self.joints!r}")
        object.__setattr__(self, "joints", tuple(self.joints))
        names = [getattr(j, "name", None) for j in self.joints]
        if len(set(names)) != len(names) or not all(isinstance(j, MountJoint) for j in self.joints):
            raise InvalidParameterError(f"MountGeometry.joints must be distinct MountJoint objects, got {names}")
        origin = _vector("base_origin", self.base_origin, "m")
        object.__setattr__(self, "base_origin",
                           tuple(check_length("MountGeometry.base_origin", v) for v in origin.tolist()))
        x, z = _direction("base_x_axis", self.base_x_axis), _direction("base_z_axis", self.base_z_axis)
        if abs(float(x @ z)) > AXIS_TOLERANCE:
            raise InvalidParameterError(f"MountGeometry.base_x_axis and base_z_axis must be orthogonal, got "
                                        f"{x.tolist()} and {z.tolist()} (cosine {float(x @ z):.3g})")
        object.__setattr__(self, "base_x_axis", tuple(x.tolist()))
        object.__setattr__(self, "base_z_axis", tuple(z.tolist()))
        object.__setattr__(self, "link_width", check_length("MountGeometry.link_width", self.link_width, positive=True))
        if self.carm_base is not None:
            parts = tuple(map(tuple, real_array(self.carm_base, "MountGeometry.carm_base (origin, x axis, z axis)",
                                                (3, 3), unit="m; unit vectors").tolist()))
            object.__setattr__(self, "carm_base", parts)
        for joint in self.joints:
            if max(abs(v) for v in joint.point) > MAX_LENGTH:
                raise InvalidParameterError(f"mount joint {joint.name!r}: point must be within {MAX_LENGTH:g} m of "
                                            f"the robot base, got {joint.point}")

    @cached_property
    def base_pose(self) -> np.ndarray:
        """``T_0B`` (4, 4): the robot base frame in the rest table frame 0."""
        x, z = np.asarray(self.base_x_axis), np.asarray(self.base_z_axis)
        T = np.eye(4)
        T[:3, :3] = np.column_stack((x, np.cross(z, x), z))
        T[:3, 3] = self.base_origin
        return T

    @cached_property
    def twists(self) -> tuple[MountJoint, ...]:
        """The joints with their twists in the rest table frame 0 (what the kinematics use)."""
        return tuple(joint.moved(self.base_pose) for joint in self.joints)


def motions(joint: MountJoint, values) -> np.ndarray:
    """``e^{η q}`` (N, 4, 4) of one joint for values (N,) (m or rad): :meth:`MountJoint.motion` vectorised
    (Rodrigues' formula; the tests hold the two together)."""
    values = np.asarray(values, dtype=float)
    u, c = np.asarray(joint.axis), np.asarray(joint.point)
    out = np.zeros(values.shape + (4, 4))
    out[..., 3, 3] = 1.0
    if joint.prismatic:
        out[..., [0, 1, 2], [0, 1, 2]] = 1.0
        out[..., :3, 3] = values[..., None] * u
        return out
    K = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    s, v = np.sin(values)[..., None, None], (1.0 - np.cos(values))[..., None, None]
    R = np.eye(3) + s * K + v * (K @ K)
    out[..., :3, :3] = R
    out[..., :3, 3] = c - R @ c
    return out


def chain(joints: tuple[MountJoint, ...], values) -> np.ndarray:
    """``e^{η1 q1} ··· e^{ηn qn}`` for joints from the floor up and their values: (4, 4) for values (n,),
    (N, 4, 4) for (N, n) (vectorised)."""
    values = np.asarray(values, dtype=float)
    if values.ndim == 2:
        return partial_chains(joints, values)[:, -1] if len(joints) else np.broadcast_to(np.eye(4), (len(values), 4, 4)).copy()
    out = np.eye(4)
    for joint, value in zip(joints, values):
        out = out @ joint.motion(float(value))
    return out


def partial_chains(joints: tuple[MountJoint, ...], values) -> np.ndarray:
    """``G_i = e^{η1 q1} ··· e^{ηi qi}`` for i = 1..n, (n, 4, 4) for values (n,), (N, n, 4, 4) for (N, n): the
    motion of the body after joint i."""
    values = np.asarray(values, dtype=float)
    if values.ndim == 2:
        out = np.empty((len(values), len(joints), 4, 4))
        G = np.broadcast_to(np.eye(4), (len(values), 4, 4))
        for i, joint in enumerate(joints):
            G = G @ motions(joint, values[:, i])
            out[:, i] = G
        return out
    out = np.empty((len(joints), 4, 4))
    G = np.eye(4)
    for i, (joint, value) in enumerate(zip(joints, values)):
        G = G @ joint.motion(float(value))
        out[i] = G
    return out


def body_boxes(mount: MountGeometry, carm_base_origin) -> list[tuple[np.ndarray, float, np.ndarray]]:
    """The robot's boxes at rest in frame 0: ``(centre (3,), length, R (3, 3))`` with the box's Z along its
    segment, for the pedestal (B's origin to the first joint's point) and each joint's body (its point to the
    next one's, the last one's to ``carm_base_origin`` (3,) m). A segment shorter than the link width is a
    cube of that side (e.g. between two axes that intersect)."""
    twists = mount.twists
    points = [np.asarray(mount.base_origin)] + [np.asarray(j.point) for j in twists] + [np.asarray(carm_base_origin)]
    width = mount.link_width
    out = []
    for a, b in zip(points[:-1], points[1:]):
        d = b - a
        length = float(np.linalg.norm(d))
        if length < width:
            out.append(((a + b) / 2, width, np.eye(3)))
            continue
        z = d / length
        helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        x = np.cross(helper, z)
        x /= np.linalg.norm(x)
        out.append(((a + b) / 2, length + width, np.column_stack((x, np.cross(z, x), z))))
    return out


def rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw (rad) of a rotation matrix, ``R = Rz(yaw) Ry(pitch) Rx(roll)``."""
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    if math.hypot(R[0, 0], R[1, 0]) < 1e-12:  # gimbal lock: put the whole turn in roll
        return math.atan2(-R[1, 2], R[1, 1]), pitch, 0.0
    return math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])


MOUNT_LINK = "mount_body_{}"
"""Name of the link that carries the body of mount joint k (1-based; 0 is the fixed pedestal): the collision
pair policy (:mod:`carmkin.world.obstacles`) knows the robot's parts by this prefix."""


def xacro_spec(mount: MountGeometry, carm_base_origin) -> tuple[str, str]:
    """``(mount_joints, mount_boxes)`` xacro arguments: the joints as ``name:type:axis:point:lower:upper``
    (twists in frame 0, the URDF joint axis = η's axis since the chain runs from the floor up) and the boxes as
    ``x,y,z:length:roll,pitch,yaw`` in frame 0 at rest, separated by spaces."""
    from .table_joints import xacro_spec as joint_spec

    boxes = " ".join(f"{_vec(c)}:{length!r}:{_vec(rpy(R))}" for c, length, R in body_boxes(mount, carm_base_origin))
    return joint_spec(mount.twists, forward=True), boxes


def _vec(v) -> str:
    return ",".join(repr(float(x)) for x in v)


__all__ = ["MountJoint", "MountGeometry", "motions", "chain", "partial_chains", "body_boxes", "xacro_spec", "MOUNT_LINK",
           "AXIS_TOLERANCE"]
