"""Clearance between two C-arms in one table frame: every link of one against every link of the other.

Two :class:`~carmkin.world.World` s whose systems share the table frame 0 (the two planes of a biplane,
:mod:`carmkin.biplane`) each place their own geometries (the world's models, one forward-kinematics pass
per configuration); :class:`Between` measures coal's signed distance of every pair (one geometry of each
world's :data:`BODY_LINKS`). The table and the floor are not a plane's own: each world already checks its
C-arm against them, so they are left out here.

For many configurations, :meth:`Between.nearest` visits the pairs in the order of a cheap lower bound (the
distance of the geometries' bounding spheres, less coal's own tolerance
:data:`~carmkin.world.tolerances.BOUND_SLACK`) and stops where that bound passes the smallest exact distance
found: the answer is the exact minimum over all pairs. Distances in metres (negative: penetration depth).
"""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin

from carmkin.errors import CollisionSceneError

from .obstacles import CARM_MOVING_LINKS, link_of
from .tolerances import BOUND_SLACK

#: The links of one C-arm measured against the other's: its base (cart or stand) and every moving part.
BODY_LINKS = ("carm_cart", *CARM_MOVING_LINKS)


def _radius(geometry) -> float:
    """Radius (m) of a sphere about the geometry's frame origin that holds it (a box's half diagonal)."""
    if isinstance(geometry, coal.Box):
        return float(np.linalg.norm(geometry.halfSide))
    geometry.computeLocalAABB()
    box = geometry.aabb_local
    return float(max(np.linalg.norm(box.min_), np.linalg.norm(box.max_)))


class _Side:
    """One world's measured geometries: indices, coal shapes, bounding radii, and its own model data."""

    def __init__(self, world, links) -> None:
        self.world = world
        objects = world.geometry_model.geometryObjects
        self.index = [i for i, g in enumerate(objects) if link_of(g.name) in links]
        self.names = [objects[i].name for i in self.index]
        self.shapes = [objects[i].geometry for i in self.index]
        self.radius = np.array([_radius(s) for s in self.shapes])
        self.data = world.model.createData()
        self.geometry_data = pin.GeometryData(world.geometry_model)

    def place(self, q) -> tuple[list, np.ndarray]:
        """coal transforms of the geometries at ``q`` and their origins (n, 3), table frame."""
        pin.forwardKinematics(self.world.model, self.data, q)
        pin.updateGeometryPlacements(self.world.model, self.data, self.world.geometry_model, self.geometry_data)
        placements = [self.geometry_data.oMg[i] for i in self.index]
        return ([coal.Transform3s(p.rotation, p.translation) for p in placements],
                np.array([p.translation for p in placements]).reshape(-1, 3))


class Between:
    """The pairs of ``world_a``'s and ``world_b``'s :data:`BODY_LINKS` geometries (``pairs``: geometry names,
    those of ``world_a`` first); both worlds' systems in one table frame."""

    def __init__(self, world_a, world_b, links=BODY_LINKS) -> None:
        from carmkin.validation import instance

        from .world import World

        for name, world in (("world_a", world_a), ("world_b", world_b)):
            instance(world, World, name, error=CollisionSceneError, hint="carmkin.world.World(system, patient)")
        if not isinstance(links, (list, tuple)) or not links or not all(isinstance(n, str) for n in links):
            raise CollisionSceneError(f"Between: links must be a list of link names (e.g. {', '.join(BODY_LINKS[:2])}), "
                                      f"got {links!r:.60}")
        self._sides = (_Side(world_a, links), _Side(world_b, links))
        a, b = self._sides
        if not a.index or not b.index:
            raise CollisionSceneError(f"Between: no geometry of the links {', '.join(links)} in one of the worlds")
        self.pairs: tuple[tuple[str, str], ...] = tuple((x, y) for x in a.names for y in b.names)
        self._request = coal.DistanceRequest()
        self._request.enable_signed_distance = True

    def __len__(self) -> int:
        return len(self.pairs)

    def _distance(self, i: int, j: int, tf_a, tf_b) -> float:
        a, b = self._sides
        result = coal.DistanceResult()
        return float(coal.distance(a.shapes[i], tf_a[i], b.shapes[j], tf_b[j], self._request, result))

    def distances(self, q_a, q_b) -> np.ndarray:
        """Signed distance (m) of every pair (n_pairs,) at ``q_a`` and ``q_b`` (each world's nq,)."""
        a, b = self._sides
        tf_a, _ = a.place(self._q(q_a, 0))
        tf_b, _ = b.place(self._q(q_b, 1))
        return np.array([self._distance(i, j, tf_a, tf_b) for i in range(len(a.index)) for j in range(len(b.index))])

    def pair_distances(self, q_a, q_b, pairs) -> np.ndarray:
        """Signed distances (m) of the pairs ``pairs`` (K,) (indices into :attr:`pairs`) at ``q_a`` and ``q_b``."""
        a, b = self._sides
        tf_a, _ = a.place(self._q(q_a, 0))
        tf_b, _ = b.place(self._q(q_b, 1))
        nb = len(b.index)
        return np.array([self._distance(k // nb, k % nb, tf_a, tf_b) for k in np.asarray(pairs).tolist()], dtype=float)

    def rates(self) -> tuple[np.ndarray, np.ndarray]:
        """``(R_a (n_pairs, nv_a), R_b (n_pairs, nv_b))``: how fast each pair's first and second geometry can move
        per unit rate of its own world's joints (:func:`carmkin.world.swept.geometry_rates`)."""
        from .swept import geometry_rates

        a, b = self._sides
        ra, rb = geometry_rates(a.world)[a.index], geometry_rates(b.world)[b.index]
        nb = len(b.index)
        return np.repeat(ra, nb, axis=0), np.tile(rb, (len(a.index), 1))

    def nearest(self, Q_a, Q_b) -> tuple[np.ndarray, np.ndarray]:
        """``(distance (N,), pair (N,))``: the exact smallest signed distance (m) over the pairs of each row of
        ``Q_a`` (N, nq_a) and ``Q_b`` (N, nq_b), and the index into :attr:`pairs` that holds it."""
        a, b = self._sides
        Q_a, Q_b = np.atleast_2d(self._q(Q_a, 0)), np.atleast_2d(self._q(Q_b, 1))
        if len(Q_a) != len(Q_b):
            raise CollisionSceneError(f"Q_a and Q_b must hold as many configurations, got {len(Q_a)} and {len(Q_b)}")
        nb = len(b.index)
        gap = a.radius[:, None] + b.radius[None, :]
        out, where = np.empty(len(Q_a)), np.empty(len(Q_a), dtype=int)
        for n, (qa, qb) in enumerate(zip(Q_a, Q_b)):
            tf_a, o_a = a.place(qa)
            tf_b, o_b = b.place(qb)
            bound = (np.linalg.norm(o_a[:, None] - o_b[None], axis=-1) - gap).ravel() - BOUND_SLACK
            best, arg = np.inf, -1
            for k in np.argsort(bound, kind="stable").tolist():
                if bound[k] >= best:
                    break
                d = self._distance(k // nb, k % nb, tf_a, tf_b)
                if d < best:
                    best, arg = d, k
            out[n], where[n] = best, arg
        return out, where

    def clearance(self, Q_a, Q_b) -> np.ndarray:
        """(N,) the exact smallest signed distance (m) over the pairs (:meth:`nearest`)."""
        return self.nearest(Q_a, Q_b)[0]

    def _q(self, q, side: int) -> np.ndarray:
        from carmkin.validation import JOINT_VALUE_LIMIT, real_array

        model = self._sides[side].world.model
        name = f"q of world {'ab'[side]}"
        q = real_array(q, name, error=CollisionSceneError, limit=JOINT_VALUE_LIMIT, unit="m, rad")
        if q.shape[-1:] != (model.nq,) or q.ndim > 2:
            raise CollisionSceneError(f"{name} must be finite with {model.nq} joints per row, got shape {q.shape}")
        return q
