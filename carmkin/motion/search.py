"""Joint-space search with OMPL: RRT-Connect, then OMPL's path simplification, over the certified checks.

The state space is OMPL's ``RealVectorStateSpace`` over the joints that move (a locked joint, min = max, keeps
its value), each scaled by its speed limit: a coordinate is the seconds the joint needs at full speed, so
OMPL's Euclidean distance (and the simplifier's path length) is close to the motion's time. A state is valid
when it keeps the margin (exact coal distances of every pair, kept for the edges that start or end there); an
edge is valid when :meth:`carmkin.motion.certificate.Certifier.segment` certifies it — a sound check, so every
edge OMPL keeps, also in the simplifier's shortcuts, is certified clear; no path is repaired afterwards.

OMPL is a well-kept sampling-based planning library (Kavraki Lab, BSD); the planners are its own, carmkin only
provides the two checks. A search that runs out of time has found nothing: it does not prove that no path exists.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from carmkin.model.params import JOINT_RANGE_TOLERANCE

#: Planners of OMPL's ``geometric`` module that :func:`search` can run, by their carmkin name.
PLANNERS = {"rrt-connect": "RRTConnect", "aorrtc": "AORRTC", "bit-star": "BITstar", "rrt-star": "RRTstar"}
#: Share of the time budget left after the search that OMPL's simplifier may use (at least this share of the
#: search's own time limit).
SIMPLIFY_SHARE = 0.25


@dataclass
class SearchResult:
    """``waypoints`` (k+1, nq) from start to goal, or None; ``distances`` (k+1, P) their exact distances;
    ``states_checked`` / ``edges_checked``: OMPL's calls to the two checks; ``seconds`` spent."""

    waypoints: np.ndarray | None
    distances: np.ndarray | None
    states_checked: int
    edges_checked: int
    seconds: float


class _Checks:
    """The state and edge checks OMPL calls, with every state's exact distances kept by its coordinates."""

    def __init__(self, certifier, margin, q_template, free, scale) -> None:
        self.certifier, self.margin = certifier, margin
        self.q_template, self.free, self.scale = q_template, free, scale
        self.cache: dict[bytes, np.ndarray] = {}
        self.states = self.edges = 0

    def q(self, state) -> np.ndarray:
        q = self.q_template.copy()
        q[self.free] = [state[i] * s for i, s in enumerate(self.scale)]
        return q

    def distances(self, q: np.ndarray) -> np.ndarray:
        key = q.tobytes()
        d = self.cache.get(key)
        if d is None:
            d = self.cache[key] = self.certifier.distances(q)
        return d

    def state(self, state) -> bool:
        self.states += 1
        d = self.distances(self.q(state))
        return bool(not len(d) or d.min() >= self.margin)

    def edge(self, s1, s2) -> bool:
        self.edges += 1
        qa, qb = self.q(s1), self.q(s2)
        da, db = self.distances(qa), self.distances(qb)
        if len(da) and (da.min() < self.margin or db.min() < self.margin):
            return False
        return self.certifier.segment(qa, qb, da, db, self.margin).clear


def search(certifier, q_from, q_to, lower, upper, speed, margin: float, time_limit: float,
           planner: str = "rrt-connect", certified: bool = True) -> SearchResult:
    """A certified path ``q_from → q_to`` (nq,) within the joint box [lower, upper] (nq,), or none within
    ``time_limit`` (s). ``speed`` (nq,): the joints' speed limits (the metric's scale). ``certified=False``
    leaves OMPL's own discrete motion validator in place (states checked every 1 % of the space's extent, its
    default): the comparison of the benchmarks, whose paths are not certified."""
    import time

    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    start_time = time.perf_counter()
    free = np.flatnonzero(np.asarray(upper) - np.asarray(lower) > JOINT_RANGE_TOLERANCE)  # locked joints keep q_from's value
    scale = np.asarray(speed, float)[free]
    checks = _Checks(certifier, margin, np.asarray(q_from, float).copy(), free, scale)
    level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)
    space = bounds = ss = si = validator = start = goal = chosen = path = None
    try:
        space = ob.RealVectorStateSpace(len(free))
        bounds = ob.RealVectorBounds(len(free))
        for i, j in enumerate(free.tolist()):
            bounds.setLow(i, float(lower[j] / scale[i]))
            bounds.setHigh(i, float(upper[j] / scale[i]))
        space.setBounds(bounds)
        ss = og.SimpleSetup(space)
        ss.setStateValidityChecker(checks.state)
        si = ss.getSpaceInformation()

        class Validator(ob.MotionValidator):
            def checkMotion(self, s1, s2, *rest):
                return checks.edge(s1, s2)

        if certified:
            validator = Validator(si)
            si.setMotionValidator(validator)
        start, goal = space.allocState(), space.allocState()
        for i, j in enumerate(free.tolist()):
            start[i] = float(q_from[j] / scale[i])
            goal[i] = float(q_to[j] / scale[i])
        ss.setStartAndGoalStates(start, goal)
        chosen = getattr(og, PLANNERS[planner])(si)
        ss.setPlanner(chosen)
        status = ss.solve(float(time_limit))
        if not (status and ss.haveExactSolutionPath()):
            return SearchResult(None, None, checks.states, checks.edges, time.perf_counter() - start_time)
        left = max(time_limit - (time.perf_counter() - start_time), SIMPLIFY_SHARE * time_limit)
        ss.simplifySolution(float(left))
        path = ss.getSolutionPath()
        Q = np.array([checks.q(s) for s in path.getStates()])
        Q[0], Q[-1] = q_from, q_to  # exactly the ends asked (the scaled copies differ by round-off)
        D = np.array([checks.distances(q) for q in Q])
        return SearchResult(Q, D, checks.states, checks.edges, time.perf_counter() - start_time)
    finally:
        # Drop every OMPL object before returning: nanobind reports objects alive at interpreter exit as leaks.
        del path, chosen, start, goal, validator, si, ss, bounds, space
        ou.setLogLevel(level)
