"""Plan a certified, timed motion between two configurations of any system (``nq`` joints).

:class:`MotionPlanner` holds what depends on the system, the patient and the margin (the world, the
certifier); :meth:`MotionPlanner.plan` runs one query:

1. the ends: in range (a locked joint at its value) and clear of the margin, else
   :class:`~carmkin.errors.MotionPlanError` naming the end, the joint or the closest pair;
2. the straight segment ``q_from → q_to``, certified by :meth:`carmkin.motion.certificate.Certifier.segment`:
   when clear, it is the motion (the time-optimal straight line);
3. otherwise the manual route — the joints one at a time in the order of :data:`carmkin.world.DEFAULT_ORDER`,
   each move certified — shortened by OMPL's simplifier (:func:`carmkin.motion.search.shortcut`) when it is clear;
   else OMPL's search (:func:`carmkin.motion.search.search`) within ``time_limit_s``, every state and edge checked
   by the same certificate, then OMPL's simplifier;
4. the path's certified minimum clearance (:meth:`~carmkin.motion.certificate.Certifier.minimum`) and its
   time law (:class:`carmkin.motion.time_law.TimeLaw`, the presets' ``[motion]`` limits).

Lengths in m, angles in rad, times in s.
"""

from __future__ import annotations

import math
import time

import numpy as np

from carmkin.errors import MotionPlanError
from carmkin.validation import JOINT_VALUE_LIMIT, real_array, real_scalar
from carmkin.world import DEFAULT_MARGIN, World
from carmkin.world.moves import greedy_moves, move_order

from .scene import scene_of
from .search import PLANNERS, Checks, search, shortcut
from .time_law import TimeLaw
from .trajectory import Trajectory

#: Default time budget (s) of one search (the straight segment needs none).
DEFAULT_TIME_LIMIT_S = 2.0
#: Share of the time budget OMPL's simplifier may spend shortening the manual route when that route is clear.
SHORTCUT_SHARE = 0.25
#: Largest time budget (s) one query may be given: ten minutes (more is a unit slip, e.g. ms as s).
MAX_TIME_LIMIT_S = 600.0


class MotionPlanner:
    """Plans motions of ``system`` (a system, or a :class:`~carmkin.model.biplane.Biplane`: both planes' joints in
    one state, the planes kept clear of each other too) around ``patient`` (as everywhere: None, a patient model
    or a list of obstacles) keeping ``margin`` (m); ``world``: a :class:`carmkin.world.World` of a single system
    to reuse. ``scene`` (:class:`carmkin.motion.scene.Scene`), ``certifier`` and ``world`` (None for a biplane)
    are what it measures with."""

    def __init__(self, system, patient=None, margin: float = DEFAULT_MARGIN, world: World | None = None) -> None:
        self.margin = real_scalar(margin, "margin", error=MotionPlanError, low=0.0, high=1.0, unit="m")
        self.scene = scene_of(system, patient, world)
        self.system, self.world, self.certifier = system, self.scene.world, self.scene.certifier
        self.speed = np.array([j.speed for j in self.scene.motion.joints])

    def check_end(self, q, name: str) -> tuple[np.ndarray, np.ndarray]:
        """``q`` (nq,) as a float array in range and clear of the margin, with its exact distances (P,)."""
        scene = self.scene
        q = real_array(q, name, (scene.nq,), error=MotionPlanError, limit=JOINT_VALUE_LIMIT, unit="m, rad")
        for r, v, prismatic in zip(scene.joint_ranges, q.tolist(), scene.prismatic):
            if not r.contains(v):
                scale, unit = (1e3, "mm") if prismatic else (math.degrees(1.0), "°")
                raise MotionPlanError(f"{name}: {r.name} = {v * scale:.6g} {unit} is outside its range "
                                      f"[{r.lower * scale:.6g}, {r.upper * scale:.6g}] {unit}")
        d = self.certifier.distances(q)
        if len(d) and d.min() < self.margin:
            k = int(np.argmin(d))
            a, b = scene.pair_names[k]
            raise MotionPlanError(f"{name} is not clear of the {self.margin * 1e3:g} mm margin: {a} is "
                                  f"{d[k] * 1e3:.1f} mm from {b}")
        return q, d

    def plan(self, q_from, q_to, time_limit_s: float = DEFAULT_TIME_LIMIT_S,
             planner: str = "rrt-connect") -> Trajectory:
        """The certified, timed motion ``q_from → q_to`` (nq,) (see the module docstring)."""
        started = time.perf_counter()
        time_limit_s = real_scalar(time_limit_s, "time_limit_s", error=MotionPlanError, low=1e-3,
                                   high=MAX_TIME_LIMIT_S, unit="s")
        if not isinstance(planner, str) or planner not in PLANNERS:
            raise MotionPlanError(f"planner must be one of {', '.join(PLANNERS)}, got {planner!r:.60}")
        q_from, d_from = self.check_end(q_from, "q_from")
        q_to, d_to = self.check_end(q_to, "q_to")
        straight = self.certifier.segment(q_from, q_to, d_from, d_to, self.margin)
        if straight.clear:
            return self._trajectory(np.array([q_from, q_to]), np.array([d_from, d_to]), straight.bound, "straight",
                                    started)
        # OMPL sees the ends inside its bounds (a value within the range tolerance outside moves by round-off); the
        # path returned starts and ends exactly at q_from and q_to and is certified again as returned
        lower, upper = self.scene.lower, self.scene.upper
        inside_from, inside_to = np.clip(q_from, lower, upper), np.clip(q_to, lower, upper)
        checks = Checks(self.certifier, self.margin)
        manual = self._joint_by_joint(checks, inside_from, inside_to)
        if manual is not None:  # the manual route is clear: OMPL's simplifier shortens it
            Q = shortcut(checks, manual, lower, upper, self.speed, SHORTCUT_SHARE * time_limit_s)
            changed = len(Q) != len(manual) or np.any(Q != manual)
            method = "joint by joint" + (", shortcut by OMPL" if changed else "")
        else:
            found = search(self.certifier, inside_from, inside_to, lower, upper, self.speed, self.margin,
                           time_limit_s, planner, checks=checks)
            if found.waypoints is None:
                return self.failed(q_from, f"not found within {time_limit_s:g} s by OMPL's {PLANNERS[planner]} "
                                           f"({found.states_checked} states, {found.edges_checked} edges checked; "
                                           f"neither the direct segment nor the joints one by one are clear: this "
                                           f"does not prove that no path exists)", started)
            Q, method = found.waypoints, PLANNERS[planner]
        Q = Q.copy()
        Q[0], Q[-1] = q_from, q_to
        D = np.array([checks.distances(q) for q in Q])
        D[0], D[-1] = d_from, d_to
        bound = math.inf
        for i in range(len(Q) - 1):  # the path as returned (exact ends), certified again: cheap, distances known
            check = self.certifier.segment(Q[i], Q[i + 1], D[i], D[i + 1], self.margin)
            if not check.clear:
                return self.failed(q_from, f"the path ({method}) did not certify again at segment {i}", started)
            bound = min(bound, check.bound)
        return self._trajectory(Q, D, bound, method, started)

    def _joint_by_joint(self, checks: Checks, q_from, q_to) -> np.ndarray | None:
        """The manual route (:func:`carmkin.world.moves.greedy_moves` in :data:`carmkin.world.DEFAULT_ORDER`, each
        move certified by ``checks``) as a polyline, or None when it is blocked (or the scene has no one world)."""
        if self.world is None:
            return None
        done, blocked = greedy_moves(q_from, q_to, move_order(self.system),
                                     lambda a, b: (checks.edge(a, b), None))
        if blocked is not None:
            return None
        return np.array([q_from] + [after for _, _, after, _ in done])

    def failed(self, q_from, reason: str, started: float | None = None) -> Trajectory:
        """A trajectory that was not found, starting at ``q_from``, and why (``started``: perf_counter at the
        query's start, for its planning time)."""
        q = np.asarray(q_from, float)[None]
        seconds = 0.0 if started is None else time.perf_counter() - started
        return Trajectory(False, reason, q, np.zeros(1), math.nan, None, self.margin, "none", seconds,
                          self.scene.joint_names)

    def _trajectory(self, Q, D, clear_bound: float, method: str, started: float) -> Trajectory:
        """The trajectory through ``Q`` (distances ``D``), certified clear with the bound ``clear_bound`` (m)."""
        bound, _, pair, _ = self.certifier.minimum(Q, D)
        bound = max(bound, clear_bound)  # two certified lower bounds of one minimum: the larger holds too
        names = self.scene.pair_names[pair] if pair >= 0 else None
        law = TimeLaw(self.scene.motion, Q)
        return Trajectory(True, None, Q, law.times, bound, names, self.margin, method,
                          time.perf_counter() - started, self.scene.joint_names, law)


def plan_motion(system, q_from, q_to, patient=None, margin: float = DEFAULT_MARGIN,
                time_limit_s: float = DEFAULT_TIME_LIMIT_S, planner: str = "rrt-connect") -> Trajectory:
    """The certified, timed motion of ``system`` (a system or a biplane) from ``q_from`` to ``q_to`` (nq,) (m, rad)
    around ``patient`` keeping ``margin`` (m): :meth:`MotionPlanner.plan` (builds the world each call; to plan many motions,
    build one :class:`MotionPlanner`)."""
    return MotionPlanner(system, patient, margin).plan(q_from, q_to, time_limit_s, planner)
