"""The one collision world: a system, its table and floor, and the patient, built once.

:class:`World` answers every "how far is the C-arm from everything" question of the toolkit, written once:

* **per pair, one configuration** — :meth:`World.distances` (coal's signed distance of every pair, with
  witness points for :meth:`World.proximity` and the QP's :meth:`World.distance_jacobian`) and
  :meth:`World.grouped` (the smallest distance to the patient, the table, the floor);
* **many configurations** — :meth:`World.clearance` / :meth:`World.nearest`: bounds for every pair at once,
  coal where they decide (:mod:`carmkin.world.bounds`), exact;
* **a joint-space segment** — :meth:`World.swept`: conservative advancement with per-pair chain speed bounds
  (:mod:`carmkin.world.swept`); its ``min_distance`` is a certified lower bound of the true swept minimum;
* **joint-by-joint moves** — :meth:`World.moves`: the manual order, each move swept by :meth:`World.swept`
  (:mod:`carmkin.world.moves`).

The pairs are the documented list of :func:`carmkin.world.obstacles.carm_pair_names`: every moving C-arm part
against the table top, each obstacle and the floor. Distances are signed (negative: penetration depth), in
metres; points and normals in the table frame 0 (the root).
"""

from __future__ import annotations

import functools
import math
import weakref
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pinocchio as pin

from carmkin.errors import CollisionSceneError, InvalidConfigurationError, PatientModelError
from carmkin.model.system import require_system
from carmkin.validation import JOINT_VALUE_LIMIT, flag, plain_floats, real_array

from .obstacles import as_obstacles, carm_pair_names, link_of
from .tolerances import DEFAULT_PATH_CLEARANCE, DEFAULT_TOLERANCE

#: Groups of :meth:`World.grouped`: what the second body of a pair is.
GROUPS = ("patient", "table", "floor")


@dataclass
class Proximity:
    """Near pairs of one configuration (arrays over the K pairs closer than the query threshold).

    ``index`` (K,) pair indices into :attr:`World.pairs`; ``distance`` (K,) signed (m);
    ``point1``/``point2`` (K, 3) witness points on the first/second object and ``normal`` (K, 3) unit
    normal from the first to the second object, all in the table frame 0.
    """

    index: np.ndarray
    distance: np.ndarray
    point1: np.ndarray
    point2: np.ndarray
    normal: np.ndarray


def _threshold(value, name: str) -> float:
    """A distance threshold (m): a real number or ±inf (no NaN, bool, complex, string), or CollisionSceneError."""
    number = float(real_array(value, name, (), error=CollisionSceneError, finite=False, limit=None, unit="m"))
    if math.isnan(number):
        raise CollisionSceneError(f"{name} must be a distance (m) or ±inf, got nan")
    return number


class World:
    """The collision world of ``system`` with ``patient`` (None, a list of
    :class:`~carmkin.world.obstacles.Obstacle`, or a patient model with ``obstacles()``), built once.

    ``model`` is the system's kinematic model; ``geometry_model`` a copy of its collision model with the
    obstacles fixed to the table frame; ``pairs`` the (name, name) geometry pairs checked; ``obstacles``
    the obstacles as given."""

    def __init__(self, system, patient=None) -> None:
        require_system(system, CollisionSceneError)
        obstacles = as_obstacles(patient, PatientModelError)
        check_placement = getattr(patient, "check_placement", None)
        if callable(check_placement):  # a patient model rests on the table top (ParametricPatient)
            check_placement(system)
        self._system = system
        model, geometry_model, _ = system.pinocchio()
        self.model = model
        self.geometry_model = geometry_model.copy()
        self.geometry_model.removeAllCollisionPairs()
        root_frame = model.getFrameId("table")
        names = {g.name for g in self.geometry_model.geometryObjects}
        for obstacle in obstacles:
            if obstacle.name in names:
                raise CollisionSceneError(f"obstacle name {obstacle.name!r} is already used by a geometry")
            names.add(obstacle.name)
            self.geometry_model.addGeometryObject(
                pin.GeometryObject(obstacle.name, 0, root_frame, pin.SE3(obstacle.pose), obstacle.geometry()))
        self.obstacles = obstacles
        index = {g.name: i for i, g in enumerate(self.geometry_model.geometryObjects)}
        pairs = carm_pair_names([g.name for g in geometry_model.geometryObjects], [o.name for o in obstacles])
        for a, b in pairs:
            self.geometry_model.addCollisionPair(pin.CollisionPair(index[a], index[b]))
        self.pairs: tuple[tuple[str, str], ...] = tuple(tuple(p) for p in pairs)
        self.geometry_data = pin.GeometryData(self.geometry_model)
        for request in self.geometry_data.distanceRequests:
            request.enable_signed_distance = True
        # One Python handle per result, taken once: they stay live views of geometry_data's results, and
        # iterating the C++ vector afresh at every query costs ~8x the reads themselves (29 pairs: 60 vs 7 µs).
        self._results = list(self.geometry_data.distanceResults)
        self._data = model.createData()
        objects = self.geometry_model.geometryObjects
        pair_objects = [(objects[p.first], objects[p.second]) for p in self.geometry_model.collisionPairs]
        self.joints = np.array([[o1.parentJoint, o2.parentJoint] for o1, o2 in pair_objects], dtype=int).reshape(-1, 2)
        # (2, n_pairs, nv) masks: columns of the joints that move each object (its support).
        self._support = np.zeros((2, len(self.pairs), model.nv))
        for k in range(len(self.pairs)):
            for side in range(2):
                for j in model.supports[int(self.joints[k, side])][1:]:
                    idx, nvj = model.joints[j].idx_v, model.joints[j].nv
                    self._support[side, k, idx: idx + nvj] = 1.0
        obstacle_names = {o.name for o in obstacles}
        #: (n_pairs,) the group of each pair's second body: "patient" (any obstacle), "table" or "floor".
        self.group = tuple("patient" if b in obstacle_names else link_of(b) for _, b in self.pairs)

    def __len__(self) -> int:
        return len(self.pairs)

    @property
    def system(self):
        """The system of this world."""
        system = self._system
        return system() if isinstance(system, weakref.ref) else system

    def hold_weakly(self) -> "World":
        """Keep only a weak reference to the system (for caches keyed by the system, see
        :mod:`carmkin.model.per_system`); returns ``self``."""
        self._system = weakref.ref(self.system)
        return self

    def __repr__(self) -> str:
        return f"World({self.system.name!r}, {len(self.obstacles)} obstacles, {len(self)} pairs)"

    def link_pairs(self) -> list[tuple[str, str]]:
        """The pairs by link name (obstacles by their name), in the order of :attr:`pairs`."""
        return [(link_of(a), link_of(b)) for a, b in self.pairs]

    def pair_names(self, k: int) -> tuple[str, str]:
        """The geometry names of pair ``k``."""
        return self.pairs[k]

    # --- one configuration, every pair -------------------------------------------------------------------
    def update(self, data: pin.Data) -> None:
        """Place the geometries after a forward-kinematics pass stored in ``data``."""
        pin.updateGeometryPlacements(self.model, data, self.geometry_model, self.geometry_data)

    def distances(self, data: pin.Data | None = None, q=None) -> np.ndarray:
        """Signed distance (m) of every pair (n_pairs,); pass ``q`` (nq,) to run forward kinematics first. The
        witness points stay in :attr:`geometry_data` for :meth:`proximity` until the next call."""
        if data is not None and not isinstance(data, pin.Data):
            raise CollisionSceneError(f"data must be a pinocchio.Data after forward kinematics, got {type(data).__name__}")
        if q is not None:
            data = data if data is not None else self._data
            pin.forwardKinematics(self.model, data, self._q(q))
        if data is None:
            raise CollisionSceneError("distances() needs data after forward kinematics, or q")
        self.update(data)
        if not self.pairs:
            return np.zeros(0)
        pin.computeDistances(self.geometry_model, self.geometry_data)
        return np.array([r.min_distance for r in self._results])

    def pair_distances(self, q, pairs) -> np.ndarray:
        """Signed distances (m) of the pairs ``pairs`` (K,) (indices into :attr:`pairs`) at ``q`` (nq,): one
        forward-kinematics pass, coal on those pairs only (the others' witness points are left as they were)."""
        pin.forwardKinematics(self.model, self._data, self._q(q))
        self.update(self._data)
        gm, gd = self.geometry_model, self.geometry_data
        return np.array([pin.computeDistance(gm, gd, k).min_distance for k in np.asarray(pairs).tolist()], dtype=float)

    def _q(self, q, name: str = "q") -> np.ndarray:
        """One configuration (nq,) in m and rad, or InvalidConfigurationError naming ``name`` (a plainly valid
        float64 array passes by :func:`~carmkin.validation.plain_floats`: the swept and QP loops call this)."""
        if type(q) is np.ndarray and plain_floats(q, self.model.nq, JOINT_VALUE_LIMIT) is not None:
            return q
        return real_array(q, name, (self.model.nq,), error=InvalidConfigurationError, limit=JOINT_VALUE_LIMIT,
                          unit="m, rad")

    def grouped(self, q) -> dict[str, float]:
        """The exact smallest signed distance (m) at ``q`` (nq,) to each of :data:`GROUPS` present."""
        d = self.distances(q=self._q(q))
        out = {group: np.inf for group in GROUPS}
        for value, group in zip(d.tolist(), self.group):
            if group in out:
                out[group] = min(out[group], value)
        return {group: value for group, value in out.items() if value < np.inf}

    def proximity(self, distances: np.ndarray, threshold: float) -> Proximity:
        """Witness points and normals of the pairs with ``distance < threshold`` (after :meth:`distances`)."""
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
        return rows[: len(k)] * self._support[1, k] - rows[len(k):] * self._support[0, k]

    # --- many configurations ------------------------------------------------------------------------------
    @functools.cached_property
    def bounds(self):
        """The branch and bound over the pairs (:class:`carmkin.world.bounds.PairBounds`), built on first use."""
        from .bounds import PairBounds

        return PairBounds(self)

    def clearance(self, Q, exact_below: float = np.inf) -> np.ndarray:
        """(N,) the exact smallest signed distance (m) over the pairs of each configuration of ``Q`` (N, nq)
        (or one (nq,) configuration: shape (1,)); where it is at least ``exact_below``, a lower bound that is
        itself at least ``exact_below`` (enough to tell "clear of a margin")."""
        return self.bounds.nearest(Q, _threshold(exact_below, "exact_below"))[0]

    def nearest(self, Q, exact_below: float = np.inf, stop_below: float = -np.inf) -> tuple[np.ndarray, np.ndarray]:
        """``(distance (N,), pair (N,))``: :meth:`clearance` and the pair index that holds it (−1: no coal call);
        with ``stop_below``, the first pair found closer than it ends a configuration's search."""
        return self.bounds.nearest(Q, _threshold(exact_below, "exact_below"), _threshold(stop_below, "stop_below"))

    # --- segments and moves -------------------------------------------------------------------------------
    @functools.cached_property
    def speed_bounds(self) -> np.ndarray:
        """``S`` (n_pairs, nv): ``|∂d_k/∂q_j| ≤ S[k, j]`` for every configuration (:mod:`carmkin.world.swept`)."""
        from .swept import speed_bounds

        return speed_bounds(self)

    def swept(self, q_a, q_b, margin: float | None = None, tolerance: float = DEFAULT_TOLERANCE,
              stop_at_contact: bool = False, path_min: float = np.inf):
        """The swept clearance of the straight joint-space segment ``q_a → q_b`` (nq,):
        :func:`carmkin.world.swept.sweep` (a :class:`~carmkin.world.swept.Swept` whose ``min_distance`` is a
        certified lower bound of the true minimum, within ``tolerance`` of it)."""
        from .swept import sweep

        return sweep(self, q_a, q_b, margin, tolerance,
                     flag(stop_at_contact, "stop_at_contact", error=CollisionSceneError), _threshold(path_min, "path_min"))

    def moves(self, q_from, q_to, order: Sequence[str] | None = None, clearance: float = DEFAULT_PATH_CLEARANCE):
        """Joint-by-joint moves from ``q_from`` to ``q_to`` (nq,): :func:`carmkin.world.moves.joint_moves`."""
        from .moves import joint_moves

        return joint_moves(self, q_from, q_to, order, clearance)

    # --- the views' screen --------------------------------------------------------------------------------
    @functools.cached_property
    def beam(self):
        """The beam screen of the view search (:class:`carmkin.world.beam.BeamScreen`), built on first use."""
        from .beam import BeamScreen

        return BeamScreen(self)

