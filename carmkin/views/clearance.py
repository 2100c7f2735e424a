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


#: Inscribed spheres per box axis in the certain-contact test.
INSCRIBED_PER_AXIS = 5


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
        # Pairs against a body fixed to the table frame get the exact distance from the moving sphere's centre
        # to that body as their bound (a 2 m table top's own sphere would bound nothing): boxes one by one,
        # capsules and spheres all at once as segments.
        box_pairs, box_objects, seg_pairs, seg = [], [], [], []
        for g in np.unique(self.second).tolist():
            o = objects[g]
            if o.parentJoint != 0:
                continue
            ks = np.flatnonzero(self.second == g)
            kind = type(o.geometry).__name__
            if kind == "Box":
                box_pairs += ks.tolist()
                box_objects += [o] * len(ks)
            elif kind in ("Capsule", "Sphere"):
                half = o.geometry.halfLength if kind == "Capsule" else 0.0
                axis = o.placement.rotation[:, 2] * half
                for k in ks.tolist():
                    seg_pairs.append(k)
                    seg.append((o.placement.translation - axis, 2 * axis, o.geometry.radius))
        self._box_pairs = np.array(box_pairs, dtype=int)
        self._box_set = _Fixed(box_objects)
        self._seg_pairs = np.array(seg_pairs, dtype=int)
        self._seg_a = np.array([a for a, _, _ in seg]).reshape(-1, 3)
        self._seg_v = np.array([v for _, v, _ in seg]).reshape(-1, 3)
        self._seg_vv = np.maximum(np.einsum("ij,ij->i", self._seg_v, self._seg_v), 1e-300)
        self._seg_r = np.array([r for _, _, r in seg])
        self._beam_parts = self._beam_spheres(objects)
        self._inscribed = self._inscribed_spheres(objects)
        names = {o.name for o in self.obstacles}
        self._environment = _Fixed([o for o in objects if o.name in names or link_of(o.name) == "table"])

    # --- exact clearance ---------------------------------------------------------------------------------
    def clearance(self, q, stop_below: float = -np.inf) -> tuple[float, int]:
        """``(distance, pair index)``: the exact smallest signed distance (m) over the scene's pairs at q; with
        ``stop_below``, the first pair found closer than it ends the search (a distance below it, not the
        smallest)."""
        pin.forwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        pin.updateGeometryPlacements(self.model, self.data, self.scene.geometry_model, self.scene.geometry_data)
        oMi = self.data.oMi
        H = np.array([oMi[j].homogeneous for j in self._joints])[self._joint_of]  # (G, 4, 4)
        world = np.einsum("gij,gj->gi", H[:, :3, :3], self.centres) + H[:, :3, 3]
        gap = world[self.first] - world[self.second]
        bound = np.sqrt(np.einsum("ij,ij->i", gap, gap)) - self.pair_radius
        if len(self._box_pairs):
            first = self.first[self._box_pairs]
            bound[self._box_pairs] = self._box_set.paired(world[first]) - self.radii[first]
        if len(self._seg_pairs):
            first = self.first[self._seg_pairs]
            w = world[first] - self._seg_a
            t = np.clip(np.einsum("ij,ij->i", w, self._seg_v) / self._seg_vv, 0.0, 1.0)
            w -= t[:, None] * self._seg_v
            bound[self._seg_pairs] = np.sqrt(np.einsum("ij,ij->i", w, w)) - self._seg_r - self.radii[first]
        order = np.argsort(bound)
        best, which = np.inf, -1
        gm, gd = self.scene.geometry_model, self.scene.geometry_data
        bound = bound.tolist()
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
        """Per moving box: (link, its centre in the link frame (3,), reach: the largest |c − centre| + r, the
        centres c (k, 3, link frame) and radii r (k,) of balls inside the box — spheres of its smallest half
        side and points of its surface (r = 0)). Each ball's distance to a body bounds the box's from above
        (also when they overlap: separating the box needs at least the ball's depth)."""
        q0 = pin.neutral(self.model)
        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, q0)
        pin.updateGeometryPlacements(self.model, data, self.scene.geometry_model, self.scene.geometry_data)
        moving = set(self.first.tolist())
        out = []
        # The source housing and the detector first: they touch most often, and the test stops at a contact.
        for g in sorted(moving, key=lambda g: (link_of(objects[g].name) not in ("xray_source", "detector"), g)):
            o = objects[g]
            if type(o.geometry).__name__ != "Box":
                continue
            link = link_of(o.name)
            box = data.oMf[self.model.getFrameId(link)].actInv(self.scene.geometry_data.oMg[g])
            half = np.asarray(o.geometry.halfSide, dtype=float)
            radius = float(np.min(half))
            # Spheres of the smallest half side, spread over the box (at most INSCRIBED_PER_AXIS a side, spaced
            # by at most their radius): each is inside the box, so each one's distance is an upper bound.
            axes = [np.linspace(-(h - radius), h - radius, min(INSCRIBED_PER_AXIS, int(np.ceil((h - radius)
                    / radius)) + 1) if h - radius > 1e-12 else 1) for h in half]
            offsets = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
            # And the box's corners, edge middles and face centres (points of the box: radius 0).
            surface = np.stack(np.meshgrid(*[(-h, 0.0, h) for h in half], indexing="ij"), axis=-1).reshape(-1, 3)
            surface = surface[np.any(surface != 0, axis=1)]
            offsets = np.vstack((offsets, surface))
            radii = np.r_[np.full(len(offsets) - len(surface), radius), np.zeros(len(surface))]
            reach = float(np.max(np.linalg.norm(offsets, axis=1) + radii))
            out.append((link, box.translation, reach, offsets @ box.rotation.T + box.translation, radii))
        return out

    def certainly_closer(self, Q: np.ndarray, margin: float) -> np.ndarray:
        """(M,) True where configuration Q[m] (M, nq) certainly has a pair closer than ``margin`` (m): a ball
        inside a moving box is already that close to the table top or an obstacle (exact point distances).
        Link frames are the system's DH frames, source and detector frames (its closed-form FK)."""
        frames, source = _link_poses(self.system, Q)
        system = self.system
        poses = {f"dh_frame_{k + 1}": frames[:, k] for k in range(6)}
        poses["xray_source"] = source
        poses["detector"] = source @ system.detector_in_xray
        out = np.zeros(len(Q), dtype=bool)
        live = np.arange(len(Q))
        for link, middle, reach, centres, radii in self._inscribed:
            T = poses.get(link)
            if T is None or not len(live):
                continue
            # A sphere (centre c, radius r) can only be within the margin where the box's centre is within
            # margin + |c − centre| + r ≤ margin + reach of the environment.
            T = T[live]
            middles = T[:, :3, :3] @ middle + T[:, :3, 3]
            environment = self._environment
            for k in range(environment.count):
                near = np.flatnonzero(environment.to(k, middles) - reach < margin)
                near = near[~out[live[near]]]
                if len(near):
                    Tn = T[near]
                    points = np.swapaxes(Tn[:, :3, :3] @ centres.T, 1, 2) + Tn[:, None, :3, 3]
                    d = environment.to(k, points.reshape(-1, 3)).reshape(len(near), len(radii))
                    out[live[near[np.any(d - radii < margin, axis=1)]]] = True
            live = live[~out[live]]
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

    def paired(self, points: np.ndarray) -> np.ndarray:
        """(K,) distance from point k (K, 3) to object k (one object per point, K = the object count; boxes
        only)."""
        q = np.abs(np.einsum("kd,kdj->kj", points - self.t, self.R)) - self.half
        return np.sqrt(np.einsum("kj,kj->k", *(np.maximum(q, 0.0),) * 2)) + np.minimum(q.max(axis=1), 0.0)
