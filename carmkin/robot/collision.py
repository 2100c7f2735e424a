"""Collision scene: coal distances between C-arm parts and the environment (table, floor, obstacles).

The collision model of :meth:`CArmSystem.pinocchio` holds one coal primitive (box) per URDF ``<collision>``
element, named ``<link>_<k>``. :class:`CollisionScene` copies it, adds user obstacles (e.g. a patient
volume) fixed to the table frame 0, and keeps only the pairs that matter (:func:`carm_pair_names`):

* every **moving C-arm part** — the links carried by the vertical joint and beyond: ``dh_frame_2``
  (column), ``dh_frame_3`` (arm sleeve), ``dh_frame_4`` (inner arm), ``dh_frame_5`` (orbital guide),
  ``dh_frame_6`` (C segments), ``xray_source`` (tube housing), ``detector`` (detector and bracket) —
* against every **environment body**: ``table`` (table top), each obstacle, and ``floor``.

Excluded on purpose: pairs inside the C-arm (the telescoping sleeve/inner arm, the column in the cart and
neighbouring links overlap by construction), the table against the cart and the floor (they only slide
past each other along Z0; the table translation range is the user's statement that this is allowed), and
the column against the floor (the column stands in the cart, on the floor).

Distances are signed (negative = penetration depth), in metres, witness points and normals in the table
frame 0 (the root, ``universe``). The normal points from the first object of a pair to the second.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import coal
import numpy as np
import pinocchio as pin

from carmkin.errors import (
    CollisionSceneError,  # noqa: F401 (defined there, raised here)
)
from carmkin.transforms import check_rigid_transform
from carmkin.validation import real_array

#: Links of the C-arm that move with the vertical joint or later joints (collision candidates).
CARM_MOVING_LINKS = ("dh_frame_2", "dh_frame_3", "dh_frame_4", "dh_frame_5", "dh_frame_6", "xray_source", "detector")
#: Environment links of the generated URDF that the moving parts must not touch.
CARM_ENVIRONMENT_LINKS = ("table", "floor")
#: (moving link, environment link) pairs left out: the column stands in the cart on the floor.
CARM_EXCLUDED_PAIRS = (("dh_frame_2", "floor"),)


@dataclass(frozen=True)
class Obstacle:
    """A rigid obstacle fixed to the table frame 0, e.g. the patient volume.

    Attributes:
        name: unique geometry name (reported in collisions).
        shape: ``"box"`` (size = full extents x, y, z), ``"capsule"`` (size = radius, length along Z),
            ``"sphere"`` (size = radius) or ``"cylinder"`` (size = radius, length along Z); metres.
        pose: 4x4 pose of the shape's centre frame in the table frame 0.
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
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "pose", check_rigid_transform(self.pose, f"Obstacle {self.name!r} pose"))

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
    moving = [g for g in geometry_names if link_of(g) in CARM_MOVING_LINKS]
    environment = [g for g in geometry_names if link_of(g) in CARM_ENVIRONMENT_LINKS] + list(obstacle_names)
    excluded = set(CARM_EXCLUDED_PAIRS)
    return [(m, e) for m in moving for e in environment if (link_of(m), link_of(e)) not in excluded]


@dataclass
class Proximity:
    """Near pairs of one configuration (arrays over the K pairs closer than the query threshold).

    ``index`` (K,) pair indices into :attr:`CollisionScene.pairs`; ``distance`` (K,) signed (m);
    ``point1``/``point2`` (K, 3) witness points on the first/second object and ``normal`` (K, 3) unit
    normal from the first to the second object, all in the table frame 0.
    """

    index: np.ndarray
    distance: np.ndarray
    point1: np.ndarray
    point2: np.ndarray
    normal: np.ndarray


class CollisionScene:
    """A Pinocchio collision model restricted to chosen pairs, plus obstacles, with reusable data.

    ``model`` is the kinematic model, ``geometry_model`` its collision model (copied, not modified);
    ``pairs`` are (name, name) geometry pairs; ``obstacles`` are fixed to the root joint (frame ``root``).
    """

    def __init__(
        self,
        model: pin.Model,
        geometry_model: pin.GeometryModel,
        pairs: Sequence[tuple[str, str]] = (),
        obstacles: Sequence[Obstacle] = (),
        root: str | None = None,
    ) -> None:
        self.model = model
        self.geometry_model = geometry_model.copy()
        self.geometry_model.removeAllCollisionPairs()
        root_frame = model.getFrameId(root) if root is not None else 0
        names = {g.name for g in self.geometry_model.geometryObjects}
        for obstacle in obstacles:
            if not isinstance(obstacle, Obstacle):
                raise CollisionSceneError(
                    f"obstacles must be carmkin.robot.collision.Obstacle, got {type(obstacle).__name__}"
                )
            if obstacle.name in names:
                raise CollisionSceneError(f"obstacle name {obstacle.name!r} is already used by a geometry")
            names.add(obstacle.name)
            self.geometry_model.addGeometryObject(
                pin.GeometryObject(obstacle.name, 0, root_frame, pin.SE3(obstacle.pose), obstacle.geometry())
            )
        self.obstacles = tuple(obstacles)
        index = {g.name: i for i, g in enumerate(self.geometry_model.geometryObjects)}
        for a, b in pairs:
            for n in (a, b):
                if n not in index:
                    raise CollisionSceneError(
                        f"collision pair ({a!r}, {b!r}): no geometry named {n!r}; known: {sorted(index)}"
                    )
            self.geometry_model.addCollisionPair(pin.CollisionPair(index[a], index[b]))
        self.pairs: tuple[tuple[str, str], ...] = tuple(tuple(p) for p in pairs)
        self.geometry_data = pin.GeometryData(self.geometry_model)
        for request in self.geometry_data.distanceRequests:
            request.enable_signed_distance = True
        # One Python handle per result, taken once: they stay live views of geometry_data's results, and
        # iterating the C++ vector afresh at every query costs ~8x the reads themselves (29 pairs: 60 vs 7 µs).
        self._results = list(self.geometry_data.distanceResults)
        objects = self.geometry_model.geometryObjects
        pair_objects = [(objects[p.first], objects[p.second]) for p in self.geometry_model.collisionPairs]
        self.joints = np.array([[o1.parentJoint, o2.parentJoint] for o1, o2 in pair_objects], dtype=int).reshape(-1, 2)
        # (n_pairs, nv) masks: columns of the joints that move each object (its support).
        self._support = np.zeros((2, len(self.pairs), model.nv))
        for k in range(len(self.pairs)):
            for side in range(2):
                for j in model.supports[int(self.joints[k, side])][1:]:
                    idx, nvj = model.joints[j].idx_v, model.joints[j].nv
                    self._support[side, k, idx : idx + nvj] = 1.0

    @classmethod
    def from_system(cls, system, obstacles: Sequence[Obstacle] = ()) -> "CollisionScene":
        """The C-arm scene of ``system`` with the documented pair list (:func:`carm_pair_names`)."""
        if obstacles is None or isinstance(obstacles, (str, bytes, dict)) or not all(
                isinstance(o, Obstacle) for o in obstacles):
            raise CollisionSceneError(
                f"obstacles must be a list of carmkin.robot.collision.Obstacle, got {obstacles!r}")
        model, geometry_model, _ = system.pinocchio()
        names = [g.name for g in geometry_model.geometryObjects]
        return cls(model, geometry_model, carm_pair_names(names, [o.name for o in obstacles]), obstacles, root="table")

    def __len__(self) -> int:
        return len(self.pairs)

    def link_pairs(self) -> list[tuple[str, str]]:
        """The pairs by link name (obstacles by their name), in the order of :attr:`pairs`."""
        return [(link_of(a), link_of(b)) for a, b in self.pairs]

    def update(self, data: pin.Data) -> None:
        """Place the geometries after a forward-kinematics pass stored in ``data``."""
        pin.updateGeometryPlacements(self.model, data, self.geometry_model, self.geometry_data)

    def distances(self, data: pin.Data | None = None, q=None) -> np.ndarray:
        """Signed distance (m) of every pair (n_pairs,); pass ``q`` to run forward kinematics first."""
        if q is not None:
            data = data if data is not None else self.model.createData()
            pin.forwardKinematics(self.model, data, np.asarray(q, dtype=float))
        if data is None:
            raise CollisionSceneError("distances() needs data after forward kinematics, or q")
        self.update(data)
        if not self.pairs:
            return np.zeros(0)
        pin.computeDistances(self.geometry_model, self.geometry_data)
        return np.array([r.min_distance for r in self._results])

    def proximity(self, distances: np.ndarray, threshold: float) -> Proximity:
        """Witness points and normals of the pairs with ``distance < threshold`` (broad-phase cut)."""
        near = np.flatnonzero(distances < threshold)
        results = [self._results[k] for k in near.tolist()]
        p1 = np.array([r.getNearestPoint1() for r in results]).reshape(-1, 3)
        p2 = np.array([r.getNearestPoint2() for r in results]).reshape(-1, 3)
        normal = np.array([r.normal for r in results]).reshape(-1, 3)
        return Proximity(near, distances[near], p1, p2, normal)

    def distance_jacobian(self, proximity: Proximity, J_world: np.ndarray) -> np.ndarray:
        """Rows (K, nv) of d(distance)/dq of the near pairs.

        ``J_world`` is ``data.J`` after :func:`pinocchio.computeJointJacobians` (6, nv): spatial Jacobian
        in the world (table) frame, so the velocity of a point p on a body is ``Jv + Jw × p`` restricted
        to the body's support. ``d' = n · (v(p2) - v(p1))``.
        """
        n, k = proximity.normal, proximity.index
        p = np.concatenate((proximity.point2, proximity.point1))
        nn = np.concatenate((n, n))
        # [n, p × n] @ J, for both witness points at once (cross product written out: np.cross is slow).
        wrench = np.empty((2 * len(k), 6))
        wrench[:, :3] = nn
        wrench[:, 3] = p[:, 1] * nn[:, 2] - p[:, 2] * nn[:, 1]
        wrench[:, 4] = p[:, 2] * nn[:, 0] - p[:, 0] * nn[:, 2]
        wrench[:, 5] = p[:, 0] * nn[:, 1] - p[:, 1] * nn[:, 0]
        rows = wrench @ J_world
        return rows[: len(k)] * self._support[1, k] - rows[len(k) :] * self._support[0, k]
