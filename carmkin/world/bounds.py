"""Clearance of many configurations at once: bounds for every pair, exact coal distances where they decide.

:class:`PairBounds` serves :meth:`carmkin.world.World.clearance` and :meth:`~carmkin.world.World.nearest`. For every
configuration and pair it computes a **lower bound** of the pair's signed distance, vectorised over the
configurations (link poses from the system's closed form, :func:`link_poses`):

* against a box, capsule or sphere (the table top, the floor, the patient's parts, fixed or carried by a
  joint): the signed distance from the centre of the first shape's bounding sphere to that shape, less the
  sphere's radius — separated, the distance to a set is at least that to the ball holding it; overlapping
  a convex shape, the ball's penetration depth ``r − sd(c)`` bounds the shape's (a 2 m table top's or an
  8 m floor's own sphere would bound nothing);
* otherwise sphere to sphere: ``|c1 − c2| − r1 − r2``.

Each bound is lowered by :data:`BOUND_SLACK` for coal's round-off; ``bound <= coal's signed distance`` for
every pair (tested). Then, per configuration, **branch and bound**: coal computes the pairs in the order of
their bounds until the next bound is no smaller than the smallest distance found. The value is the minimum
over all pairs of coal's distance (the same shapes and request as :meth:`World.distances`), i.e.
exact to coal's GJK/EPA tolerance (1e-6 m): two coal calls on one pair differ by up to that, as their
initial guesses do. ``World.distances`` (coal on every pair) is the independent route the tests hold it to. Where the smallest bound is already at least ``exact_below``, no coal call is made and
that bound is returned (enough to tell a configuration clear of a margin).

Written here because coal's broad phase answers "which pairs collide", not "the smallest distance of a
fixed pair list" for many configurations at this cost. Lengths in metres, frames in the root (table) frame 0.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from carmkin.errors import InvalidConfigurationError

from .tolerances import BOUND_SLACK
#: Shapes whose signed point distance the bounds compute exactly.
POINT_DISTANCE_SHAPES = ("Box", "Capsule", "Sphere")


def link_frames(system) -> tuple[str, ...]:
    """Names of the frames of :func:`link_poses`, in its order: DH frames 1..6, then with a mount the
    floor-fixed ``table_reference`` and the mount bodies' ``<joint>_frame`` (:mod:`carmkin.model.mount_joints`)."""
    names = tuple(f"dh_frame_{k + 1}" for k in range(6))
    if system.mount.joints:
        names += ("table_reference",) + tuple(f"{joint.name}_frame" for joint in system.mount.joints)
    return names


def link_poses(system, Q) -> tuple[np.ndarray, np.ndarray]:
    """The frames of :func:`link_frames` (M, F, 4, 4) and source poses (M, 4, 4) of configurations Q (M, nq): the
    closed form, with a motorized table's motion ``Tz(d0) E(q_table)`` computed once per distinct table
    configuration (and a mount's ``G(q_mount)`` per configuration)."""
    from carmkin.model import kinematics

    if system.mount.joints:
        from carmkin.model.mount_joints import partial_chains

        Q = kinematics.check_configuration(Q, system.nq)
        q6 = system.split(Q)[0].copy()
        q6[:, 0] = 0.0
        rest = Q.copy()
        rest[:, 1 + len(system.table.joints):-5] = 0.0
        held = system.base_motion(rest)  # Tz(d0) E(q_table): the mount at rest
        bodies = held[:, None] @ partial_chains(system.mount.twists, system.mount_part(Q))  # = system.mount_frames(Q)
        motion = bodies[:, -1]  # = system.base_motion(Q), the chain computed once
        frames = np.concatenate((motion[:, None] @ kinematics.dh_frames(system.dh_table, q6), held[:, None], bodies),
                                axis=1)
        return frames, motion @ system.closed_form.poses(q6)
    if not system.table.joints:
        return system.dh_frames(Q), system.fk(Q, check_units=False)

    q6, q_table = system.split(Q)
    distinct, which = np.unique(q_table, axis=0, return_inverse=True)
    E = np.array([system.table_motion(v) for v in distinct]).reshape(-1, 4, 4)[np.ravel(which)]
    E[:, 2, 3] += q6[:, 0]
    q6 = q6.copy()
    q6[:, 0] = 0.0
    return E[:, None] @ kinematics.dh_frames(system.dh_table, q6), E @ system.closed_form.poses(q6)


def bounding_sphere(obj) -> tuple[np.ndarray, float]:
    """Centre (in the parent joint's frame) and radius (m) of the sphere about the shape's local AABB."""
    geometry = obj.geometry
    geometry.computeLocalAABB()
    return obj.placement.act(np.asarray(geometry.aabb_center, dtype=float)), float(geometry.aabb_radius)


class PairBounds:
    """Bounds and exact distances over the pairs of ``world`` (a :class:`carmkin.world.World`)."""

    def __init__(self, world) -> None:
        self.world = world
        self.geometry_model = world.geometry_model
        self.model = model = world.model
        self.data = model.createData()
        self.geometry_data = pin.GeometryData(world.geometry_model)  # its own: the world's stays untouched
        for request in self.geometry_data.distanceRequests:
            request.enable_signed_distance = True
        objects = world.geometry_model.geometryObjects
        spheres = [bounding_sphere(o) for o in objects]
        self.centres = np.array([c for c, _ in spheres]).reshape(-1, 3)  # in the parent joint's frame
        self.radii = np.array([r for _, r in spheres])
        self.parent = np.array([o.parentJoint for o in objects], dtype=int)
        pairs = world.geometry_model.collisionPairs
        self.first = np.array([p.first for p in pairs], dtype=int)
        self.second = np.array([p.second for p in pairs], dtype=int)
        self.pair_radius = self.radii[self.first] + self.radii[self.second]
        # Every moving shape rides on a joint that carries one of the frames of link_poses: its centre in that frame.
        data0 = model.createData()
        pin.framesForwardKinematics(model, data0, pin.neutral(model))
        dh = {}
        for k, name in enumerate(link_frames(world.system)):
            f = model.getFrameId(name)
            dh.setdefault(model.frames[f].parentJoint, (k, data0.oMf[f]))
        self._moving = np.flatnonzero(self.parent != 0)
        self._frame_of_moving = np.array([dh[j][0] for j in self.parent[self._moving].tolist()], dtype=int)
        self._moving_local = np.array([dh[j][1].actInv(data0.oMi[j].act(self.centres[g])) for g, j in
                                       zip(self._moving.tolist(), self.parent[self._moving].tolist())]).reshape(-1, 3)
        # Pairs whose second shape gets the point-distance bound: its pose in its DH frame (or the table frame).
        plain = np.ones(len(self.first), dtype=bool)
        exact, poses, frames, shapes = [], [], [], []
        for g in np.unique(self.second).tolist():
            o, j = objects[g], int(self.parent[g])
            kind = type(o.geometry).__name__
            if kind not in POINT_DISTANCE_SHAPES:
                continue
            ks = np.flatnonzero(self.second == g)
            plain[ks] = False
            pose, frame = o.placement, -1
            if j:
                frame, dh_pose = dh[j]
                pose = dh_pose.actInv(data0.oMi[j] * o.placement)
            half = np.asarray(o.geometry.halfSide, dtype=float) if kind == "Box" else np.zeros(3)
            segment = (o.geometry.halfLength if kind == "Capsule" else 0.0, 0.0 if kind == "Box" else o.geometry.radius)
            exact += ks.tolist()
            poses += [(pose.rotation.copy(), pose.translation.copy())] * len(ks)
            frames += [frame] * len(ks)
            shapes += [(kind == "Box", half, segment)] * len(ks)
        self._plain = np.flatnonzero(plain)
        self._exact = np.array(exact, dtype=int)
        self._exact_R = np.array([R for R, _ in poses]).reshape(-1, 3, 3)
        self._exact_t = np.array([t for _, t in poses]).reshape(-1, 3)
        self._exact_frame = np.array(frames, dtype=int)
        self._exact_box = np.array([box for box, _, _ in shapes], dtype=bool)
        self._exact_half = np.array([h for _, h, _ in shapes]).reshape(-1, 3)
        self._exact_segment = np.array([seg for _, _, seg in shapes]).reshape(-1, 2)

    def __len__(self) -> int:
        return len(self.first)

    # --- bounds ----------------------------------------------------------------------------------------------
    def lower_bounds(self, qs) -> np.ndarray:
        """(N, P): a lower bound of every pair's signed distance (m) for configurations ``qs`` (N, nq) (see the
        module docstring), vectorised."""
        return self._bounds(self._configurations(qs))

    def _bounds(self, qs: np.ndarray) -> np.ndarray:
        frames, _ = link_poses(self.world.system, qs)  # (N, 6, 4, 4)
        # Components as (3, N, G) arrays: numpy is slow on a last axis of length 3.
        F = frames[:, self._frame_of_moving]
        c = self._moving_local
        world = np.empty((3, len(qs), len(self.centres)))
        world[:] = self.centres.T[:, None, :]
        for i in range(3):
            world[i][:, self._moving] = (F[..., i, 0] * c[:, 0] + F[..., i, 1] * c[:, 1] + F[..., i, 2] * c[:, 2]
                                         + F[..., i, 3])
        bound = np.empty((len(qs), len(self.first)))
        k = self._plain
        gap = world[:, :, self.first[k]] - world[:, :, self.second[k]]
        bound[:, k] = np.sqrt(gap[0] ** 2 + gap[1] ** 2 + gap[2] ** 2) - self.pair_radius[k]
        if len(self._exact):
            first = self.first[self._exact]
            p = world[:, :, first]  # (3, N, E): the first shapes' centres
            for f in np.unique(self._exact_frame[self._exact_frame >= 0]).tolist():  # second shapes on a joint
                e = np.flatnonzero(self._exact_frame == f)
                T = frames[:, f]
                d = [p[j][:, e] - T[:, j, 3, None] for j in range(3)]
                for i in range(3):  # into DH frame f: Rᵀ (p − t)
                    p[i][:, e] = T[:, 0, i, None] * d[0] + T[:, 1, i, None] * d[1] + T[:, 2, i, None] * d[2]
            R, t = self._exact_R, self._exact_t
            d = [p[j] - t[:, j] for j in range(3)]
            x, y, z = (R[:, 0, i] * d[0] + R[:, 1, i] * d[1] + R[:, 2, i] * d[2] for i in range(3))
            hx, hy, hz = self._exact_half.T
            qx, qy, qz = np.abs(x) - hx, np.abs(y) - hy, np.abs(z) - hz
            d_box = np.sqrt(np.maximum(qx, 0.0) ** 2 + np.maximum(qy, 0.0) ** 2 + np.maximum(qz, 0.0) ** 2) \
                + np.minimum(np.maximum(np.maximum(qx, qy), qz), 0.0)
            half, radius = self._exact_segment.T
            z = z - np.clip(z, -half, half)
            d_segment = np.sqrt(x * x + y * y + z * z) - radius
            bound[:, self._exact] = np.where(self._exact_box, d_box, d_segment) - self.radii[first]
        return bound - BOUND_SLACK

    # --- exact distances -------------------------------------------------------------------------------------
    def nearest(self, qs, exact_below: float = np.inf, stop_below: float = -np.inf) -> tuple[np.ndarray, np.ndarray]:
        """``(distance (N,), pair (N,))`` for configurations ``qs`` (N, nq): the smallest signed distance over
        the pairs (m) and its pair, exact wherever it is below ``exact_below`` (elsewhere the smallest bound,
        itself at least ``exact_below``, and pair −1); with ``stop_below``, the first pair found closer than it
        ends a configuration's search (a distance below it, not the smallest). ``inf`` without pairs."""
        qs = self._configurations(qs)
        out, which = np.full(len(qs), np.inf), np.full(len(qs), -1)
        if not len(self) or not len(qs):
            return out, which
        bound = self._bounds(qs)
        order = np.argsort(bound, axis=1)
        bound = np.take_along_axis(bound, order, axis=1)
        out[:] = bound[:, 0]
        model, data = self.model, self.data
        gm, gd = self.geometry_model, self.geometry_data
        for i in np.flatnonzero(bound[:, 0] < exact_below).tolist():
            pin.forwardKinematics(model, data, qs[i])
            pin.updateGeometryPlacements(model, data, gm, gd)
            best, pair = np.inf, -1
            for b, k in zip(bound[i].tolist(), order[i].tolist()):
                if b >= best:
                    break  # every remaining pair is at least as far: best is exact
                d = pin.computeDistance(gm, gd, k).min_distance
                if d < best:
                    best, pair = d, k
                    if best < stop_below:
                        break
            out[i], which[i] = best, pair
        return out, which

    def _configurations(self, qs) -> np.ndarray:
        from carmkin.validation import JOINT_VALUE_LIMIT, real_array

        qs = real_array(qs, "qs", error=InvalidConfigurationError, limit=JOINT_VALUE_LIMIT, unit="m, rad")
        if qs.ndim == 1:
            qs = qs[None]
        if qs.ndim != 2 or qs.shape[1] != self.model.nq:
            raise InvalidConfigurationError(
                f"qs must be finite with shape (N, {self.model.nq}) (m, rad), got shape {qs.shape}")
        return qs
