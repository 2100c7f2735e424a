"""A clinical view: a beam axis through a target, in the table frame, with its ways in and out.

A :class:`View` is the unit direction of the principal axis (source → detector) and the target point it
passes through, both in the table frame 0 (m); the source–target ``distance`` (m) is given or left to the
C-arm (``None``: anywhere with the target between source and detector). The roll about the beam is free,
or fixed by ``x_axis``: the direction the source frame's x axis (the image's rows) should take, projected
onto the plane across the beam (so any vector not along the beam names one roll).

Built from DICOM XA angles for any Patient Position (PS3.3 C.8.7.5.1.2: primary LAO +, RAO −; secondary
CRA +, CAU −) through :func:`carmkin.interop.dicom.pose_from_xa_angles`, from a direction, from a target
and a point the source lies towards, or as the foreshortening-free views of a segment (directions
perpendicular to it). :meth:`View.angles` reads a view back in clinical terms for a patient.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import CarmkinError, ViewError
from carmkin.imaging.projection import patient_pose
from carmkin.interop import dicom
from carmkin.transforms import check_rigid_transform
from carmkin.validation import flag, real_array, real_scalar, rigid_transform, target_point

#: Below this norm (m) a direction or segment is refused as undefined.
DIRECTION_TOLERANCE = 1e-9


def _point(value, name) -> np.ndarray:
    """A point (3,) in m, table frame; one given in mm is refused naming the slip (:func:`target_point`)."""
    return target_point(value, name, error=ViewError)


def _unit(value, name) -> np.ndarray:
    v = real_array(value, name, (3,), error=ViewError)
    norm = float(np.linalg.norm(v))
    if norm < DIRECTION_TOLERANCE:
        raise ViewError(f"{name} must be a non-zero 3-vector, got {v.tolist()}")
    return v / norm


def _patient_frame(position):
    """The patient's pose (4, 4) in the table frame: a Patient Position code, a pose, or a patient model."""
    pose = getattr(position, "pose", None)
    if callable(pose):
        return pose()
    try:
        if isinstance(position, str):
            return patient_pose(position)
        return check_rigid_transform(np.asarray(position, dtype=float), "position")
    except (CarmkinError, TypeError) as exc:
        raise ViewError(f"position must be a Patient Position code or a 4x4 pose, got {position!r:.60}") from exc


@dataclass(frozen=True)
class View:
    """Beam ``direction`` (3,) unit, source → detector, through ``target`` (3,) m, table frame; ``distance``
    source–target (m) or ``None`` (free); ``name`` for people; ``x_axis`` (3,) the source frame's x axis
    (unit, across the beam: the given vector projected) or ``None`` (free roll)."""

    target: tuple
    direction: tuple
    distance: float | None = None
    name: str = ""
    x_axis: tuple | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "target", tuple(_point(self.target, "target").tolist()))
        object.__setattr__(self, "direction", tuple(_unit(self.direction, "direction").tolist()))
        if self.x_axis is not None:
            z = np.array(self.direction)
            x = real_array(self.x_axis, "x_axis", (3,), error=ViewError)
            across = x - (x @ z) * z
            if np.linalg.norm(across) < DIRECTION_TOLERANCE * max(1.0, float(np.linalg.norm(x))):
                raise ViewError(f"x_axis must not lie along the beam direction {np.round(z, 6).tolist()}, got "
                                f"{x.tolist()}")
            object.__setattr__(self, "x_axis", tuple((across / np.linalg.norm(across)).tolist()))
        if self.distance is not None:
            object.__setattr__(self, "distance", real_scalar(self.distance, "distance", error=ViewError,
                                                             low=DIRECTION_TOLERANCE, high=10.0, unit="m"))
        if not isinstance(self.name, str):
            raise ViewError(f"name must be a string, got {self.name!r}")

    # --- constructors ------------------------------------------------------------------------------------
    @classmethod
    def from_angles(cls, primary_deg, secondary_deg, target, position="HFS", distance=None, name="",
                    rotation_deg=None) -> "View":
        """XA Positioner Primary (LAO +) and Secondary (CRA +) Angles (deg) of a patient in ``position`` (a
        Patient Position code, the patient's LPS pose (4, 4) in the table frame, or a patient model);
        ``rotation_deg``: the detector's rotation about the beam as :func:`carmkin.interop.dicom.xa_angles`
        reads it (deg), or ``None`` (free roll)."""
        p = real_scalar(primary_deg, "primary_deg", error=ViewError, low=-180.0, high=180.0, unit="deg")
        s = real_scalar(secondary_deg, "secondary_deg", error=ViewError, low=-90.0, high=90.0, unit="deg")
        rotation = 0.0 if rotation_deg is None else real_scalar(rotation_deg, "rotation_deg", error=ViewError,
                                                                 low=-180.0, high=180.0, unit="deg")
        target = _point(target, "target")
        T = dicom.pose_from_xa_angles(p, s, target, 1.0, _patient_frame(position), rotation)
        return cls(tuple(target), tuple(T[:3, 2]), distance, name, None if rotation_deg is None else tuple(T[:3, 0]))

    @classmethod
    def from_pose(cls, T_source, distance=None, name="", roll: bool = True) -> "View":
        """The view of a source pose (4, 4, table frame): its beam through the point ``distance`` (m) ahead of
        the source, at that distance, with its roll (``roll=False``: free)."""
        T = rigid_transform(T_source, "T_source", error=ViewError)
        d = real_scalar(distance, "distance", error=ViewError, low=DIRECTION_TOLERANCE, high=10.0, unit="m")
        roll = flag(roll, "roll", error=ViewError)  # a string "False" would read as True
        return cls(tuple(T[:3, 3] + d * T[:3, 2]), tuple(T[:3, 2]), d, name, tuple(T[:3, 0]) if roll else None)

    @classmethod
    def from_direction(cls, direction, target, distance=None, name="") -> "View":
        """A beam along ``direction`` (source → detector, table frame) through ``target`` (m)."""
        return cls(target, direction, distance, name)

    @classmethod
    def towards(cls, target, source_side_point, distance=None, name="") -> "View":
        """The beam through ``target`` whose source lies towards ``source_side_point`` (m, table frame)."""
        target = _point(target, "target")
        w = target - _point(source_side_point, "source_side_point")
        if np.linalg.norm(w) < DIRECTION_TOLERANCE:
            raise ViewError("source_side_point must differ from target")
        return cls(tuple(target), tuple(w), distance, name)

    @classmethod
    def perpendicular_to(cls, a, b, count: int = 72, target=None) -> list["View"]:
        """The foreshortening-free views of the segment a–b (m, table frame; a vessel, a screw): ``count``
        beam directions perpendicular to it, evenly spaced over the full turn, through ``target`` (default
        the segment's midpoint)."""
        a, b = _point(a, "a"), _point(b, "b")
        axis = b - a
        if np.linalg.norm(axis) < DIRECTION_TOLERANCE:
            raise ViewError("the segment's end points a and b must differ")
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
            raise ViewError(f"count must be a positive integer, got {count!r}")
        axis = axis / np.linalg.norm(axis)
        helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
        e1 = np.cross(axis, helper)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(axis, e1)
        centre = 0.5 * (a + b) if target is None else _point(target, "target")
        return [cls(tuple(centre), tuple(math.cos(t) * e1 + math.sin(t) * e2), None, f"perpendicular {k}")
                for k, t in enumerate(np.linspace(0.0, 2 * math.pi, count, endpoint=False))]

    # --- readers -----------------------------------------------------------------------------------------
    @property
    def axis(self) -> np.ndarray:
        return np.array(self.direction)

    def angles(self, patient="HFS") -> tuple[float, float]:
        """``(primary, secondary)`` (deg): XA angles of this beam for a patient (position code, LPS pose or
        patient model); the secondary in [−90, 90]."""
        T = np.eye(4)
        z = self.axis
        x = np.cross(np.eye(3)[int(np.argmin(np.abs(z)))], z)
        x /= np.linalg.norm(x)
        T[:3, :3] = np.column_stack((x, np.cross(z, x), z))
        p, s, _ = dicom.xa_angles(T, _patient_frame(patient))
        return p, s

    def angle_to(self, other: "View") -> float:
        """Angle (rad) between the two beam axes."""
        c = float(np.clip(np.dot(self.axis, other.axis), -1.0, 1.0))
        return math.atan2(float(np.linalg.norm(np.cross(self.axis, other.axis))), c)
