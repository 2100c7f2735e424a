"""Swept clearance: a certified lower bound on every collision pair's distance along a joint-space path.

The path between two frames is the straight joint-space segment ``q(t) = q_a + t (q_b − q_a)``, t ∈ [0, 1]
(a controller stepping its joints linearly between acquisition positions); frames in range imply the
segment is (the joint box is convex). Along it each pair distance is checked by **conservative
advancement** with exact coal distances (:class:`carmkin.robot.collision.CollisionScene`) and a bound on
how fast any pair can close:

* **Point-speed bound (per pair, per joint).** A point of geometry g carried by joint i moves, for a rate of
  revolute joint j (an ancestor of i), at most ``ρ_jg`` m/rad, its distance from j's axis. The axis passes
  through the origin of joint j's frame, so by the triangle inequality along the chain
  ``ρ_jg ≤ Σ_k (|t_k| + e_k) + |p_g| + r_g`` over the joints k after j up to i (t_k: joint placement,
  e_k: largest |value| of a prismatic k), with p_g the geometry's placement and r_g its bounding radius.
  A prismatic joint moves every carried point at exactly 1 m/m. A joint carrying *both* geometries of a
  pair moves them rigidly together and does not change their distance. Hence
  ``|Δd| ≤ Σ_j S_j |Δq_j|``, sound for every configuration (not a local estimate).
* **Advancement.** From a sample at t with distances d_k, every pair stays above τ for
  ``Δt ≤ min_k (d_k − ε_k − τ) / L_k`` (L_k = Σ_j S_kj |q_b − q_a|_j, ε_k = :func:`accuracy`). With
  τ = max(margin, m* − tol) (m*: smallest sampled distance so far) the path is certified ≥ margin and the
  reported minimum is within ``tol`` of the true one. A sample within :data:`CONTACT_RESOLUTION` of the
  margin stops the segment: contact, with the angle and the pair.

Lengths in m, angles in rad, frames as in the collision scene (table frame 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Accuracy assumed of a coal distance, relative to max(1 m, the distance): twice GJK/EPA's 1e-6 tolerance (two
#: calls on one pair differ by up to that, see carmkin.robot.clearance; 4e-6 m measured on a pair 3.3 m apart);
#: subtracted from every sampled distance before it certifies (:func:`accuracy`).
DISTANCE_ACCURACY = 2e-6
#: A sample closer than margin + this (m) is a contact: advancement stops instead of creeping on.
CONTACT_RESOLUTION = 1e-5
#: Default tightness (m) of the reported swept minimum: it lies within this below the true minimum.
DEFAULT_TOLERANCE = 1e-3
#: Samples per segment before giving up (counted as a contact at the last sample).
MAX_SAMPLES = 20000


def accuracy(d: np.ndarray) -> np.ndarray:
    """Accuracy (m) of coal distances ``d`` (m): :data:`DISTANCE_ACCURACY` · max(1, d)."""
    return DISTANCE_ACCURACY * np.maximum(1.0, d)


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


def speed_bounds(scene) -> np.ndarray:
    """``S`` (n_pairs, nv): ``|∂d_k/∂q_j| ≤ S[k, j]`` for every configuration (m per m or rad)."""
    model = scene.model
    objects = scene.geometry_model.geometryObjects
    lower, upper = np.array(model.lowerPositionLimit), np.array(model.upperPositionLimit)
    prismatic = np.array(["P" in model.joints[j].shortname().replace("JointModel", "") for j in range(model.njoints)])
    extent = np.zeros(model.njoints)
    for j in range(1, model.njoints):
        if prismatic[j]:
            i = model.joints[j].idx_q
            extent[j] = max(abs(lower[i]), abs(upper[i]))
    link = np.array([np.linalg.norm(model.jointPlacements[j].translation) for j in range(model.njoints)]) + extent

    def per_geometry(index: int) -> np.ndarray:
        obj = objects[index]
        reach = np.linalg.norm(obj.placement.translation) + bounding_radius(obj.geometry)
        rates = np.zeros(model.nv)
        chain = list(model.supports[obj.parentJoint])[1:]  # root side first, the parent joint last
        for pos, j in enumerate(chain):
            idx = model.joints[j].idx_v
            rates[idx] = 1.0 if prismatic[j] else reach + sum(link[k] for k in chain[pos + 1:])
        return rates

    cache: dict[int, np.ndarray] = {}
    S = np.zeros((len(scene.pairs), model.nv))
    for k, pair in enumerate(scene.geometry_model.collisionPairs):
        a = cache.setdefault(pair.first, per_geometry(pair.first))
        b = cache.setdefault(pair.second, per_geometry(pair.second))
        only_one = (a > 0) != (b > 0)
        S[k] = np.where(only_one, a + b, 0.0)
    return S


@dataclass(frozen=True)
class SegmentCheck:
    """Conservative advancement over one segment.

    ``bound``: certified lower bound (m) of every pair's distance over the checked part; ``sampled_min``:
    smallest exact distance at the samples (m); ``samples``: distance queries made; ``contact_t``: path
    parameter of the contact (None when the whole segment keeps the margin); ``pair``: the pair index there.
    """

    bound: float
    sampled_min: float
    samples: int
    contact_t: float | None = None
    pair: int | None = None


class SweptClearance:
    """Conservative advancement on a :class:`~carmkin.robot.collision.CollisionScene` (built once)."""

    def __init__(self, scene, margin: float, tolerance: float = DEFAULT_TOLERANCE) -> None:
        self.scene, self.margin, self.tolerance = scene, float(margin), float(tolerance)
        self.S = speed_bounds(scene)
        self.data = scene.model.createData()

    def distances(self, q: np.ndarray) -> np.ndarray:
        """Exact signed distances (n_pairs,) at ``q`` (m)."""
        return self.scene.distances(self.data, q=q)

    def segment(self, q_a: np.ndarray, q_b: np.ndarray, d_a: np.ndarray, best: float) -> SegmentCheck:
        """Check ``q_a → q_b`` given the distances ``d_a`` at ``q_a`` and the smallest sampled distance so far."""
        L = self.S @ np.abs(q_b - q_a)
        t, d, samples = 0.0, d_a, 0
        bound = np.inf
        best = min(best, float(d.min()))
        while True:
            k_min = int(np.argmin(d))
            if d[k_min] < self.margin + CONTACT_RESOLUTION or samples >= MAX_SAMPLES:
                return SegmentCheck(min(bound, float(d[k_min] - accuracy(d[k_min]))), best, samples, t, k_min)
            tau = max(self.margin, best - self.tolerance)
            slack = d - accuracy(d) - tau
            with np.errstate(divide="ignore"):
                steps = np.where(L > 0, slack / L, np.inf)
            step = min(float(steps.min()), 1.0 - t)
            bound = min(bound, float(np.min(d - accuracy(d) - step * L)))
            if t + step >= 1.0:
                return SegmentCheck(bound, best, samples)
            t += step
            d = self.distances(q_a + t * (q_b - q_a))
            samples += 1
            best = min(best, float(d.min()))
