"""Clearance of configurations, exact where it decides: bounds for every pair at once, coal for the near ones.

:class:`World` holds one :class:`carmkin.robot.collision.CollisionScene` of a system with the patient (and
any other obstacles), built once. :meth:`World.clearances` is the exact minimum signed distance (m) over
the scene's pairs for many configurations, found by branch and bound. For all configurations at once
(vectorised, the link poses from the closed form) every pair gets a lower bound: the distance from the
moving shape's bounding-sphere centre to the other shape less the radius — exact point distances to boxes,
capsules and spheres (table top, floor, patient; a 2 m table top's or an 8 m floor's own sphere would bound
nothing), sphere to sphere otherwise. Then per configuration coal computes pairs in increasing order of
their bound and stops when the smallest exact distance so far is below the next bound: the result is the
minimum over all pairs (the tests compare it with a fresh scene's full computation). Written here because
coal's broad phase answers "which pairs collide", not "the smallest distance of a fixed pair list" for many
configurations at this cost.

:meth:`World.beam_bound` is the cheap ranking score of the view search: a lower bound on the distance of
the source housing and of the detector (spheres about the beam axis) to the fixed environment (table top and
obstacles), vectorised over source positions. :attr:`World.roll_lever` serves the contact regions of
:mod:`carmkin.views.regions`. Lengths in m.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from carmkin.robot.collision import CollisionScene, link_of


def _sphere(obj) -> tuple[np.ndarray, float]:
    geometry = obj.geometry
    geometry.computeLocalAABB()
    centre = obj.placement.act(np.asarray(geometry.aabb_center, dtype=float))
    return centre, float(geometry.aabb_radius)


#: Shapes whose point distance :class:`_Fixed` computes exactly.
_EXACT_SHAPES = ("Box", "Capsule", "Sphere")


class World:
    """The collision world of ``system`` with ``obstacles`` (table frame), built once."""

    def __init__(self, system, obstacles=()) -> None:
        self.system = system
        self.obstacles = tuple(obstacles)
        self.scene = CollisionScene.from_system(system, self.obstacles)
        self.model = self.scene.model
        self.data = self.model.createData()
        gm = self.scene.geometry_model
        objects = gm.geometryObjects
        spheres = [_sphere(o) for o in objects]
        self.centres = np.array([c for c, _ in spheres])  # in the parent joint's frame
        self.radii = np.array([r for _, r in spheres])
        self.parent = np.array([o.parentJoint for o in objects])
        pairs = gm.collisionPairs
        self.first = np.array([p.first for p in pairs], dtype=int)
        self.second = np.array([p.second for p in pairs], dtype=int)
        self.pair_radius = self.radii[self.first] + self.radii[self.second]
        self._joints, self._joint_of = np.unique(self.parent, return_inverse=True)
        self._joints = self._joints.tolist()
        # Each moving geometry's centre in the DH frame on its joint, so that the bounds of many configurations
        # come from the vectorised closed form (no per-configuration Pinocchio call).
        data0 = self.model.createData()
        pin.framesForwardKinematics(self.model, data0, pin.neutral(self.model))
        dh = {}
        for k in range(6):
            f = self.model.getFrameId(f"dh_frame_{k + 1}")
            dh[self.model.frames[f].parentJoint] = (k, data0.oMf[f])
        self._moving = np.flatnonzero(self.parent != 0)
        self._frame_of_moving = np.array([dh[j][0] for j in self.parent[self._moving].tolist()], dtype=int)
        self._moving_local = np.array([dh[j][1].actInv(data0.oMi[j].act(self.centres[g]))
                                       for g, j in zip(self._moving.tolist(), self.parent[self._moving].tolist())]).reshape(-1, 3)
        # Pairs against a box, capsule or sphere (the table top, the floor, the patient's parts) get the exact
        # distance from the moving sphere's centre to that body as their bound (a 2 m table top's or an 8 m
        # floor's own sphere would bound nothing); the pose of the body is fixed or follows its DH frame.
        plain = np.ones(len(self.first), dtype=bool)
        exact, body_pose, body_frame, shapes = [], [], [], []
        for g in np.unique(self.second).tolist():
            o, j = objects[g], int(self.parent[g])
            kind = type(o.geometry).__name__
            if kind not in _EXACT_SHAPES:
                continue
            ks = np.flatnonzero(self.second == g)
            plain[ks] = False
            pose = data0.oMi[j] * o.placement if j else o.placement
            frame = -1
            if j:
                frame, dh_pose = dh[j]
                pose = dh_pose.actInv(pose)
            half = np.asarray(o.geometry.halfSide, dtype=float) if kind == "Box" else np.zeros(3)
            segment = (o.geometry.halfLength if kind == "Capsule" else 0.0, 0.0 if kind == "Box" else o.geometry.radius)
            exact += ks.tolist()
            body_pose += [(pose.rotation.copy(), pose.translation.copy())] * len(ks)
            body_frame += [frame] * len(ks)
            shapes += [(kind == "Box", half, segment)] * len(ks)
        self._exact = np.array(exact, dtype=int)
        self._exact_R = np.array([R for R, _ in body_pose]).reshape(-1, 3, 3)
        self._exact_t = np.array([t for _, t in body_pose]).reshape(-1, 3)
        self._exact_frame = np.array(body_frame, dtype=int)
        self._exact_box = np.array([box for box, _, _ in shapes], dtype=bool)
        self._exact_half = np.array([h for _, h, _ in shapes]).reshape(-1, 3)
        self._exact_segment = np.array([seg for _, _, seg in shapes]).reshape(-1, 2)
        self._plain = np.flatnonzero(plain)
        self._beam_parts = self._beam_spheres(objects)
        names = {o.name for o in self.obstacles}
        environment = [o for o in objects if o.name in names or link_of(o.name) == "table"]
        self._environment = _Fixed(environment)
        self.roll_lever = self._roll_levers(objects)

    # --- exact clearance ---------------------------------------------------------------------------------
    def clearance(self, q, stop_below: float = -np.inf) -> tuple[float, int]:
        """``(distance, pair index)``: the exact smallest signed distance (m) over the scene's pairs at q; with
        ``stop_below``, the first pair found closer than it ends the search (a distance below it, not the
        smallest)."""
        d, pair = self.clearances(np.asarray(q, dtype=float)[None], stop_below)
        return float(d[0]), int(pair[0])

    def clearances(self, Q, stop_below: float = -np.inf) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`clearance` of configurations Q (M, nq): distances (M,) (m) and pair indices (M,) (−1: no
        pair). The bounds of every pair are computed for all M at once; coal then runs per configuration in
        the order of its bounds."""
        Q = np.asarray(Q, dtype=float).reshape(-1, self.model.nq)
        if not len(Q):
            return np.zeros(0), np.zeros(0, dtype=int)
        model, data = self.model, self.data
        gm, gd = self.scene.geometry_model, self.scene.geometry_data
        bound = self._bounds(Q)
        order = np.argsort(bound, axis=1)
        bound = np.take_along_axis(bound, order, axis=1)
        out, which = np.full(len(Q), np.inf), np.full(len(Q), -1)
        for i, q in enumerate(Q):
            pin.forwardKinematics(model, data, q)
            pin.updateGeometryPlacements(model, data, gm, gd)
            best, pair = np.inf, -1
            for b, k in zip(bound[i].tolist(), order[i].tolist()):
                if b >= best:
                    break
                d = pin.computeDistance(gm, gd, k).min_distance
                if d < best:
                    best, pair = d, k
                    if best < stop_below:
                        break
            out[i], which[i] = best, pair
        return out, which

    def _bounds(self, Q) -> np.ndarray:
        """(M, P) lower bounds of every pair's signed distance (m): bounding spheres, or the exact distance from
        the moving sphere's centre to a body fixed to the table frame."""
        frames, _ = _link_poses(self.system, Q)  # (M, 6, 4, 4): DH frames 1..6, the closed form
        # Components as (M, G) arrays: numpy is slow on a last axis of length 3.
        F = frames[:, self._frame_of_moving]
        c = self._moving_local
        world = np.empty((3, len(Q), len(self.centres)))
        world[:] = self.centres.T[:, None, :]
        for i in range(3):
            world[i][:, self._moving] = F[..., i, 0] * c[:, 0] + F[..., i, 1] * c[:, 1] + F[..., i, 2] * c[:, 2] + F[..., i, 3]
        bound = np.empty((len(Q), len(self.first)))
        k = self._plain
        gap = world[:, :, self.first[k]] - world[:, :, self.second[k]]
        bound[:, k] = np.sqrt(gap[0] ** 2 + gap[1] ** 2 + gap[2] ** 2) - self.pair_radius[k]
        if len(self._exact):
            first = self.first[self._exact]
            p = world[:, :, first]  # (3, M, E)
            for f in np.unique(self._exact_frame[self._exact_frame >= 0]).tolist():  # bodies on a joint (the floor)
                e = np.flatnonzero(self._exact_frame == f)
                T = frames[:, f]
                d = [p[j][:, e] - T[:, j, 3, None] for j in range(3)]
                for i in range(3):  # into frame f: Rᵀ (p − t)
                    p[i][:, e] = T[:, 0, i, None] * d[0] + T[:, 1, i, None] * d[1] + T[:, 2, i, None] * d[2]
            # Into each body's frame, then the exact point distance.
            R, t = self._exact_R, self._exact_t
            d = [p[j] - t[:, j] for j in range(3)]
            x, y, z = (R[:, 0, i] * d[0] + R[:, 1, i] * d[1] + R[:, 2, i] * d[2] for i in range(3))
            box = self._exact_box
            hx, hy, hz = self._exact_half.T
            qx, qy, qz = np.abs(x) - hx, np.abs(y) - hy, np.abs(z) - hz
            d_box = np.sqrt(np.maximum(qx, 0.0) ** 2 + np.maximum(qy, 0.0) ** 2 + np.maximum(qz, 0.0) ** 2) \
                + np.minimum(np.maximum(np.maximum(qx, qy), qz), 0.0)
            half, radius = self._exact_segment.T
            z = z - np.clip(z, -half, half)
            d_seg = np.sqrt(x * x + y * y + z * z) - radius
            bound[:, self._exact] = np.where(box, d_box, d_seg) - self.radii[first]
        return bound

    def pair_names(self, k: int) -> tuple[str, str]:
        return self.scene.pairs[k]

    def _roll_levers(self, objects) -> np.ndarray:
        """(P,) per pair: the largest distance (m) of its first geometry's points from the beam axis when that
        geometry rides on the orbital joint (rigid with the source) and its second is a convex shape fixed to
        the table frame; inf otherwise (the pair's motion is not set by distance and roll alone)."""
        from carmkin.qp.options import SOURCE_FRAME
        from carmkin.sweeps.clearance import bounding_radius

        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, pin.neutral(self.model))
        pin.updateGeometryPlacements(self.model, data, self.scene.geometry_model, self.scene.geometry_data)
        source = self.model.getFrameId(SOURCE_FRAME)
        T_source = data.oMf[source]
        last = self.model.frames[source].parentJoint
        convex = [type(o.geometry).__name__ in _EXACT_SHAPES + ("Cylinder", "Cone", "Ellipsoid")
                  or type(o.geometry).__name__.startswith("Convex") for o in objects]
        lever = np.full(len(self.first), np.inf)
        for k, (a, b) in enumerate(zip(self.first.tolist(), self.second.tolist())):
            if objects[a].parentJoint != last or objects[b].parentJoint != 0 or not (convex[a] and convex[b]):
                continue
            centre = T_source.actInv(self.scene.geometry_data.oMg[a]).translation
            lever[k] = float(np.hypot(centre[0], centre[1])) + bounding_radius(objects[a].geometry)
        return lever

    # --- cheap bound for ranking ---------------------------------------------------------------------------
    def _beam_spheres(self, objects):
        """(offset along the beam from the source (m), radius (m)) of spheres holding the source housing and
        the detector, measured at the zero configuration in the source frame."""
        from carmkin.qp.options import SOURCE_FRAME

        q0 = pin.neutral(self.model)
        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, q0)
        T_source = data.oMf[self.model.getFrameId(SOURCE_FRAME)]
        parts = []
        for link in ("xray_source", "detector"):
            for o in objects:
                if link_of(o.name) != link:
                    continue
                centre, radius = _sphere(o)
                world = data.oMi[o.parentJoint].act(centre)
                local = T_source.actInv(world)
                along = float(local[2])
                parts.append((along, radius + float(np.hypot(local[0], local[1]))))
        return parts

    def beam_bound(self, sources: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Lower bound (M,) on the distance (m) from the source housing and detector to the table top and the
        obstacles, for sources (M, 3) and beam directions (M, 3) in the table frame."""
        out = np.full(len(sources), np.inf)
        for along, radius in self._beam_parts:
            out = np.minimum(out, self._environment.nearest(sources + along * directions) - radius)
        return out


def _link_poses(system, Q):
    """DH frames 1..6 (M, 6, 4, 4) and source poses (M, 4, 4) of configurations Q (M, nq): the closed form,
    with a motorized table's motion ``Tz(d0) E(q_table)`` computed once per distinct table configuration."""
    if not system.table.joints:
        return system.dh_frames(Q), system.fk(Q)
    from carmkin.model import kinematics

    q6, q_table = system.split(Q)
    distinct, which = np.unique(q_table, axis=0, return_inverse=True)
    E = np.array([system.table_motion(v) for v in distinct])[np.ravel(which)]
    E[:, 2, 3] += q6[:, 0]
    q6 = q6.copy()
    q6[:, 0] = 0.0
    return E[:, None] @ kinematics.dh_frames(system.dh_table, q6), E @ system.closed_form.poses(q6)


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
