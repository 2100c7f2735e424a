"""Certified clearance of a joint-space path: two-sided bisection over the world's exact distances.

A path is a polyline of waypoints ``Q[0] … Q[k]`` (nq each, m and rad) in joint space; segment ``i`` is
``q(t) = Q[i] + t (Q[i+1] − Q[i])``, t ∈ [0, 1]. Along it every collision pair ``p`` moves at most
``L_p = Σ_j S_pj |ΔQ_j|`` per unit of t (``S``: the world's chain speed bounds, :mod:`carmkin.world.swept`),
so on an interval ``[t_a, t_b]`` whose ends have exact distances ``d_a`` and ``d_b`` (coal, less their
accuracy :func:`carmkin.world.tolerances.accuracy`)::

    d_p(t) ≥ max(d_a,p − L_p (t − t_a), d_b,p − L_p (t_b − t)) ≥ (d_a,p + d_b,p − L_p (t_b − t_a)) / 2

for every t in the interval: the **interval bound** (two cones meeting). It needs no sample inside the
interval, so a segment far from everything is certified by its two ends alone, in microseconds once the ends'
distances are known (the planner keeps every state's distances). Where the bound is too low, the interval is
halved and its midpoint's exact distances computed. Two questions are answered:

* **clear** (:meth:`Certifier.segment`): does every point keep ``threshold`` (the planner's margin)? An interval
  whose bound reaches it is done; an interval smaller than :data:`SEARCH_RESOLUTION` (its bound's looseness
  ``max_p L_p w / 2``) that does not is *not certified* (conservative: the segment is refused, never passed);
  an exact sample below the threshold ends the check (a real violation). An interval that touches a waypoint
  may end :data:`END_TOLERANCE` below the threshold: a waypoint exactly at the margin (a view planned against it)
  can be left or reached, which no Lipschitz bound can prove to the last micrometre.
* **minimum** (:meth:`Certifier.minimum`): a certified lower bound of the smallest distance along the path,
  within :data:`carmkin.world.DEFAULT_TOLERANCE` (1 mm, + coal's accuracy) of the true minimum: intervals whose bound is within the
  tolerance of the smallest exact sample so far are done, the rest halved.

Both are sound for every configuration, not estimates: the speed bounds hold everywhere, the ends' distances
are coal's. :meth:`carmkin.world.World.swept` answers the same question one-sided (conservative advancement
from one end, every step a full distance pass); this two-sided form reuses the distances a planner already has
at its states, which is what makes edge checks cheap. Lengths in m, frames as in the world (table frame 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from carmkin.world.tolerances import DEFAULT_TOLERANCE, accuracy

#: Smallest interval looseness (m) the clear-check halves down to: an interval whose bound still misses the
#: threshold once ``max_p L_p w / 2`` is below this is not certified, and the segment is refused (1 mm: a path
#: refused by it passes within 1 mm of the margin; the planner then finds another).
SEARCH_RESOLUTION = 1e-3
#: How far (m) below the threshold an interval touching a waypoint may be certified (0.1 mm). A waypoint at
#: exactly the margin is valid, yet no Lipschitz bound proves a segment leaving it keeps the margin to the last
#: micrometre; the path's reported minimum says what was certified.
END_TOLERANCE = 1e-4
#: Bisection depth limit of one segment (2^-40 of its length: far below any resolution; a guard, not a bound).
MAX_DEPTH = 40


@dataclass(frozen=True)
class SegmentCheck:
    """The clear-check of one segment: ``clear`` when certified; ``bound`` (m) the smallest interval bound met
    (certified lower bound of the segment's clearance when clear); ``t`` where it lies; ``pair`` its pair index;
    ``samples`` exact distance passes made inside the segment; ``violation``: an exact sample fell below the
    threshold (a real collision or margin breach, not only an uncertified interval)."""

    clear: bool
    bound: float
    t: float
    pair: int
    samples: int
    violation: bool = False


class Certifier:
    """Exact distances and interval bounds of one scene: ``distances(q) -> (P,)`` exact signed distances (m)
    of the scene's pairs at ``q`` (nq,), and ``speed_bounds`` (P, nq) with ``|∂d_p/∂q_j| ≤ S[p, j]``
    everywhere. :meth:`for_world` builds it from a :class:`carmkin.world.World`."""

    def __init__(self, distances, pair_distances, speed_bounds: np.ndarray) -> None:
        self._distances, self._pair_distances = distances, pair_distances
        self.S = np.asarray(speed_bounds, dtype=float)
        self.passes = 0  # distance passes made (for benchmarks)

    @classmethod
    def for_world(cls, world) -> "Certifier":
        """The certifier of one world (its pairs, its chain speed bounds)."""
        return cls(lambda q: world.distances(q=q), world.pair_distances, world.speed_bounds)

    def distances(self, q) -> np.ndarray:
        """Exact signed distances (P,) of every pair at ``q`` (nq,) (m)."""
        self.passes += 1
        return self._distances(q)

    def midpoint(self, q, da, db, L, w, threshold) -> tuple[np.ndarray, float]:
        """Lowered distances (P,) at the midpoint ``q`` of an interval of width ``w`` whose ends have lowered
        distances ``da``, ``db``: exact (less coal's accuracy) for the pairs that could bring a half interval below
        ``threshold``, the ends' cone bound ``max(da, db) − L w / 2`` for the others (a lower bound too; coal is
        not called for them). Returns them and the smallest exact distance computed (inf if none)."""
        lower = np.maximum(da, db) - 0.5 * L * w
        active = np.flatnonzero(lower - 0.25 * L * w < threshold)
        self.passes += 1
        if not len(active):
            return lower, math.inf
        exact = self._pair_distances(q, active)
        lower[active] = exact - accuracy(exact)
        return lower, float(exact.min())

    def rates(self, q_a, q_b) -> np.ndarray:
        """``L`` (P,): how fast each pair's distance can change per unit of t on ``q_a → q_b`` (m)."""
        return self.S @ np.abs(np.asarray(q_b, float) - np.asarray(q_a, float))

    def segment(self, q_a, q_b, d_a, d_b, threshold: float, resolution: float = SEARCH_RESOLUTION,
                end_tolerance: float = END_TOLERANCE) -> SegmentCheck:
        """Does ``q_a → q_b`` keep ``threshold`` (m) everywhere? ``d_a``, ``d_b``: the ends' exact distances (P,)
        (:meth:`distances`); see the module docstring."""
        q_a, q_b = np.asarray(q_a, float), np.asarray(q_b, float)
        L = self.rates(q_a, q_b)
        if not len(L):
            return SegmentCheck(True, math.inf, 0.0, -1, 0)
        L_max = float(L.max())
        lowered = (np.asarray(d_a) - accuracy(d_a), np.asarray(d_b) - accuracy(d_b))
        stack = [(0.0, 1.0, lowered[0], lowered[1], 0)]
        best, best_t, best_pair, samples = math.inf, 0.0, -1, 0
        while stack:
            ta, tb, da, db, depth = stack.pop()
            w = tb - ta
            per_pair = 0.5 * (da + db - L * w)
            p = int(np.argmin(per_pair))
            bound = float(per_pair[p])
            needed = threshold - (end_tolerance if ta == 0.0 or tb == 1.0 else 0.0)
            if bound >= needed:
                if bound < best:
                    best, best_t, best_pair = bound, 0.5 * (ta + tb), p
                continue
            if 0.5 * L_max * w <= resolution or depth >= MAX_DEPTH:
                return SegmentCheck(False, bound, 0.5 * (ta + tb), p, samples)
            tm = 0.5 * (ta + tb)
            dm, exact = self.midpoint(q_a + tm * (q_b - q_a), da, db, L, w, threshold)
            samples += 1
            if exact < threshold:
                k = int(np.argmin(dm))
                return SegmentCheck(False, exact, tm, k, samples, violation=True)
            stack.append((tm, tb, dm, db, depth + 1))
            stack.append((ta, tm, da, dm, depth + 1))
        return SegmentCheck(True, best, best_t, best_pair, samples)

    def minimum(self, Q, D=None, tolerance: float = DEFAULT_TOLERANCE) -> tuple[float, int, int, float]:
        """A certified lower bound (m) of the smallest distance along the path through ``Q`` (k+1, nq), within
        ``tolerance`` (+ coal's accuracy) of the true minimum; ``D`` (k+1, P) the waypoints' exact distances
        when known. Returns ``(bound, segment, pair, t)``: where the bound lies (segment index, pair, its t)."""
        Q = np.asarray(Q, float)
        D = np.array([self.distances(q) for q in Q]) if D is None else np.asarray(D, float)
        if D.ndim != 2 or not D.shape[1]:
            return math.inf, 0, -1, 0.0
        best_exact = float(D.min())
        bound, where = math.inf, (0, -1, 0.0)
        # one pass over all segments with a shared "best exact": intervals far above the path's minimum stop early
        stack = []
        for i in range(len(Q) - 1):
            L = self.rates(Q[i], Q[i + 1])
            stack.append((i, L, 0.0, 1.0, D[i] - accuracy(D[i]), D[i + 1] - accuracy(D[i + 1]), 0))
        if len(Q) == 1:
            k = int(np.argmin(D[0]))
            return float(D[0, k] - accuracy(D[0, k])), 0, k, 0.0
        while stack:
            i, L, ta, tb, da, db, depth = stack.pop()
            w = tb - ta
            per_pair = 0.5 * (da + db - L * w)
            p = int(np.argmin(per_pair))
            value = float(per_pair[p])
            if value >= best_exact - tolerance or 0.5 * float(L.max()) * w <= tolerance or depth >= MAX_DEPTH:
                if value < bound:
                    bound, where = value, (i, p, 0.5 * (ta + tb))
                continue
            tm = 0.5 * (ta + tb)
            dm, exact = self.midpoint(Q[i] + tm * (Q[i + 1] - Q[i]), da, db, L, w, best_exact - tolerance)
            best_exact = min(best_exact, exact)
            stack.append((i, L, tm, tb, dm, db, depth + 1))
            stack.append((i, L, ta, tm, da, dm, depth + 1))
        return bound, where[0], where[1], where[2]
