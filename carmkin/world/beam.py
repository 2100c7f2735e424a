"""The beam screen of the view search: cheap lower bounds for the parts rigid with the X-ray source.

:meth:`BeamScreen.bound` is the ranking score of the view search (:mod:`carmkin.views.search`): a lower bound
on the distance of the source housing and of the detector (spheres about the beam axis) to the fixed
environment (table top and obstacles), vectorised over source positions. :attr:`BeamScreen.roll_lever`
serves the certified contact regions of :mod:`carmkin.views.regions`. Written here, beside the world's
other bounds, because it is a bound on the world's distances; exact answers always come from
:meth:`carmkin.world.World.nearest`. Lengths in m, table frame 0.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .obstacles import link_of
from .swept import bounding_radius

#: Shapes coal treats as convex (the point-distance shapes of :mod:`carmkin.world.bounds` and these).
_CONVEX_SHAPES = ("Box", "Capsule", "Sphere", "Cylinder", "Cone", "Ellipsoid")
#: Frame of the X-ray source.
SOURCE_FRAME = "xray_source"


class BeamScreen:
    """Bounds for the parts of ``world`` that ride with the source (built once per world)."""

    def __init__(self, world) -> None:
        self.world = world
        model, geometry_model = world.model, world.geometry_model
        objects = geometry_model.geometryObjects
        names = {o.name for o in world.obstacles}
        self._environment = _Fixed([o for o in objects if o.name in names or link_of(o.name) == "table"])
        # Every geometry's pose in the source frame at the zero configuration (for the beam spheres and levers).
        data, geometry = model.createData(), pin.GeometryData(geometry_model)
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        pin.updateGeometryPlacements(model, data, geometry_model, geometry)
        source = model.getFrameId(SOURCE_FRAME)
        in_source = [data.oMf[source].actInv(M) for M in geometry.oMg]
        self._beam_parts = self._beam_spheres(objects, in_source)
        self.roll_lever = self._roll_levers(objects, in_source, model.frames[source].parentJoint)

    def _roll_levers(self, objects, in_source, last: int) -> np.ndarray:
        """(P,) per pair: the largest distance (m) of its first geometry's points from the beam axis when that
        geometry rides on the orbital joint ``last`` (rigid with the source) and its second is a convex shape
        fixed to the table frame; inf otherwise (the pair's motion is not set by distance and roll alone).
        ``in_source``: every geometry's pose in the source frame."""
        convex = [type(o.geometry).__name__ in _CONVEX_SHAPES or type(o.geometry).__name__.startswith("Convex")
                  for o in objects]
        pairs = self.world.geometry_model.collisionPairs
        lever = np.full(len(pairs), np.inf)
        for k, pair in enumerate(pairs):
            a, b = pair.first, pair.second
            if objects[a].parentJoint != last or objects[b].parentJoint != 0 or not (convex[a] and convex[b]):
                continue
            centre = in_source[a].translation
            lever[k] = float(np.hypot(centre[0], centre[1])) + bounding_radius(objects[a].geometry)
        return lever

    # --- cheap bound for ranking ---------------------------------------------------------------------------
    @staticmethod
    def _beam_spheres(objects, in_source):
        """(offset along the beam from the source (m), radius (m)) of spheres holding the source housing and
        the detector (``in_source``: every geometry's pose in the source frame)."""
        parts = []
        for link in ("xray_source", "detector"):
            for g, o in enumerate(objects):
                if link_of(o.name) != link:
                    continue
                o.geometry.computeLocalAABB()
                local = in_source[g].act(np.asarray(o.geometry.aabb_center, dtype=float))
                parts.append((float(local[2]), float(o.geometry.aabb_radius) + float(np.hypot(local[0], local[1]))))
        return parts

    def bound(self, sources: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Lower bound (M,) on the distance (m) from the source housing and detector to the table top and the
        obstacles, for sources (M, 3) and beam directions (M, 3) in the table frame."""
        out = np.full(len(sources), np.inf)
        for along, radius in self._beam_parts:
            out = np.minimum(out, self._environment.nearest(sources + along * directions) - radius)
        return out


class _Fixed:
    """Geometries fixed to the table frame, stacked: distances (m) from points (table frame) to all of them at
    once — exact for boxes, capsules and spheres (negative inside), a lower bound (the bounding sphere) for
    anything else."""

    def __init__(self, objects) -> None:
        self.count = len(objects)
        self.R = np.array([o.placement.rotation for o in objects]).reshape(-1, 3, 3)
        self.t = np.array([o.placement.translation for o in objects]).reshape(-1, 3)
        kinds = [type(o.geometry).__name__ for o in objects]
        self.box = np.array([k == "Box" for k in kinds], dtype=bool)
        self.half = np.array([o.geometry.halfSide if k == "Box" else np.zeros(3) for o, k in zip(objects, kinds)]
                             ).reshape(-1, 3)
        self.length = np.array([o.geometry.halfLength if k == "Capsule" else 0.0 for o, k in zip(objects, kinds)])
        centre, radius = [], []
        for o, k in zip(objects, kinds):
            if k in ("Capsule", "Sphere"):
                centre.append(np.zeros(3))
                radius.append(o.geometry.radius)
            elif k == "Box":
                centre.append(np.zeros(3))
                radius.append(0.0)
            else:
                o.geometry.computeLocalAABB()
                centre.append(np.asarray(o.geometry.aabb_center, dtype=float))
                radius.append(o.geometry.aabb_radius)
        self.centre, self.radius = np.array(centre).reshape(-1, 3), np.array(radius)

    def to(self, k: int, points: np.ndarray) -> np.ndarray:
        """(M,) distance from points (M, 3) to object k, by components (numpy's reductions over a last axis
        of 3 are slow on long arrays)."""
        x, y, z = self.R[k].T @ (points - self.t[k]).T  # rows: contiguous components
        if self.box[k]:
            hx, hy, hz = self.half[k]
            qx, qy, qz = np.abs(x) - hx, np.abs(y) - hy, np.abs(z) - hz
            d = np.sqrt(np.maximum(qx, 0.0) ** 2 + np.maximum(qy, 0.0) ** 2 + np.maximum(qz, 0.0) ** 2)
            return d + np.minimum(np.maximum(np.maximum(qx, qy), qz), 0.0)
        cx, cy, cz = self.centre[k]
        z = z - cz
        z = z - np.clip(z, -self.length[k], self.length[k])
        return np.sqrt((x - cx) ** 2 + (y - cy) ** 2 + z ** 2) - self.radius[k]

    def nearest(self, points: np.ndarray) -> np.ndarray:
        """(M,) distance from each point (M, 3) to the nearest of the objects (inf without objects)."""
        out = np.full(len(points), np.inf)
        for k in range(self.count):
            np.minimum(out, self.to(k, points), out=out)
        return out
