"""Joint speeds and accelerations, and how long a move takes (SI: m/s and m/s² for prismatic joints, rad/s
and rad/s² for revolute ones; times in s).

**One joint.** A joint that moves a distance ``d`` from rest to rest under a speed limit ``v`` and an
acceleration limit ``a`` takes the time-optimal trapezoidal velocity profile: accelerate at ``a`` up to
``v``, cruise, decelerate at ``a``. When ``d < v²/a`` it never reaches ``v`` and the profile is triangular
(peak speed ``√(a d)``)::

    t(d) = d/v + v/a     for d ≥ v²/a   (trapezoidal)
    t(d) = 2 √(d/a)      for d < v²/a   (triangular)

Both give ``2 v/a`` at the switch ``d = v²/a``, so ``t`` is continuous and increasing in ``d``. A joint
whose acceleration is not known (``acceleration=None``) moves at its speed at once: ``t(d) = d/v``, a lower
bound of the true time. (Siciliano, Sciavicco, Villani, Oriolo, *Robotics: Modelling, Planning and
Control*, Springer 2009, §4.2.1, the trapezoidal velocity profile of point-to-point motion.)

**Several joints.** A *synchronized* move starts every joint at once — the standard assumption of
point-to-point motion of a multi-axis machine (ibid.) — so it lasts as long as its slowest joint,
``T = max_j t_j(|Δq_j|)``; the other joints are slowed to end with it (same acceleration, a lower cruise
speed: :func:`velocity_profile`), which does not change ``T``. The moves the planners check for collision
(:meth:`carmkin.world.World.moves`, the repositioning guidance) are *joint by joint*: one joint at a time,
each from rest to rest, so they last ``Σ_j t_j``. A *path* of waypoints is a sequence of synchronized
moves, each starting and ending at rest: ``Σ_segments max_j t_j``.

**A sweep at a given acquisition time** (:func:`follow`): the views are acquired at equal time steps
``Δt = T/(n − 1)`` along the sampled joint trajectory (n views). Each joint's speed on a step is its change
over ``Δt`` and its acceleration at a view the change of those speeds over ``Δt`` (finite differences at the
views' resolution); the joints are already moving at the first view and still moving at the last: the run-up
from rest before the first view and the stop after the last (each joint at its acceleration, the slowest
sets it) are added to the sweep's duration, outside the acquisition and its collision check.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import MotionError
from carmkin.validation import JOINT_VALUE_LIMIT, real_array, real_scalar

#: The reason a plan reports no duration when its system has no joint speeds.
NO_SPEEDS = "no joint speeds in the preset"
#: A joint follows a sweep when its required speed and acceleration are at most its limits times
#: ``1 + FOLLOW_TOLERANCE`` (round-off of the finite differences; far below any drive's accuracy).
FOLLOW_TOLERANCE = 1e-9
#: Largest speed (m/s or rad/s) and acceleration (m/s² or rad/s²) a joint may be given: 1e3, far beyond any
#: C-arm or table (a larger value is a unit slip, e.g. mm/s given as m/s).
MAX_RATE = 1e3
#: Shortest and longest acquisition time (s) a sweep may be asked for: a millisecond to a day (beyond, a unit
#: slip; the bounds keep the finite differences finite).
ACQUISITION_TIME_RANGE = (1e-3, 86400.0)
#: Smallest speed and acceleration a joint may be given (same units): 1e-6, a micrometre or microradian per
#: second; zero or less is no speed (a joint that cannot move is not a joint).
MIN_RATE = 1e-6


@dataclass(frozen=True)
class JointMotion:
    """Speed limit ``speed`` (m/s or rad/s, > 0) and acceleration limit ``acceleration`` (m/s² or rad/s²,
    > 0; ``None`` when not known: the joint then reaches its speed at once) of the joint ``name``."""

    speed: float
    acceleration: float | None = None
    name: str = "joint"

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise MotionError(f"JointMotion.name must be a joint name (a non-empty string), got {self.name!r:.60}")
        object.__setattr__(self, "speed", _rate(self.speed, f"{self.name} speed", "m/s or rad/s"))
        if self.acceleration is not None:
            object.__setattr__(self, "acceleration",
                               _rate(self.acceleration, f"{self.name} acceleration", "m/s² or rad/s²"))

    def time(self, distance: float) -> float:
        """Seconds to move ``|distance|`` (m or rad) from rest to rest (the module's profile)."""
        return joint_time(distance, self.speed, self.acceleration)


def _rate(value, what: str, unit: str) -> float:
    """A speed or acceleration: a real, finite number in (0, :data:`MAX_RATE`], or MotionError naming it."""
    number = real_scalar(value, what, error=MotionError, unit=unit)
    if not MIN_RATE <= number <= MAX_RATE:
        raise MotionError(f"{what} must be in [{MIN_RATE:g}, {MAX_RATE:g}] {unit}, got {number:g} {unit}"
                          + (" (a joint that cannot move has no speed: leave it out of the system's motion)"
                             if number == 0 else ""))
    return number


@dataclass(frozen=True)
class Motion:
    """The speed and acceleration of every joint of a system, in the order of q (``joints``: one
    :class:`JointMotion` per joint, named as :attr:`carmkin.CArmSystem.joint_names`)."""

    joints: tuple[JointMotion, ...]

    def __post_init__(self) -> None:
        joints = tuple(self.joints) if isinstance(self.joints, (list, tuple)) else self.joints
        if not isinstance(joints, tuple) or not joints or not all(isinstance(j, JointMotion) for j in joints):
            raise MotionError(f"Motion.joints must be a non-empty tuple of JointMotion, got {self.joints!r:.80}")
        names = [j.name for j in joints]
        if len(set(names)) != len(names):
            raise MotionError(f"Motion.joints name a joint twice: {names}")
        object.__setattr__(self, "joints", joints)

    @classmethod
    def of(cls, names, speeds, accelerations=None) -> "Motion":
        """A motion from parallel sequences: joint names, speeds and accelerations (``None`` entries or
        ``accelerations=None``: not known)."""
        names, speeds = _sequence(names, "names"), _sequence(speeds, "speeds")
        accelerations = [None] * len(names) if accelerations is None else _sequence(accelerations, "accelerations")
        if not len(names) == len(speeds) == len(accelerations):
            raise MotionError(f"Motion.of: {len(names)} names, {len(speeds)} speeds and {len(accelerations)} "
                              "accelerations: give one of each per joint")
        return cls(tuple(JointMotion(s, a, n) for n, s, a in zip(names, speeds, accelerations)))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    @property
    def nq(self) -> int:
        return len(self.joints)

    def for_joints(self, names) -> "Motion | None":
        """This motion for the joints ``names`` (in that order), or None when one of them has no speed here."""
        by_name = {j.name: j for j in self.joints}
        if not all(n in by_name for n in names):
            return None
        return Motion(tuple(by_name[n] for n in names))

    def __getitem__(self, name: str) -> JointMotion:
        for joint in self.joints:
            if joint.name == name:
                return joint
        raise MotionError(f"no joint {name!r} in this motion; joints: {', '.join(self.names)}")


def _sequence(value, name: str) -> list:
    """``value`` (a list, tuple or 1-D array: one entry per joint) as a list, or MotionError naming ``name``."""
    if not isinstance(value, (list, tuple, np.ndarray)) or (isinstance(value, np.ndarray) and value.ndim != 1):
        raise MotionError(f"Motion.of: {name} must be a list with one entry per joint, got {value!r:.60}")
    return list(value)


def _timing(timing, allowed) -> Timing:
    """``timing`` when it is one of ``allowed`` (:class:`Timing` members), or MotionError naming them."""
    if not isinstance(timing, Timing) or timing not in allowed:
        raise MotionError(f"timing must be {' or '.join(f'Timing.{t.name}' for t in allowed)} for one move, got "
                          f"{timing!r:.60}")
    return timing


def joint_time(distance, speed, acceleration=None) -> float:
    """Seconds for one joint to move ``|distance|`` (m or rad) from rest to rest at ``speed`` (m/s or rad/s)
    and ``acceleration`` (m/s² or rad/s², ``None``: not known): trapezoidal, or triangular when short."""
    d = abs(real_scalar(distance, "distance", error=MotionError, limit=JOINT_VALUE_LIMIT, unit="m or rad"))
    v = _rate(speed, "speed", "m/s or rad/s")
    if acceleration is None:
        return d / v
    a = _rate(acceleration, "acceleration", "m/s² or rad/s²")
    return d / v + v / a if d >= v * v / a else 2.0 * math.sqrt(d / a)


class Timing(enum.Enum):
    """How the joints of a move share the time (see the module docstring)."""

    SYNCHRONIZED = "synchronized"      # every joint at once: the slowest sets the time
    JOINT_BY_JOINT = "joint by joint"  # one joint after another, each from rest to rest: the times add
    PATH = "path"                      # synchronized segments between waypoints, each from rest to rest


@dataclass(frozen=True)
class Duration:
    """How long a move lasts. ``seconds`` (None when unknown, ``reason`` then says why); ``timing``
    (:class:`Timing`); ``parts``: seconds per joint (synchronized, joint by joint) or per segment (path);
    ``slowest``: the joint that sets a synchronized move's time (or the longest joint-by-joint move)."""

    seconds: float | None
    timing: Timing
    parts: tuple[float, ...] = ()
    slowest: str | None = None
    reason: str | None = None

    def __str__(self) -> str:
        if self.seconds is None:
            return f"duration unknown: {self.reason}"
        if self.timing is not Timing.PATH and sum(p > 0 for p in self.parts) == 1:
            return f"{self.seconds:.1f} s ({self.slowest} alone)"
        by = f", {self.slowest} the longest" if self.slowest else ""
        return f"{self.seconds:.1f} s ({self.timing.value}{by})"


def unknown(timing: Timing = Timing.SYNCHRONIZED, reason: str = NO_SPEEDS) -> Duration:
    """A duration that cannot be given, and why (default: :data:`NO_SPEEDS`)."""
    return Duration(None, timing, reason=reason)


def _joints(motion: Motion, value, name: str, shape) -> np.ndarray:
    if not isinstance(motion, Motion):
        raise MotionError(f"motion must be a carmkin.model.motion.Motion (system.motion), got "
                          f"{type(motion).__name__}")
    return real_array(value, name, shape, error=MotionError, limit=JOINT_VALUE_LIMIT, unit="m, rad")


def joint_times(motion: Motion, q_from, q_to) -> np.ndarray:
    """Seconds (nq,) each joint needs for its part of the move ``q_from`` → ``q_to`` (nq,), alone."""
    a = _joints(motion, q_from, "q_from", (motion.nq if isinstance(motion, Motion) else None,))
    b = _joints(motion, q_to, "q_to", (motion.nq,))
    return np.array([j.time(float(d)) for j, d in zip(motion.joints, b - a)])


def move_duration(motion: Motion, q_from, q_to, timing: Timing = Timing.SYNCHRONIZED) -> Duration:
    """The duration of the move ``q_from`` → ``q_to`` (nq,): ``max_j t_j`` synchronized (every joint at
    once), ``Σ_j t_j`` joint by joint."""
    timing = _timing(timing, (Timing.SYNCHRONIZED, Timing.JOINT_BY_JOINT))
    times = joint_times(motion, q_from, q_to)
    total = float(times.max()) if timing is Timing.SYNCHRONIZED else float(times.sum())
    slowest = motion.joints[int(np.argmax(times))].name if times.max() > 0 else None
    return Duration(total, timing, tuple(float(t) for t in times), slowest)


def path_duration(motion: Motion, waypoints) -> Duration:
    """The duration of the path through ``waypoints`` (k, nq), k ≥ 1: one synchronized move per segment,
    each from rest to rest; ``parts`` the segments' seconds (k − 1,)."""
    Q = _joints(motion, waypoints, "waypoints", (None, motion.nq if isinstance(motion, Motion) else None))
    if not len(Q):
        raise MotionError(f"waypoints must hold at least one configuration ({motion.nq},), got none")
    parts = tuple(move_duration(motion, a, b).seconds for a, b in zip(Q[:-1], Q[1:]))
    return Duration(float(sum(parts)), Timing.PATH, parts)


def velocity_profile(motion: Motion, q_from, q_to, t) -> np.ndarray:
    """Joint velocities (len(t), nq) (m/s, rad/s) of the synchronized move ``q_from`` → ``q_to`` at times
    ``t`` (s, from its start): each joint a trapezoid (or triangle) ending with the slowest joint, at its own
    acceleration with the cruise speed lowered to fit, zero outside ``[0, T]``."""
    times = joint_times(motion, q_from, q_to)
    delta = np.asarray(q_to, float) - np.asarray(q_from, float)
    # a move at the smallest rates lasts far beyond 1e6 s: t only guards overflow (a·t stays finite)
    t = real_array(t, "t", (None,), error=MotionError, limit=JOINT_VALUE_LIMIT, unit="s")
    T = float(times.max())
    out = np.zeros((len(t), motion.nq))
    if T == 0.0:
        return out
    for k, (joint, d) in enumerate(zip(motion.joints, delta)):
        d_abs = abs(float(d))
        if d_abs == 0.0:
            continue
        a = joint.acceleration
        if a is None:  # speed only: constant d/T over the whole move (at most the speed: min() drops round-off)
            out[:, k] = np.where((t >= 0) & (t <= T), math.copysign(min(d_abs / T, joint.speed), d), 0.0)
            continue
        # cruise speed v with d/v + v/a = T, the smaller root (a trapezoid of duration T; T ≥ 2√(d/a) here):
        # ½(aT − √((aT)² − 4ad)) loses v to cancellation when v ≪ aT (issue 41: up to 1.4e-3 above the speed
        # limit, 6.5 % off the move), so the root is taken in the form without a difference, 2d/(T + √(T² − 4d/a)),
        # written 2d / (T (1 + √(1 − 4d/(aT²)))) so that T² cannot overflow. It is at most the joint's speed
        # (equal for the slowest joint); min() drops the last ulp of round-off.
        ratio = 4.0 * d_abs / a / T / T
        v = min(2.0 * d_abs / (T * (1.0 + math.sqrt(max(1.0 - ratio, 0.0)))), joint.speed)
        speed = np.clip(np.minimum(a * t, a * (T - t)), 0.0, v)
        speed[(t < 0) | (t > T)] = 0.0
        out[:, k] = math.copysign(1.0, d) * speed
    return out


# --- sweeps at an acquisition time ------------------------------------------------------------------


class Follow(enum.Enum):
    """Whether the joints can follow a sweep at the asked acquisition time."""

    FOLLOWS = "follows"          # every joint within its speed and acceleration
    TOO_FAST = "too fast"        # a joint would exceed its speed or acceleration (``joint``, ``quantity``)
    NOT_ASKED = "not asked"      # no acquisition time given: ``minimum_time`` is the fastest the joints allow
    NO_SPEEDS = "no joint speeds"  # the system has no motion: nothing can be checked


@dataclass(frozen=True)
class FollowCheck:
    """The speed check of a sweep (see the module docstring for the model).

    ``status`` (:class:`Follow`); ``acquisition_time``: asked (s, None if not); ``minimum_time``: the
    shortest acquisition (s) every joint can follow; ``joint`` and ``quantity`` (``"speed"`` or
    ``"acceleration"``): the binding joint — the one that cannot follow when ``TOO_FAST``, the one that sets
    ``minimum_time`` otherwise; ``required`` and ``limit``: its peak need at the asked time (or at
    ``minimum_time``) and its limit (m/s, rad/s, m/s², rad/s²), ``ratio = required / limit`` (> 1: by how
    much it cannot follow); ``run_up`` / ``run_out``: seconds to reach the first view's speeds from rest and
    to stop after the last; ``duration``: ``run_up + acquisition + run_out`` (s; the acquisition is the asked
    time, else ``minimum_time``); ``prismatic``: of the binding joint (for the units of :meth:`__str__`)."""

    status: Follow
    acquisition_time: float | None = None
    minimum_time: float | None = None
    joint: str | None = None
    quantity: str | None = None
    required: float = math.nan
    limit: float = math.nan
    run_up: float = 0.0
    run_out: float = 0.0
    prismatic: bool = False

    @property
    def ratio(self) -> float:
        return self.required / self.limit if self.limit == self.limit and self.limit > 0 else math.nan

    @property
    def duration(self) -> float | None:
        acquisition = self.acquisition_time if self.acquisition_time is not None else self.minimum_time
        return None if acquisition is None else self.run_up + acquisition + self.run_out

    def __str__(self) -> str:
        if self.status is Follow.NO_SPEEDS:
            return f"speed check not possible: {NO_SPEEDS}"
        unit = ("mm/s" if self.prismatic else "°/s") + ("²" if self.quantity == "acceleration" else "")
        scale = 1e3 if self.prismatic else math.degrees(1.0)
        required, limit = f"{self.required * scale:.3g} {unit}", f"{self.limit * scale:.3g} {unit}"
        if self.status is Follow.TOO_FAST:
            return (f"the joints cannot follow a {self.acquisition_time:.1f} s acquisition: {self.joint} needs "
                    f"{self.quantity} {required}, its limit is {limit} ({self.ratio:.2f}x); the fastest acquisition "
                    f"they follow takes {self.minimum_time:.1f} s")
        if self.status is Follow.FOLLOWS:
            return (f"the joints follow a {self.acquisition_time:.1f} s acquisition ({self.joint} at {self.ratio:.0%} "
                    f"of its {self.quantity} limit, {required} of {limit}); the fastest takes "
                    f"{self.minimum_time:.1f} s")
        return (f"the fastest acquisition the joints follow takes {self.minimum_time:.1f} s ({self.joint} at its "
                f"{self.quantity} limit {limit})")


def check_acquisition_time(value, error=MotionError) -> float:
    """``value`` (s) as a float within :data:`ACQUISITION_TIME_RANGE`, or ``error`` naming
    ``acquisition_time_s``."""
    low, high = ACQUISITION_TIME_RANGE
    return real_scalar(value, "acquisition_time_s", error=error, low=low, high=high, unit="s")


def follow(motion: Motion | None, q, acquisition_time=None, prismatic=None) -> FollowCheck:
    """Can the joints follow the sampled sweep ``q`` (n, nq), n ≥ 2 views acquired at equal steps over
    ``acquisition_time`` (s, > 0; None: only the fastest time the joints allow)? ``motion`` None (a system
    without speeds) gives :attr:`Follow.NO_SPEEDS`. ``prismatic`` (nq,) bools: for the units of the
    sentence (default all revolute). A joint that cannot follow is data (``TOO_FAST``), not an error."""
    if motion is None:
        return FollowCheck(Follow.NO_SPEEDS, None if acquisition_time is None else check_acquisition_time(acquisition_time))
    Q = _joints(motion, q, "q", (None, motion.nq if isinstance(motion, Motion) else None))
    if len(Q) < 2:
        raise MotionError(f"a sweep needs at least two views to be timed, got {len(Q)}")
    if acquisition_time is not None:
        acquisition_time = check_acquisition_time(acquisition_time)
    if prismatic is None:
        prismatic = (False,) * motion.nq
    elif (not isinstance(prismatic, (list, tuple, np.ndarray)) or getattr(prismatic, "ndim", 1) != 1
          or len(prismatic) != motion.nq
          or not all(isinstance(p, (bool, np.bool_)) for p in prismatic)):
        raise MotionError(f"prismatic must be {motion.nq} bools (one per joint: True for a prismatic joint), got "
                          f"{prismatic!r:.60}")
    else:
        prismatic = tuple(bool(p) for p in prismatic)
    steps = len(Q) - 1
    step = np.diff(Q, axis=0)                        # Δq per step (steps, nq)
    bend = np.diff(step, axis=0) if steps > 1 else np.zeros((0, motion.nq))  # Δ²q at interior views
    speed = np.array([j.speed for j in motion.joints])
    accel = np.array([j.acceleration if j.acceleration is not None else math.inf for j in motion.joints])
    peak_step = np.abs(step).max(axis=0)
    peak_bend = np.abs(bend).max(axis=0) if len(bend) else np.zeros(motion.nq)
    # the shortest time step each joint allows: Δq/Δt ≤ v and Δ²q/Δt² ≤ a
    dt_speed = peak_step / speed
    dt_accel = np.sqrt(peak_bend / accel)
    dt_min = float(max(dt_speed.max(), dt_accel.max()))
    minimum_time = dt_min * steps
    dt = dt_min if acquisition_time is None else acquisition_time / steps
    if dt == 0.0:  # nothing moves
        return FollowCheck(Follow.NOT_ASKED if acquisition_time is None else Follow.FOLLOWS, acquisition_time, 0.0)
    ratio_speed = peak_step / dt / speed
    ratio_accel = peak_bend / dt ** 2 / accel
    k_speed, k_accel = int(np.argmax(ratio_speed)), int(np.argmax(ratio_accel))
    if ratio_accel[k_accel] > ratio_speed[k_speed]:
        k, quantity, required, limit = k_accel, "acceleration", peak_bend[k_accel] / dt ** 2, accel[k_accel]
    else:
        k, quantity, required, limit = k_speed, "speed", peak_step[k_speed] / dt, speed[k_speed]
    if acquisition_time is None:
        status = Follow.NOT_ASKED
    else:
        status = Follow.FOLLOWS if required <= limit * (1.0 + FOLLOW_TOLERANCE) else Follow.TOO_FAST
    finite = np.isfinite(accel)
    ramps = [float(np.max(np.where(finite, np.abs(v) / dt / np.where(finite, accel, 1.0), 0.0)))
             for v in (step[0], step[-1])]
    return FollowCheck(status, acquisition_time, minimum_time, motion.joints[k].name, quantity, float(required),
                       float(limit), ramps[0], ramps[1], prismatic[k])


# --- for a system ------------------------------------------------------------------------------------


def system_move(system, q_from, q_to, timing: Timing = Timing.SYNCHRONIZED) -> Duration:
    """:func:`move_duration` on ``system.motion``, or an unknown duration (:data:`NO_SPEEDS`) without it."""
    if not (hasattr(system, "motion") and hasattr(system, "joint_names")):  # a CArmSystem (no import: system imports us)
        raise MotionError(f"system must be a carmkin.CArmSystem (carmkin.load_preset(...)), got {type(system).__name__}")
    if system.motion is None:
        return unknown(_timing(timing, (Timing.SYNCHRONIZED, Timing.JOINT_BY_JOINT)))
    return move_duration(system.motion, q_from, q_to, timing)
