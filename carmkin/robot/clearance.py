"""Clearance of many configurations at once: a bounding-box broad phase, exact coal distances where they decide.

:class:`BoundedScene` wraps a :class:`~carmkin.robot.collision.CollisionScene`. Every geometry gets its
oriented bounding box (the local AABB of its coal shape, moved with its joint: for the boxes of the C-arm
model the box itself). For each pair, a **lower bound** of the signed distance is the signed distance
between the second box and the box, aligned with it, that contains the first one (:meth:`lower_bounds`):
separated, the distance between two sets is at least that between sets containing them; overlapping, the
overlap along any unit axis is at least the penetration depth of two convex sets (for convex sets the
penetration depth is the smallest overlap of their projections over all directions). Hence, less :data:`BOUND_SLACK` for coal's round-off, ``bound <= coal's signed
distance`` for every pair (tested).

Exactness, as used by :meth:`BoundedScene.min_distance` and :meth:`BoundedScene.below`:

* a pair whose bound is at least the margin cannot be closer than the margin: its coal distance is not
  computed; every pair whose bound is below the margin gets its exact coal distance, so the set of pairs
  closer than the margin and their distances are exactly those of computing every pair;
* the smallest distance is found branch-and-bound: pairs in order of their bound, coal for each until the
  next bound is no smaller than the smallest distance found. The value is the minimum over all pairs of
  coal's distance (the same shapes and request as :meth:`CollisionScene.distances`), i.e. exact to coal's
  GJK/EPA tolerance (1e-6 m): two coal calls on one pair differ by up to that, as their initial guesses do.

Lengths in metres, frames in the root (table) frame 0.
"""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin

from carmkin.errors import InvalidConfigurationError

from .collision import CollisionScene

#: Coal's GJK/EPA stop within their tolerances (``gjk_tolerance`` = ``epa_tolerance`` = 1e-6 by default): near
#: contact a box pair 4e-7 m apart is reported at 0 (found by the tests). Every bound is lowered by twice that
#: tolerance (m), so that a pruned pair is farther than the margin in coal's own numbers too.
BOUND_SLACK = 2e-6


class BoundedScene:
    """Broad phase (oriented bounding boxes) and exact narrow phase (coal) over the pairs of ``scene``."""

    def __init__(self, scene: CollisionScene) -> None:
        self.scene = scene
        model, objects = scene.model, scene.geometry_model.geometryObjects
        self.model = model
        self.data = model.createData()
        used = sorted({int(i) for p in scene.geometry_model.collisionPairs for i in (p.first, p.second)})
        slot = {g: k for k, g in enumerate(used)}
        self.pair_slots = np.array([[slot[p.first], slot[p.second]] for p in scene.geometry_model.collisionPairs],
                                   dtype=np.intp).reshape(-1, 2)
        self.geometries = [objects[g].geometry for g in used]
        self.joints = np.array([objects[g].parentJoint for g in used], dtype=np.intp)
        self.moving_joints = sorted({int(j) for j in self.joints if j != 0})
        self._joint_slot = np.array([self.moving_joints.index(j) + 1 if j else 0 for j in self.joints], dtype=np.intp)
        n = len(used)
        self.placement_R = np.empty((n, 3, 3))
        self.box_centre = np.empty((n, 3))  # centre of the bounding box in the parent joint's frame
        self.half = np.empty((n, 3))
        for k, g in enumerate(used):
            geometry = objects[g].geometry
            geometry.computeLocalAABB()
            lo, hi = np.array(geometry.aabb_local.min_), np.array(geometry.aabb_local.max_)
            M = objects[g].placement
            self.placement_R[k] = M.rotation
            self.box_centre[k] = M.rotation @ (0.5 * (lo + hi)) + M.translation
            self.half[k] = 0.5 * np.abs(hi - lo)  # a box given a negative size has its AABB corners swapped
        self._placements = [objects[g].placement for g in used]
        self.request = coal.DistanceRequest()
        self.request.enable_signed_distance = True
        self._result = coal.DistanceResult()

    def __len__(self) -> int:
        return len(self.pair_slots)

    # --- kinematics -----------------------------------------------------------------------------------------
    def joint_frames(self, qs: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
        """(N, 1 + J, 4, 4) poses of the universe and of the joints that carry pair geometries, for qs (N, nq)
        (one Pinocchio forward-kinematics pass each; ``data`` is reused when given)."""
        data = data if data is not None else self.data
        out = np.empty((len(qs), 1 + len(self.moving_joints), 4, 4))
        out[:, 0] = np.eye(4)
        joints = self.moving_joints
        for i, q in enumerate(qs):
            pin.forwardKinematics(self.model, data, q)
            oMi = data.oMi
            for k, j in enumerate(joints, 1):
                out[i, k] = oMi[j].homogeneous
        return out

    def boxes(self, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World centres (N, G, 3) and axes (N, G, 3, 3) (columns) of the geometries' bounding boxes."""
        F = frames[:, self._joint_slot]  # (N, G, 4, 4)
        R = F[..., :3, :3]
        centres = (R @ self.box_centre[..., None])[..., 0] + F[..., :3, 3]
        return centres, R @ self.placement_R

    # --- bounds and exact distances -----------------------------------------------------------------------
    def lower_bounds(self, centres: np.ndarray, axes: np.ndarray) -> np.ndarray:
        """(N, P): a lower bound of every pair's signed distance (see the module docstring).

        The first box of a pair, seen in the second box's frame, lies in the axis-aligned box of half extents
        ``|R_bᵀ R_a| h_a`` about its centre; the bound is the signed distance between that box and the
        second box (exact for axis-aligned boxes: the Euclidean norm of the separations along the second
        box's axes, or the largest (negative) overlap when they overlap on every axis).
        """
        a, b = self.pair_slots[:, 0], self.pair_slots[:, 1]
        RbT = np.swapaxes(axes[:, b], -1, -2)  # (N, P, 3, 3)
        local = (RbT @ (centres[:, a] - centres[:, b])[..., None])[..., 0]  # centre of a in b's frame
        extent = (np.abs(RbT @ axes[:, a]) @ self.half[a][..., None])[..., 0]
        gap = np.abs(local) - extent - self.half[b]  # (N, P, 3)
        outside = np.maximum(gap, 0.0)
        apart = np.sqrt((outside * outside).sum(axis=-1))
        return np.where(apart > 0.0, apart, gap.max(axis=-1)) - BOUND_SLACK

    def _transform(self, frames_i: np.ndarray, slot: int) -> coal.Transform3s:
        M = frames_i[self._joint_slot[slot]]
        placement = self._placements[slot]
        R = M[:3, :3] @ placement.rotation
        return coal.Transform3s(R, M[:3, :3] @ placement.translation + M[:3, 3])

    def exact(self, frames_i: np.ndarray, pair: int) -> float:
        """Coal's signed distance (m) of ``pair`` in the configuration of ``frames_i`` (1 + J, 4, 4)."""
        a, b = self.pair_slots[pair]
        result = self._result
        result.clear()
        coal.distance(self.geometries[a], self._transform(frames_i, a), self.geometries[b],
                      self._transform(frames_i, b), self.request, result)
        return float(result.min_distance)

    def _min(self, frames_i: np.ndarray, bounds_i: np.ndarray, stop: float, best: float = np.inf) -> float:
        """Branch and bound from the distance ``best`` already known: the exact smallest distance when it is
        below ``stop``, else the smallest bound."""
        for pair in np.argsort(bounds_i).tolist():
            bound = bounds_i[pair]
            if bound >= best:
                break  # every remaining pair is at least as far: best is exact
            if bound >= stop:
                return min(best, float(bound))  # a lower bound, at least stop (or the exact best below it)
            best = min(best, self.exact(frames_i, pair))
        return best

    def min_distance(self, qs, exact_below: float = np.inf) -> np.ndarray:
        """(N,) the smallest signed distance over the pairs (m) of each configuration of ``qs`` (N, nq).

        Exact (coal, branch and bound) wherever it is below ``exact_below``; where it is not, the value is a
        lower bound that is itself at least ``exact_below`` — enough to tell a configuration clear of a margin
        at the cost of the broad phase alone. ``inf`` for a scene without pairs.
        """
        qs = self._configurations(qs)
        frames = self.joint_frames(qs)
        if not len(self):
            return np.full(len(qs), np.inf)
        bounds = self.lower_bounds(*self.boxes(frames))
        out = bounds.min(axis=1)
        for i in np.flatnonzero(out < exact_below).tolist():
            out[i] = self._min(frames[i], bounds[i], exact_below)
        return out

    def below(self, frames_i: np.ndarray, bounds_i: np.ndarray, margin: float) -> tuple[np.ndarray, np.ndarray, float]:
        """For one configuration: ``(pairs, distances, min_distance)`` — the pairs closer than ``margin`` with
        their exact distances, and the exact smallest distance over all pairs (``inf`` without pairs)."""
        near = np.flatnonzero(bounds_i < margin)
        distances = np.array([self.exact(frames_i, k) for k in near.tolist()])
        close = distances < margin
        best = float(distances.min()) if len(distances) else np.inf
        if len(bounds_i) and not best < margin:  # nothing decided yet below the margin: branch and bound the rest
            rest = bounds_i.copy()
            rest[near] = np.inf
            best = self._min(frames_i, rest, np.inf, best)
        return near[close], distances[close], best

    def _configurations(self, qs) -> np.ndarray:
        qs = np.asarray(qs, dtype=float)
        if qs.ndim == 1:
            qs = qs[None]
        if qs.ndim != 2 or qs.shape[1] != self.model.nq or not np.all(np.isfinite(qs)):
            raise InvalidConfigurationError(
                f"qs must be finite with shape (N, {self.model.nq}) (m, rad), got shape {qs.shape}")
        return qs
