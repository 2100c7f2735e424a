"""Distances between the C-arm and its surroundings, for colouring the viewer (coal via Pinocchio).

Pair selection (kept simple on purpose): every collision geometry of a C-arm link (every link except
``table`` and ``floor``) against the table top (link ``table``) and against the ``floor``, except the cart
against the floor it stands on. C-arm parts are not checked against each other. This module is
for display only; planning code should use :mod:`carmkin.robot.collision`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from carmkin.errors import InvalidConfigurationError
from carmkin.model.system import CArmSystem

#: Links the C-arm is checked against.
OBSTACLE_LINKS = ("table", "floor")
#: (C-arm link, obstacle link) pairs left out: the cart stands on the floor.
EXCLUDED = (("carm_cart", "floor"),)


@dataclass(frozen=True)
class PairDistance:
    """Distance between a C-arm part and an obstacle at one configuration.

    Attributes:
        part, obstacle: collision geometry names (``<link>_<index>``, as Pinocchio names them).
        distance: signed distance (m); negative is the penetration depth.
        point_part, point_obstacle: nearest points (m) in the table frame.
    """

    part: str
    obstacle: str
    distance: float
    point_part: np.ndarray
    point_obstacle: np.ndarray

    @property
    def in_collision(self) -> bool:
        return self.distance <= 0.0


def collision_pairs(model: pin.Model, collision_model: pin.GeometryModel) -> list[tuple[int, int]]:
    """Indices ``(part, obstacle)`` of the geometry pairs checked (see the module docstring)."""
    link = [model.frames[g.parentFrame].name for g in collision_model.geometryObjects]
    parts = [i for i, name in enumerate(link) if name not in OBSTACLE_LINKS]
    obstacles = [i for i, name in enumerate(link) if name in OBSTACLE_LINKS]
    return [(p, o) for o in obstacles for p in parts if (link[p], link[o]) not in EXCLUDED]


class DistanceChecker:
    """Signed distances of the C-arm parts to the table top and the floor (table frame, metres)."""

    def __init__(self, system: CArmSystem) -> None:
        model, collision_model, _ = system.pinocchio()
        self.model = model
        self.collision_model = collision_model.copy()  # the system's models are shared and read-only
        for part, obstacle in collision_pairs(model, self.collision_model):
            self.collision_model.addCollisionPair(pin.CollisionPair(part, obstacle))
        self.data = model.createData()
        self.collision_data = pin.GeometryData(self.collision_model)

    def distances(self, q) -> list[PairDistance]:
        """All pair distances at configuration ``q`` (6,) (m, rad), in the order of the pairs."""
        q = np.asarray(q, dtype=float)
        if q.shape != (self.model.nq,) or not np.all(np.isfinite(q)):
            raise InvalidConfigurationError(f"q must be {self.model.nq} finite numbers, got {q!r}")
        pin.computeDistances(self.model, self.data, self.collision_model, self.collision_data, q)
        names = [g.name for g in self.collision_model.geometryObjects]
        out = []
        for pair, result in zip(self.collision_model.collisionPairs, self.collision_data.distanceResults):
            out.append(PairDistance(names[pair.first], names[pair.second], float(result.min_distance),
                                    np.array(result.getNearestPoint1()), np.array(result.getNearestPoint2())))
        return out


def distance_color(distance: float, margin: float) -> tuple[float, float, float]:
    """Red at contact or penetration (distance <= 0), through orange to yellow at ``margin`` (m)."""
    t = float(np.clip(distance / margin, 0.0, 1.0)) if distance > 0 else 0.0
    return (1.0, 0.85 * t, 0.0)
