"""Constraints of one QP step as objects (as pink and mink do): joint limits as bounds, collision avoidance
as inequality rows ``G dq <= h``.

:class:`JointLimits` bounds the step ``dq`` by the joint box and the trust region ``|dq_i| <= max_step``,
and holds locked joints. :class:`CollisionAvoidance` is the discrete velocity damper of Faverjon &
Tournassoud: a step may close at most the fraction ``gain`` of the gap to the safety margin,
``-grad d_k · dq <= gain (d_k - margin)``; a pair already inside the margin must leave it in one
(linearised) step, ``-grad d_k · dq <= d_k - margin``. Pairs farther than ``influence_distance`` add no row
(broad phase). ``grad d`` comes from coal's witness points and normals
(:meth:`carmkin.world.World.distance_jacobian`). Lengths in metres, angles in radians.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from carmkin.world import World
from carmkin.robot.state import KinematicState

from .options import MARGIN_TOLERANCE, QPIKError


class JointLimits:
    """Bounds ``lb <= dq <= ub`` of a step from ``q``: joint box ``[lower, upper]`` (nv,), trust region
    ``max_step`` (m or rad), and ``locked`` joint indices whose step is 0."""

    def __init__(self, lower, upper, max_step: float, locked: Sequence[int] = ()) -> None:
        self.lower, self.upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
        self.max_step = float(max_step)
        self.free = np.ones(self.lower.size, dtype=bool)
        for index in locked:
            if not 0 <= int(index) < self.lower.size:
                raise QPIKError(f"locked joint index {index} outside 0..{self.lower.size - 1}")
            self.free[int(index)] = False

    def bounds(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(lb, ub)`` (nv,) of the step from ``q``; ``lb > ub`` somewhere when ``q`` lies more than
        ``max_step`` outside the box."""
        lb = np.maximum(self.lower - q, -self.max_step)
        ub = np.minimum(self.upper - q, self.max_step)
        lb[~self.free] = ub[~self.free] = 0.0
        return lb, ub

    def project(self, q: np.ndarray) -> np.ndarray:
        """``q`` clipped onto the joint box (removes floating-point residue after a bounded step)."""
        return np.clip(q, self.lower, self.upper)

    def at_limits(self, q: np.ndarray, tolerance: float) -> np.ndarray:
        """Indices of the joints within ``tolerance`` of a bound."""
        return np.flatnonzero((np.abs(q - self.lower) < tolerance) | (np.abs(q - self.upper) < tolerance))


class CollisionAvoidance:
    """Velocity-damper rows of the pairs of ``world`` closer than ``influence_distance`` (m)."""

    def __init__(self, world: World, margin: float, gain: float, influence_distance: float) -> None:
        self.world, self.margin, self.gain, self.influence = world, float(margin), float(gain), float(influence_distance)

    def __len__(self) -> int:
        return len(self.world)

    def inequalities(self, state: KinematicState) -> tuple[np.ndarray, np.ndarray] | None:
        """``(G (K, nv), h (K,))`` for the near pairs at ``state`` (Jacobians computed), or ``None``."""
        distances = state.distances
        near = self.world.proximity(distances, self.influence)
        if not near.index.size:
            return None
        gap = near.distance - self.margin
        return -self.world.distance_jacobian(near, state.data.J), np.where(gap >= 0, self.gain * gap, gap)

    def clear(self, state: KinematicState) -> bool:
        """Every pair at least the margin apart (up to :data:`MARGIN_TOLERANCE`)."""
        return state.min_distance >= self.margin - MARGIN_TOLERANCE

    def near_pairs(self, distances: np.ndarray, slack: float) -> tuple[str, ...]:
        """Names ``"first/second"`` of the pairs closer than ``margin + slack``."""
        limit = self.margin + slack
        return tuple(f"{a}/{b}" for k, (a, b) in enumerate(self.world.pairs) if distances[k] < limit)
