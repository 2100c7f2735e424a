"""Distances between the C-arm and its surroundings, for colouring the viewer.

The pairs are those of the one world (:class:`carmkin.world.World`: every moving C-arm
part against the table top, the patient's bodies and the floor, the column against the floor left out), the same pairs the
planner and the §4.4.3 validity report use: what the screen paints red is what validity calls a collision.
Signed distances (coal through Pinocchio), metres, witness points in the table frame 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from carmkin.errors import InvalidConfigurationError
from carmkin.model.kinematics import check_configuration
from carmkin.model.system import CArmSystem
from carmkin.world import World


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


class DistanceChecker:
    """Signed distances of the C-arm parts to the table top, the floor and the patient, if any (table frame,
    metres; ``patient`` as :class:`carmkin.world.World` takes it).

    ``scene`` is the :class:`carmkin.world.World` of the system and patient; ``collision_model`` and
    ``collision_data`` are its geometry model and data, placed at the configuration of the last call.
    """

    def __init__(self, system: CArmSystem, patient=None) -> None:
        self.scene = World(system, patient)
        self.model = self.scene.model
        self.collision_model = self.scene.geometry_model
        self.collision_data = self.scene.geometry_data
        self._data = self.model.createData()  # reused by every call given q

    def distances(self, q=None, *, data: pin.Data | None = None) -> list[PairDistance]:
        """All pair distances, in pair order, at configuration ``q`` (nq,) (m, rad), or at the configuration
        whose forward kinematics is already in ``data`` (no second FK)."""
        if (q is None) == (data is None):
            raise InvalidConfigurationError("DistanceChecker.distances takes q or data, exactly one of them")
        if data is None:
            q = check_configuration(q, self.model.nq)
            if q.ndim != 1:
                raise InvalidConfigurationError(f"q must have shape ({self.model.nq},), got {q.shape}")
            data = self._data
            pin.forwardKinematics(self.model, data, q)
        distances = self.scene.distances(data)
        near = self.scene.proximity(distances, np.inf)  # witness points of every pair
        return [PairDistance(a, b, float(d), p1, p2)
                for (a, b), d, p1, p2 in zip(self.scene.pairs, distances, near.point1, near.point2)]


def distance_color(distance: float, margin: float) -> tuple[float, float, float]:
    """Red at contact or penetration (distance <= 0), through orange to yellow at ``margin`` (m)."""
    t = float(np.clip(distance / margin, 0.0, 1.0)) if distance > 0 else 0.0
    return (1.0, 0.85 * t, 0.0)
