"""Swept clearance: a certified lower bound on every collision pair's distance along a joint-space segment.

The one conservative advancement of the toolkit (sweeps' frame pairs, views' moves and the repositioning
guidance all call it through :meth:`carmkin.world.World.swept`). The path is the straight joint-space segment
``q(t) = q_a + t (q_b − q_a)``, t ∈ [0, 1] (a controller stepping its joints linearly; a single joint moved
alone is one); ends in range imply the segment is (the joint box is convex). Along it each pair distance is
checked with exact coal distances (:meth:`carmkin.world.World.distances`) and a bound on how fast any pair
can close:

* **Point-speed bound (per pair, per joint).** A point of geometry g carried by joint i moves, for a rate of
  revolute joint j (an ancestor of i), at most ``ρ_jg`` m/rad, its distance from j's axis. The axis passes
  through the origin of joint j's frame, so by the triangle inequality along the chain
  ``ρ_jg ≤ Σ_k (|t_k| + e_k) + |p_g| + r_g`` over the joints k after j up to i (t_k: joint placement,
  e_k: largest |value| of a prismatic k), with p_g the geometry's placement and r_g its bounding radius.
  A prismatic joint moves every carried point at exactly 1 m/m. A joint carrying *both* geometries of a
  pair moves them rigidly together and does not change their distance. Hence
  ``|Δd| ≤ Σ_j S_j |Δq_j|``, sound for every configuration (not a local estimate).
* **Advancement.** From a sample at t with distances d_k, every pair stays above τ for
  ``Δt ≤ min_k (d_k − ε_k − τ) / L_k`` (L_k = Σ_j S_kj |q_b − q_a|_j, ε_k = :func:`accuracy`), and the
  certified bound of that step is ``min_k (d_k − ε_k − Δt L_k) ≥ τ``. With τ = m* − tol (m*: smallest
  sampled distance so far), the reported :attr:`Swept.min_distance` is ≤ the true minimum of the segment
  and ≥ it − tol; with a ``margin``, τ = max(margin, m* − tol) while the samples keep the margin (fewer
  samples where the segment is far from contact, the same guarantee). A sample within
  :data:`CONTACT_RESOLUTION` of the margin is a contact (:attr:`Swept.contact_t`); the sweep goes on to the
  end unless asked to stop there, so the minimum is always that of the whole segment.

Lengths in m, angles in rad, frames as in the world (table frame 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import CollisionSceneError
from carmkin.validation import JOINT_VALUE_LIMIT, real_array, real_scalar

from .tolerances import CONTACT_RESOLUTION, DEFAULT_TOLERANCE, MAX_SAMPLES, accuracy


def bounding_radius(geometry) -> float:
    """Radius (m) of a sphere about the shape's centre that holds a coal primitive."""
    import coal

    if isinstance(geometry, coal.Box):
        return float(np.linalg.norm(geometry.halfSide))
    if isinstance(geometry, coal.Sphere):
        return float(geometry.radius)
    if isinstance(geometry, coal.Capsule):
        return float(geometry.radius + geometry.halfLength)
    if isinstance(geometry, coal.Cylinder):
        return float(np.hypot(geometry.radius, geometry.halfLength))
    aabb = geometry.aabb_local if hasattr(geometry, "aabb_local") else None
    if aabb is None:
        geometry.computeLocalAABB()
        aabb = geometry.aabb_local
    return float(max(np.linalg.norm(aabb.min_), np.linalg.norm(aabb.max_)))


def geometry_rates(world) -> np.ndarray:
    """``R`` (n_geometries, nv): how fast (m per m or rad) any point of each geometry of ``world`` can move for a
    unit rate of each joint, for every configuration (the point-speed bound of the module docstring; 0 for the
    joints that do not carry it)."""
    model = world.model
    objects = world.geometry_model.geometryObjects
    lower, upper = np.array(model.lowerPositionLimit), np.array(model.upperPositionLimit)
    prismatic = np.array(["P" in model.joints[j].shortname().replace("JointModel", "") for j in range(model.njoints)])
    extent = np.zeros(model.njoints)
    for j in range(1, model.njoints):
        if prismatic[j]:
            i = model.joints[j].idx_q
            extent[j] = max(abs(lower[i]), abs(upper[i]))
    link = np.array([np.linalg.norm(model.jointPlacements[j].translation) for j in range(model.njoints)]) + extent
    R = np.zeros((len(objects), model.nv))
    for index, obj in enumerate(objects):
        reach = np.linalg.norm(obj.placement.translation) + bounding_radius(obj.geometry)
        chain = list(model.supports[obj.parentJoint])[1:]  # root side first, the parent joint last
        for pos, j in enumerate(chain):
            R[index, model.joints[j].idx_v] = 1.0 if prismatic[j] else reach + sum(link[k] for k in chain[pos + 1:])
    return R


def pair_rates(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Speed bounds of pairs whose geometries move at rates ``a`` and ``b`` (…, nv): their sum, except on a joint
    that carries both geometries, which moves them rigidly together and does not change their distance."""
    return np.where((a > 0) != (b > 0), a + b, 0.0)


def speed_bounds(world) -> np.ndarray:
    """``S`` (n_pairs, nv): ``|∂d_k/∂q_j| ≤ S[k, j]`` for every configuration (m per m or rad)."""
    R = geometry_rates(world)
    pairs = world.geometry_model.collisionPairs
    first = np.array([p.first for p in pairs], dtype=int)
    second = np.array([p.second for p in pairs], dtype=int)
    return pair_rates(R[first], R[second]).reshape(len(pairs), world.model.nv)


@dataclass(frozen=True)
class Swept:
    """The swept clearance of one segment (see the module docstring).

    ``min_distance``: certified lower bound (m) of every pair's distance over the checked part
    ``[0, checked_to]`` (the whole segment unless the sweep stopped at a contact or gave up), within
    ``tolerance`` (+ coal's accuracy) below the true minimum; ``sampled_min``: the smallest exact distance
    at the samples (m) and ``pair`` its pair index (into :attr:`carmkin.world.World.pairs`, −1 without
    pairs); ``samples``: coal passes made; ``margin`` (m, or None); ``contact_t``: path parameter of the first
    sample within the margin (None when every sample keeps it); ``contact_pair`` and ``contact_distance``
    (m): its pair and exact distance there."""

    min_distance: float
    sampled_min: float
    pair: int
    samples: int
    margin: float | None
    tolerance: float
    contact_t: float | None = None
    contact_pair: int | None = None
    contact_distance: float | None = None
    checked_to: float = 1.0

    @property
    def complete(self) -> bool:
        """The whole segment was certified (not stopped at a contact, not given up)."""
        return self.checked_to >= 1.0

    @property
    def clear(self) -> bool:
        """The whole segment keeps the margin (certified): complete and no sample within it, so that every
        advancement step was bounded by the margin (``min_distance`` ≥ margin up to its last rounding)."""
        return self.complete and self.contact_t is None


def sweep(world, q_a, q_b, margin: float | None = None, tolerance: float = DEFAULT_TOLERANCE,
          stop_at_contact: bool = False, path_min: float = math.inf) -> Swept:
    """The swept clearance of ``q_a → q_b`` (nq, m and rad) in ``world`` by conservative advancement.

    ``margin`` (m): samples within it (+ :data:`CONTACT_RESOLUTION`) are contacts, and far from it the steps
    are longer; ``tolerance`` (m): how far below the true minimum ``min_distance`` may be;
    ``stop_at_contact``: end at the first contact (``checked_to`` < 1 then) instead of certifying the whole
    segment (a yes/no question answered sooner); ``path_min`` (m): the smallest exact distance already sampled
    on other segments of the same path (a sweep's earlier frame pairs): the steps then only keep the bound
    within ``tolerance`` of the path's minimum, not of this segment's (``min_distance`` stays certified)."""
    nq = world.model.nq
    q_a = real_array(q_a, "q_a", (nq,), error=CollisionSceneError, limit=JOINT_VALUE_LIMIT, unit="m, rad")
    q_b = real_array(q_b, "q_b", (nq,), error=CollisionSceneError, limit=JOINT_VALUE_LIMIT, unit="m, rad")
    if margin is not None:
        margin = real_scalar(margin, "margin", error=CollisionSceneError, low=-1.0, high=1.0, unit="m")
    tolerance = real_scalar(tolerance, "tolerance", error=CollisionSceneError, low=1e-6, high=0.1, unit="m")
    if not len(world):
        return Swept(math.inf, math.inf, -1, 0, margin, tolerance)
    dq = q_b - q_a
    L = world.speed_bounds @ np.abs(dq)
    t, samples = 0.0, 1
    d = world.distances(q=q_a)
    k = int(np.argmin(d))
    best, pair, bound = float(d[k]), k, math.inf
    contact_t = contact_pair = contact_distance = None
    while True:
        k = int(np.argmin(d))
        if margin is not None and contact_t is None and d[k] < margin + CONTACT_RESOLUTION:
            contact_t, contact_pair, contact_distance = t, k, float(d[k])
            if stop_at_contact:
                bound = min(bound, float(d[k] - accuracy(d[k])))
                return Swept(bound, best, pair, samples, margin, tolerance, contact_t, contact_pair, contact_distance, t)
        if samples >= MAX_SAMPLES:
            bound = min(bound, float(d[k] - accuracy(d[k])))
            return Swept(bound, best, pair, samples, margin, tolerance, contact_t, contact_pair, contact_distance, t)
        tau = min(best, path_min) - tolerance
        if margin is not None and contact_t is None:
            tau = max(margin, tau)
        eps = accuracy(d)
        with np.errstate(divide="ignore", invalid="ignore"):
            steps = np.where(L > 0, (d - eps - tau) / np.where(L > 0, L, 1.0), np.inf)
        step = min(float(steps.min()), 1.0 - t)
        bound = min(bound, float(np.min(d - eps - step * L)))
        if t + step >= 1.0:
            return Swept(bound, best, pair, samples, margin, tolerance, contact_t, contact_pair, contact_distance)
        t += step
        d = world.distances(q=q_a + t * dq)
        samples += 1
        k = int(np.argmin(d))
        if d[k] < best:
            best, pair = float(d[k]), k
