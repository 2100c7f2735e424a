"""Clearance of a configuration, exact where it decides: bounding spheres first, coal only for near pairs.

:class:`World` holds one :class:`carmkin.robot.collision.CollisionScene` of a system with the patient (and
any other obstacles), built once. Its :meth:`World.clearance` is the exact minimum signed distance (m) over
the scene's pairs, found by branch and bound: every geometry's local AABB sphere gives a lower bound
``|c1 − c2| − r1 − r2`` for each pair; coal computes pairs in increasing order of that bound and stops when
the smallest exact distance so far is below the next bound — the result equals the minimum over all pairs
(the tests compare it with a fresh scene's full computation). Written here because coal's broad phase
answers "which pairs collide", not "the smallest distance of a fixed pair list" at this cost.

:meth:`World.beam_bound` is the cheap ranking score of the view search: a lower bound on the distance of
the source housing and of the detector (spheres about the beam axis) to the fixed environment (table top and
obstacles), vectorised over source positions. Lengths in m.
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
        self.joints_used = [(j, np.flatnonzero(self.parent == j)) for j in np.unique(self.parent).tolist()]
        # Pairs against a body fixed to the table frame get the exact distance from the moving sphere's centre
        # to that body as their bound (a 2 m table top's own sphere would bound nothing): boxes one by one,
        # capsules and spheres all at once as segments.
        self._boxes, seg_pairs, seg = [], [], []
        for g in np.unique(self.second).tolist():
            o = objects[g]
            if o.parentJoint != 0:
                continue
            ks = np.flatnonzero(self.second == g)
            kind = type(o.geometry).__name__
            if kind == "Box":
                self._boxes.append((o, ks))
            elif kind in ("Capsule", "Sphere"):
                half = o.geometry.halfLength if kind == "Capsule" else 0.0
                axis = o.placement.rotation[:, 2] * half
                for k in ks.tolist():
                    seg_pairs.append(k)
                    seg.append((o.placement.translation - axis, 2 * axis, o.geometry.radius))
        self._seg_pairs = np.array(seg_pairs, dtype=int)
        self._seg_a = np.array([a for a, _, _ in seg]).reshape(-1, 3)
        self._seg_v = np.array([v for _, v, _ in seg]).reshape(-1, 3)
        self._seg_vv = np.maximum(np.einsum("ij,ij->i", self._seg_v, self._seg_v), 1e-300)
        self._seg_r = np.array([r for _, _, r in seg])
        self._beam_parts = self._beam_spheres(objects)
        self._inscribed = self._inscribed_spheres(objects)
        names = {o.name for o in self.obstacles}
        self._environment = [o for o in objects if o.name in names or link_of(o.name) == "table"]

    # --- exact clearance ---------------------------------------------------------------------------------
    def clearance(self, q, stop_below: float = -np.inf) -> tuple[float, int]:
        """``(distance, pair index)``: the exact smallest signed distance (m) over the scene's pairs at q; with
        ``stop_below``, the first pair found closer than it ends the search (a distance below it, not the
        smallest)."""
        pin.forwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        pin.updateGeometryPlacements(self.model, self.data, self.scene.geometry_model, self.scene.geometry_data)
        world = np.empty_like(self.centres)
        for j, sel in self.joints_used:
            M = self.data.oMi[j]
            world[sel] = self.centres[sel] @ M.rotation.T + M.translation
        bound = np.linalg.norm(world[self.first] - world[self.second], axis=1) - self.pair_radius
        for obj, ks in self._boxes:
            first = self.first[ks]
            bound[ks] = _point_distance(obj, world[first]) - self.radii[first]
        if len(self._seg_pairs):
            first = self.first[self._seg_pairs]
            w = world[first] - self._seg_a
            t = np.clip(np.einsum("ij,ij->i", w, self._seg_v) / self._seg_vv, 0.0, 1.0)
            bound[self._seg_pairs] = (np.linalg.norm(w - t[:, None] * self._seg_v, axis=1) - self._seg_r
                                      - self.radii[first])
        order = np.argsort(bound)
        best, which = np.inf, -1
        gm, gd = self.scene.geometry_model, self.scene.geometry_data
        for k in order.tolist():
            if bound[k] >= best:
                break
            d = pin.computeDistance(gm, gd, k).min_distance
            if d < best:
                best, which = d, k
                if best < stop_below:
                    break
        return float(best), which

    def pair_names(self, k: int) -> tuple[str, str]:
        return self.scene.pairs[k]

    # --- certain contacts, vectorised ---------------------------------------------------------------------
    def _inscribed_spheres(self, objects):
        """(link, centre in the link frame (3,), radius) of a sphere inside each moving box, and the fixed
        bodies (table top, obstacles) they are paired with."""
        q0 = pin.neutral(self.model)
        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, q0)
        pin.updateGeometryPlacements(self.model, data, self.scene.geometry_model, self.scene.geometry_data)
        moving = set(self.first.tolist())
        out = []
        for g in sorted(moving):
            o = objects[g]
            if type(o.geometry).__name__ != "Box":
                continue
            link = link_of(o.name)
            frame = data.oMf[self.model.getFrameId(link)]
            centre = frame.actInv(self.scene.geometry_data.oMg[g].translation)
            out.append((link, centre, float(np.min(o.geometry.halfSide))))
        return out

    def certainly_closer(self, Q: np.ndarray, margin: float) -> np.ndarray:
        """(M,) True where configuration Q[m] (M, nq) certainly has a pair closer than ``margin`` (m): a sphere
        inside a moving box is already that close to the table top or an obstacle (exact point distances).
        Link frames are the system's DH frames, source and detector frames (its closed-form FK)."""
        frames, source = _link_poses(self.system, Q)
        system = self.system
        poses = {f"dh_frame_{k + 1}": frames[:, k] for k in range(6)}
        poses["xray_source"] = source
        poses["detector"] = source @ system.detector_in_xray
        out = np.zeros(len(Q), dtype=bool)
        for link, centre, radius in self._inscribed:
            T = poses.get(link)
            if T is None:
                continue
            points = T[:, :3, :3] @ centre + T[:, :3, 3]
            for o in self._environment:
                out |= _point_distance(o, points) - radius < margin
        return out

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
            centres = sources + along * directions
            for o in self._environment:
                out = np.minimum(out, _point_distance(o, centres) - radius)
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


def _point_distance(obj, points: np.ndarray) -> np.ndarray:
    """Distance (M,) from points (table frame) to a fixed geometry: exact for boxes, capsules and spheres
    (negative inside), a lower bound (the bounding sphere) for anything else."""
    M = obj.placement
    local = (points - M.translation) @ M.rotation
    g = obj.geometry
    kind = type(g).__name__
    if kind == "Box":
        q = np.abs(local) - np.asarray(g.halfSide)
        outside = np.sqrt(np.sum(np.maximum(q, 0.0) ** 2, axis=1))
        return outside + np.minimum(np.max(q, axis=1), 0.0)
    if kind == "Capsule":
        local[:, 2] -= np.clip(local[:, 2], -g.halfLength, g.halfLength)
        return np.sqrt(np.sum(local ** 2, axis=1)) - g.radius
    if kind == "Sphere":
        return np.linalg.norm(local, axis=1) - g.radius
    g.computeLocalAABB()
    return np.linalg.norm(local - np.asarray(g.aabb_center), axis=1) - g.aabb_radius
