"""The time law of a joint-space polyline: each segment a straight line, timed optimally, from rest to rest.

Between two waypoints the joints move along the straight segment ``q(s) = q_a + s Δq``, s ∈ [0, 1], so the
executed geometry is exactly the segment the certificate covers (:mod:`carmkin.motion.certificate`). Along a
straight line every joint's speed and acceleration are ``|Δq_j| ṡ`` and ``|Δq_j| s̈``: the limits of the
system's :class:`~carmkin.model.motion.Motion` become one limit on the path parameter,

    ṡ ≤ v_s = min_j v_j / |Δq_j|,     |s̈| ≤ a_s = min_j a_j / |Δq_j|      (joints with Δq_j ≠ 0),

and the time-optimal rest-to-rest motion along the segment is the trapezoid (or triangle) in s of
``carmkin.model.motion.joint_time`` with ``d = 1`` (Siciliano et al. 2009, §4.2.1; the same result as
time-optimal path parameterization of a straight line, e.g. toppra, which the tests hold it to). At a waypoint
the direction of motion changes, so a path through it without stopping would need an unbounded acceleration:
every segment starts and ends at rest. Joints whose acceleration is not known reach their speed at once
(``a_j = ∞``; their ``q̈`` is zero between the impulses at the ends, as in :mod:`carmkin.model.motion`).

Times in s, q in m and rad (the system's joint order), q̇ in m/s and rad/s, q̈ in m/s² and rad/s².
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import MotionError
from carmkin.model.motion import Motion


@dataclass(frozen=True)
class SegmentLaw:
    """The trapezoid of one segment in its path parameter: ``v`` (1/s) cruise speed reached, ``a`` (1/s², inf
    when no acceleration is known) acceleration, ``duration`` (s); ``accelerating`` (s) the time spent speeding
    up (= the time slowing down)."""

    v: float
    a: float
    duration: float

    @property
    def accelerating(self) -> float:
        return 0.0 if math.isinf(self.a) else self.v / self.a

    def s(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Path parameter, its rate and its acceleration at times ``t`` (s) in [0, duration]."""
        T, v, a, ta = self.duration, self.v, self.a, self.accelerating
        t = np.clip(t, 0.0, T)
        if T == 0.0:
            return np.ones_like(t), np.zeros_like(t), np.zeros_like(t)
        if ta == 0.0:
            return t / T, np.full_like(t, 1.0 / T), np.zeros_like(t)
        up, down = t < ta, t > T - ta
        s = np.where(up, 0.5 * a * t ** 2, np.where(down, 1.0 - 0.5 * a * (T - t) ** 2, 0.5 * v * ta + v * (t - ta)))
        sd = np.where(up, a * t, np.where(down, a * (T - t), v))
        sdd = np.where(up, a, np.where(down, -a, 0.0))
        return s, sd, sdd


def segment_law(motion: Motion, delta: np.ndarray) -> SegmentLaw:
    """The time-optimal rest-to-rest trapezoid of the straight move ``delta`` (nq,) (m, rad) under ``motion``."""
    moving = np.abs(delta) > 0.0
    if not moving.any():
        return SegmentLaw(0.0, math.inf, 0.0)
    d = np.abs(delta[moving])
    speed = np.array([j.speed for j in motion.joints])[moving]
    accel = np.array([math.inf if j.acceleration is None else j.acceleration for j in motion.joints])[moving]
    v = float(np.min(speed / d))
    a = float(np.min(accel / d))
    if math.isinf(a):
        return SegmentLaw(v, a, 1.0 / v)
    if 1.0 >= v * v / a:  # trapezoid: joint_time(1, v, a) written out (a round-off move gives huge v, a: no check)
        return SegmentLaw(v, a, 1.0 / v + v / a)
    return SegmentLaw(math.sqrt(a), a, 2.0 / math.sqrt(a))  # triangle: peak rate of s √a


class TimeLaw:
    """q(t), q̇(t), q̈(t) of the polyline ``waypoints`` (k+1, nq) under ``motion``: one :class:`SegmentLaw` per
    segment, each from rest to rest. ``times`` (k+1,): when each waypoint is reached (s)."""

    def __init__(self, motion: Motion, waypoints: np.ndarray) -> None:
        if not isinstance(motion, Motion):
            raise MotionError(f"motion must be a carmkin.model.motion.Motion, got {type(motion).__name__}")
        self.waypoints = np.asarray(waypoints, dtype=float)
        self.deltas = np.diff(self.waypoints, axis=0)
        self.segments = tuple(segment_law(motion, d) for d in self.deltas)
        self.times = np.concatenate(([0.0], np.cumsum([s.duration for s in self.segments])))

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def sample(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q, q̇, q̈)`` each (len(t), nq) at times ``t`` (s, within [0, duration])."""
        t = np.asarray(t, dtype=float).reshape(-1)
        n = self.waypoints.shape[1]
        q = np.empty((len(t), n))
        qd = np.zeros((len(t), n))
        qdd = np.zeros((len(t), n))
        if not self.segments:
            q[:] = self.waypoints[0]
            return q, qd, qdd
        which = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.segments) - 1)
        for i in np.unique(which).tolist():
            m = which == i
            s, sd, sdd = self.segments[i].s(t[m] - self.times[i])
            delta = self.deltas[i]
            q[m] = self.waypoints[i] + s[:, None] * delta
            qd[m] = sd[:, None] * delta
            qdd[m] = sdd[:, None] * delta
        return q, qd, qdd
