"""Joint-space search with OMPL: RRT-Connect (or another of its planners), then OMPL's path simplification, over
the certified checks; and OMPL's simplifier alone on a given path (:func:`shortcut`).

The state space is OMPL's ``RealVectorStateSpace`` over the joints that move (a locked joint, min = max, keeps
its value), each scaled by its speed limit: a coordinate is the seconds the joint needs at full speed, so
OMPL's Euclidean distance (and the simplifier's path length) is close to the motion's time. A state is valid
when it keeps the margin (exact coal distances of every pair, kept for the edges that start or end there); an
edge is valid when :meth:`carmkin.motion.certificate.Certifier.segment` certifies it — a sound check, so every
edge OMPL keeps, also in the simplifier's shortcuts, is certified clear; no path is repaired afterwards.

OMPL is a well-kept sampling-based planning library (Kavraki Lab, BSD); the planners and the simplifier are its
own, carmkin only provides the two checks. A search that runs out of time has found nothing: it does not prove
that no path exists.
"""

from __future__ import annotations

import time
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


class Checks:
    """The state and edge checks, with every state's exact distances kept by its coordinates (m, rad)."""

    def __init__(self, certifier, margin) -> None:
        self.certifier, self.margin = certifier, margin
        self.cache: dict[bytes, np.ndarray] = {}
        self.states = self.edges = 0

    def distances(self, q: np.ndarray) -> np.ndarray:
        key = q.tobytes()
        d = self.cache.get(key)
        if d is None:
            d = self.cache[key] = self.certifier.distances(q)
        return d

    def state(self, q: np.ndarray) -> bool:
        self.states += 1
        d = self.distances(q)
        return bool(not len(d) or d.min() >= self.margin)

    def edge(self, qa: np.ndarray, qb: np.ndarray) -> bool:
        self.edges += 1
        da, db = self.distances(qa), self.distances(qb)
        if len(da) and (da.min() < self.margin or db.min() < self.margin):
            return False
        return self.certifier.segment(qa, qb, da, db, self.margin).clear


class _Problem:
    """OMPL's objects for one query over ``checks`` (dropped by :meth:`close`: nanobind reports objects alive at
    interpreter exit as leaks)."""

    def __init__(self, checks: Checks, q_template, lower, upper, speed, certified: bool) -> None:
        from ompl import base as ob
        from ompl import geometric as og

        self.free = free = np.flatnonzero(np.asarray(upper) - np.asarray(lower) > JOINT_RANGE_TOLERANCE)  # locked keep q
        self.scale = scale = np.asarray(speed, float)[free]
        self.template = np.asarray(q_template, float).copy()
        self.space = ob.RealVectorStateSpace(len(free))
        bounds = ob.RealVectorBounds(len(free))
        for i, j in enumerate(free.tolist()):
            bounds.setLow(i, float(lower[j] / scale[i]))
            bounds.setHigh(i, float(upper[j] / scale[i]))
        self.space.setBounds(bounds)
        self.ss = og.SimpleSetup(self.space)
        self.ss.setStateValidityChecker(lambda state: checks.state(self.q(state)))
        self.si = self.ss.getSpaceInformation()
        self.validator = None
        if certified:
            q = self.q

            class Validator(ob.MotionValidator):
                def checkMotion(self, s1, s2, *rest):
                    return checks.edge(q(s1), q(s2))

            self.validator = Validator(self.si)
            self.si.setMotionValidator(self.validator)
        self.si.setup()

    def q(self, state) -> np.ndarray:
        q = self.template.copy()
        q[self.free] = [state[i] * s for i, s in enumerate(self.scale)]
        return q

    def state(self, q):
        state = self.space.allocState()
        for i, j in enumerate(self.free.tolist()):
            state[i] = float(q[j] / self.scale[i])
        return state

    def close(self) -> None:
        for name in ("validator", "si", "ss", "space"):
            setattr(self, name, None)


def _quiet():
    from ompl import util as ou

    level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)
    return lambda: ou.setLogLevel(level)


def search(certifier, q_from, q_to, lower, upper, speed, margin: float, time_limit: float,
           planner: str = "rrt-connect", certified: bool = True, checks: Checks | None = None) -> SearchResult:
    """A certified path ``q_from → q_to`` (nq,) within the joint box [lower, upper] (nq,), or none within
    ``time_limit`` (s). ``speed`` (nq,): the joints' speed limits (the metric's scale). ``certified=False``
    leaves OMPL's own discrete motion validator in place (states checked every 1 % of the space's extent, its
    default): the comparison of the benchmarks, whose paths are not certified. ``checks``: a :class:`Checks`
    whose distances to reuse."""
    from ompl import geometric as og

    started = time.perf_counter()
    checks = checks if checks is not None else Checks(certifier, margin)
    restore = _quiet()
    problem = start = goal = chosen = path = None
    try:
        problem = _Problem(checks, q_from, lower, upper, speed, certified)
        start, goal = problem.state(q_from), problem.state(q_to)
        problem.ss.setStartAndGoalStates(start, goal)
        chosen = getattr(og, PLANNERS[planner])(problem.si)
        problem.ss.setPlanner(chosen)
        status = problem.ss.solve(float(time_limit))
        if not (status and problem.ss.haveExactSolutionPath()):
            return SearchResult(None, None, checks.states, checks.edges, time.perf_counter() - started)
        left = max(time_limit - (time.perf_counter() - started), SIMPLIFY_SHARE * time_limit)
        problem.ss.simplifySolution(float(left))
        path = problem.ss.getSolutionPath()
        Q = np.array([problem.q(s) for s in path.getStates()])
        Q[0], Q[-1] = q_from, q_to  # exactly the ends asked (the scaled copies differ by round-off)
        D = np.array([checks.distances(q) for q in Q])
        return SearchResult(Q, D, checks.states, checks.edges, time.perf_counter() - started)
    finally:
        del path, chosen, start, goal
        if problem is not None:
            problem.close()
        restore()


def shortcut(checks: Checks, Q, lower, upper, speed, time_limit: float) -> np.ndarray:
    """The polyline ``Q`` (k+1, nq), certified clear, shortened by OMPL's simplifier within ``time_limit`` (s):
    every shortcut it keeps is certified by ``checks``; the ends stay exactly ``Q[0]`` and ``Q[-1]``."""
    from ompl import geometric as og

    restore = _quiet()
    problem = path = simplifier = states = None
    try:
        problem = _Problem(checks, Q[0], lower, upper, speed, True)
        path = og.PathGeometric(problem.si)
        states = [problem.state(q) for q in Q]
        for state in states:
            path.append(state)
        simplifier = og.PathSimplifier(problem.si)
        simplifier.simplify(path, float(time_limit))
        out = np.array([problem.q(s) for s in path.getStates()])
        out[0], out[-1] = Q[0], Q[-1]
        return out
    finally:
        del path, simplifier, states
        if problem is not None:
            problem.close()
        restore()
