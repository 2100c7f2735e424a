"""What the world is made of: the obstacles fixed to the table frame and the documented pair list.

The collision model of :meth:`CArmSystem.pinocchio` holds one coal primitive (box) per URDF ``<collision>``
element, named ``<link>_<k>``. :class:`carmkin.world.World` copies it, adds :class:`Obstacle` s (e.g. a
patient volume) fixed to the table frame 0, and keeps only the pairs that matter (:func:`carm_pair_names`):

* every **moving C-arm part** — the links carried by the vertical joint and beyond: ``dh_frame_2``
  (column), ``dh_frame_3`` (arm sleeve), ``dh_frame_4`` (inner arm), ``dh_frame_5`` (orbital guide),
  ``dh_frame_6`` (C segments), ``xray_source`` (tube housing), ``detector`` (detector and bracket) —
  and with a mount (a robot holding the C, :mod:`carmkin.model.mount_joints`) its moving bodies
  ``mount_body_1`` … ``mount_body_n`` —
* against every **environment body**: ``table`` (table top), each obstacle, and ``floor``.

Excluded on purpose: pairs inside the C-arm (the telescoping sleeve/inner arm, the column in the cart and
neighbouring links overlap by construction), the table against the cart and the floor (they only slide
past each other along Z0; the table translation range is the user's statement that this is allowed), and
the column against the floor (the column stands in the cart, on the floor), and a mount's fixed pedestal
``mount_body_0`` (it stands on the floor; the robot's own bodies and the C-arm are one device, as above).

Distances are signed (negative = penetration depth), in metres, witness points and normals in the table
frame 0 (the root, ``universe``). The normal points from the first object of a pair to the second.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import coal
import numpy as np

from carmkin.errors import (
    CarmkinError,
    CollisionSceneError,  # noqa: F401 (defined there, raised here)
    PatientModelError,
)
from carmkin.transforms import check_rigid_transform
from carmkin.validation import MAX_DISTANCE, MIN_DISTANCE, real_array, unit_slip

#: Links of the C-arm that move with the vertical joint or later joints (collision candidates).
CARM_MOVING_LINKS = ("dh_frame_2", "dh_frame_3", "dh_frame_4", "dh_frame_5", "dh_frame_6", "xray_source", "detector")
#: Environment links of the generated URDF that the moving parts must not touch.
CARM_ENVIRONMENT_LINKS = ("table", "floor")
#: (moving link, environment link) pairs left out: the column stands in the cart on the floor.
CARM_EXCLUDED_PAIRS = (("dh_frame_2", "floor"),)
#: Largest size (m: extent, radius or length) of an :class:`Obstacle` and largest distance of its centre from
#: the table frame's origin: 10 m (:data:`carmkin.validation.MAX_DISTANCE`), more than an operating room. A
#: larger number is a unit slip (a 500 mm patient given as 500 m), refused naming it.
MAX_OBSTACLE_EXTENT = MAX_DISTANCE


@dataclass(frozen=True)
class Obstacle:
    """A rigid obstacle fixed to the table frame 0, e.g. the patient volume.

    Attributes:
        name: unique geometry name (reported in collisions).
        shape: ``"box"`` (size = full extents x, y, z), ``"capsule"`` (size = radius, length along Z),
            ``"sphere"`` (size = radius) or ``"cylinder"`` (size = radius, length along Z); metres, each
            within [1 µm, :data:`MAX_OBSTACLE_EXTENT`] (a size in mm is refused, naming the slip).
        pose: 4x4 pose of the shape's centre frame in the table frame 0, its centre within
            :data:`MAX_OBSTACLE_EXTENT` of the origin along each axis.
    """

    name: str
    shape: str
    size: tuple[float, ...]
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))

    _ARITY = {"box": 3, "capsule": 2, "sphere": 1, "cylinder": 2}

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise CollisionSceneError(f"Obstacle.name must be a non-empty string, got {self.name!r}")
        if self.shape not in self._ARITY:
            raise CollisionSceneError(
                f"Obstacle {self.name!r}: shape must be one of {sorted(self._ARITY)}, got {self.shape!r}"
            )
        size = tuple(real_array(np.atleast_1d(self.size) if isinstance(self.size, (int, float)) else self.size,
                                f"Obstacle {self.name!r} size", (None,), error=CollisionSceneError, unit="m").tolist())
        if len(size) != self._ARITY[self.shape] or not all(np.isfinite(v) and v > 0 for v in size):
            raise CollisionSceneError(
                f"Obstacle {self.name!r}: a {self.shape} needs {self._ARITY[self.shape]} positive finite sizes (m),"
                f" got {size}"
            )
        for value in size:
            if not MIN_DISTANCE <= value <= MAX_OBSTACLE_EXTENT:
                raise CollisionSceneError(
                    f"Obstacle {self.name!r}: size {value:g} m is not an obstacle near a C-arm (each size within "
                    f"[{MIN_DISTANCE:g}, {MAX_OBSTACLE_EXTENT:g}] m){unit_slip(value, MIN_DISTANCE, MAX_OBSTACLE_EXTENT, 'm')}")
        object.__setattr__(self, "size", size)
        pose = check_rigid_transform(self.pose, f"Obstacle {self.name!r} pose")
        offset = float(np.abs(pose[:3, 3]).max())
        if offset > MAX_OBSTACLE_EXTENT:
            raise CollisionSceneError(
                f"Obstacle {self.name!r}: centre {pose[:3, 3].tolist()} m lies {offset:g} m from the table frame's "
                f"origin along an axis, beyond {MAX_OBSTACLE_EXTENT:g} m{unit_slip(offset, 0.0, MAX_OBSTACLE_EXTENT, 'm')}")
        object.__setattr__(self, "pose", pose)

    @classmethod
    def box(cls, name: str, size, center=(0.0, 0.0, 0.0), rotation=None) -> "Obstacle":
        """An axis-aligned (or rotated) box of full extents ``size`` (m) centred at ``center`` (table frame)."""
        return cls(name, "box", size, _pose(center, rotation))

    @classmethod
    def capsule(cls, name: str, radius: float, length: float, center=(0.0, 0.0, 0.0), rotation=None) -> "Obstacle":
        """A capsule (cylinder of ``length`` along its Z with hemispherical caps of ``radius``), metres."""
        return cls(name, "capsule", (radius, length), _pose(center, rotation))

    def geometry(self) -> coal.CollisionGeometry:
        """The coal primitive of this obstacle."""
        if self.shape == "box":
            return coal.Box(*self.size)
        if self.shape == "capsule":
            return coal.Capsule(*self.size)
        if self.shape == "cylinder":
            return coal.Cylinder(*self.size)
        return coal.Sphere(self.size[0])


def _pose(center, rotation) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = real_array(center, "Obstacle center", (3,), error=CollisionSceneError, unit="m")
    if rotation is not None:
        T[:3, :3] = real_array(rotation, "Obstacle rotation", (3, 3), error=CollisionSceneError)
    return T


def link_of(geometry_name: str) -> str:
    """Link name of a geometry created from a URDF (``<link>_<k>`` → ``<link>``); obstacles keep their name."""
    stem, _, index = geometry_name.rpartition("_")
    return stem if stem and index.isdigit() else geometry_name


def carm_pair_names(geometry_names: Sequence[str], obstacle_names: Sequence[str] = ()) -> list[tuple[str, str]]:
    """The documented pair list of the C-arm model: every moving part against table, obstacles and floor."""
    moving = [g for g in geometry_names if link_of(g) in CARM_MOVING_LINKS or _moving_mount_body(link_of(g))]
    environment = [g for g in geometry_names if link_of(g) in CARM_ENVIRONMENT_LINKS] + list(obstacle_names)
    excluded = set(CARM_EXCLUDED_PAIRS)
    return [(m, e) for m in moving for e in environment if (link_of(m), link_of(e)) not in excluded]


def _moving_mount_body(link: str) -> bool:
    """Whether ``link`` is a moving body of a mount (``mount_body_k``, k ≥ 1; k = 0 is the fixed pedestal)."""
    stem, _, k = link.rpartition("_")
    return stem == "mount_body" and k.isdigit() and k != "0"


def as_obstacles(patient, error: type[CarmkinError] = PatientModelError) -> tuple:
    """What ``patient=`` accepts everywhere (the world, views, sweeps) as a tuple of :class:`Obstacle`:
    ``None`` (empty), one obstacle, a list of them, or a patient model with ``obstacles()``
    (:class:`~carmkin.patient.ParametricPatient`, :class:`~carmkin.patient.CTPatient`); else ``error``."""
    if patient is None:
        return ()
    if hasattr(patient, "obstacles") and callable(patient.obstacles):
        patient = patient.obstacles()
    if isinstance(patient, Obstacle):
        patient = [patient]
    expected = "a patient model (ParametricPatient, CTPatient) or a list of carmkin.robot.collision.Obstacle"
    if isinstance(patient, (str, bytes, dict)):
        raise error(f"patient must be {expected}, got {type(patient).__name__}")
    try:
        items = tuple(patient)
    except TypeError:
        raise error(f"patient must be {expected}, got {type(patient).__name__}") from None
    for item in items:
        if not isinstance(item, Obstacle):
            raise error(f"patient must be {expected}, got an item {type(item).__name__}")
    return items
