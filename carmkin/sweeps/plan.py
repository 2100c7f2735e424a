"""Plan a cone-beam CT sweep: joints, source poses and projection matrices per frame, swept clearance, the
joint that limits the arc, isocentre drift and the short-scan check (see :mod:`.trajectory` and
:mod:`.clearance` for the mathematics). Library units: m and rad, table frame 0; sentences in mm and degrees.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import numpy as np

from carmkin.errors import SweepError
from carmkin.model import motion
from carmkin.model.system import require_system
from carmkin.validation import flag, real_array, real_scalar, target_point

from carmkin.world import DEFAULT_MARGIN, DEFAULT_TOLERANCE, World
from carmkin.world.obstacles import as_obstacles

from . import trajectory as tr
#: Most frames a sweep may have (bounds the cost of planning and export).
MAX_VIEWS = 2000


class Limit(enum.Enum):
    """Why (part of) an arc is not feasible."""

    JOINT_LIMIT = "joint limit"
    CONTACT = "contact"
    UNREACHABLE = "unreachable"


@dataclass(frozen=True)
class SweepFailure:
    """The first obstruction along the arc: ``kind`` (:class:`Limit`), ``angle`` φ (rad) where it happens,
    ``frame`` index, ``joint`` (name, for a joint limit), ``pair`` (link names, for a contact), ``distance``
    (m, for a contact) and the largest feasible arc ``feasible`` = (φ_first, φ_last) of whole frames (rad)."""

    kind: Limit
    angle: float
    frame: int
    feasible: tuple[float, float] | None
    joint: str | None = None
    pair: tuple[str, str] | None = None
    distance: float | None = None

    def __str__(self) -> str:
        where = f"at φ = {math.degrees(self.angle):+.1f}° (frame {self.frame})"
        if self.kind is Limit.JOINT_LIMIT:
            what = f"joint {self.joint} leaves its range"
        elif self.kind is Limit.CONTACT:
            what = (f"{self.pair[0]} comes within {self.distance * 1e3:.1f} mm of {self.pair[1]}" if self.distance >= 0
                    else f"{self.pair[0]} enters {self.pair[1]} by {-self.distance * 1e3:.1f} mm")
        else:
            what = "the pose has no joint solution"
        arc = ("no feasible arc" if self.feasible is None else
               f"largest feasible arc {math.degrees(self.feasible[1] - self.feasible[0]):.1f}° "
               f"(φ = {math.degrees(self.feasible[0]):+.1f}° … {math.degrees(self.feasible[1]):+.1f}°)")
        return f"{what} {where}; {arc}"


@dataclass(frozen=True)
class ShortScan:
    """Short-scan check: ``arc`` against ``needed`` = π + ``fan`` (rad); ``complete`` when arc ≥ needed."""

    arc: float
    fan: float

    @property
    def needed(self) -> float:
        return math.pi + self.fan

    @property
    def complete(self) -> bool:
        return self.arc >= self.needed - 1e-12

    def __str__(self) -> str:
        a, f, n = (math.degrees(v) for v in (self.arc, self.fan, self.needed))
        verdict = ("a complete short scan" if self.complete else
                   f"NOT a complete short scan: {n - a:.1f}° missing (Parker weights cannot fill them)")
        return f"arc {a:.1f}° vs 180° + fan {f:.1f}° = {n:.1f}°: {verdict}"


@dataclass(frozen=True, eq=False)
class Sweep:
    """A planned sweep of n frames (arrays over frames first).

    ``q`` (n, nq) joints; ``angles`` φ (n,) rad; ``poses`` (n, 4, 4) source poses and ``P`` (n, 3, 4)
    projection matrices (table-frame m → px); ``target`` (3,) m; ``distance``: source-to-target (m);
    ``compensated``: frames keep the target on the axis; ``q_plain`` (n, nq) and ``drift`` (n,) m of the
    plain joint rotation; ``min_clearance``: certified swept lower bound (m) of every pair's distance over
    the whole arc (:meth:`carmkin.world.World.swept` on every frame pair), also for a failed sweep (below the
    margin, negative where a frame penetrates), NaN when a frame has no joints in range (the arc is then not
    a path of the machine); ``sampled_clearance``: smallest exact distance at the samples; samples made
    ``clearance_samples``;
    ``margin`` (m); ``frame_clearance`` (n,) smallest pair distance at each frame (m, NaN where not checked);
    ``limiting_joint`` with ``joint_extent`` (φ_min, φ_max) rad allowed by the joint ranges
    on this trajectory; ``short_scan`` (:class:`ShortScan`); ``failure`` (:class:`SweepFailure`, None on
    success); ``success``; ``approach`` (:class:`~carmkin.model.motion.Duration`): the synchronized move from
    ``q_start`` to the first frame (unknown, with the reason, without ``q_start`` or joint speeds; not
    checked for collision); ``timing`` (:class:`~carmkin.model.motion.FollowCheck`): whether the joints follow
    the arc at the asked acquisition time, the fastest they follow, and the sweep's duration with the run-up
    and stop (None when a frame has no joints in range); ``approach_motion``: with ``q_start`` and a sweep that
    fits, the certified motion from ``q_start`` to the first frame (a :class:`carmkin.motion.Trajectory`, keeping
    half the margin as :func:`carmkin.views.plan_view`'s moves do; the arc itself is certified frame pair by frame
    pair: the virtual trial run), or None.
    """

    system: object
    q: np.ndarray
    angles: np.ndarray
    poses: np.ndarray
    P: np.ndarray
    target: np.ndarray
    distance: float
    compensated: bool
    weights: np.ndarray
    q_plain: np.ndarray
    drift: np.ndarray
    min_clearance: float
    sampled_clearance: float
    clearance_samples: int
    margin: float
    limiting_joint: str | None
    joint_extent: tuple[float, float]
    short_scan: ShortScan
    frame_clearance: np.ndarray
    failure: SweepFailure | None = None
    obstacles: tuple = field(default=())
    approach: motion.Duration | None = None
    timing: motion.FollowCheck | None = None
    approach_motion: object = None

    @property
    def success(self) -> bool:
        return self.failure is None

    @property
    def n_views(self) -> int:
        return len(self.angles)

    @property
    def arc(self) -> float:
        return float(self.angles[-1] - self.angles[0])

    @property
    def detector_poses(self) -> np.ndarray:
        """Poses (n, 4, 4) of the ``detector`` frame (on the principal axis at the SDD)."""
        return self.poses @ self.system.detector_in_xray

    def configuration(self, angle) -> np.ndarray:
        """Joints (nq,) at φ = ``angle`` (rad) on the planned path (linear between frames)."""
        phi = real_scalar(angle, "angle", error=SweepError, low=float(self.angles[0]), high=float(self.angles[-1]),
                          unit="rad")
        return np.array([np.interp(phi, self.angles, self.q[:, j]) for j in range(self.q.shape[1])])

    def cut(self) -> "Sweep":
        """The sweep planned again over its largest feasible arc (itself when it succeeded): the same frames,
        started from the first feasible one (its φ restart at 0)."""
        if self.failure is None:
            return self
        if self.failure.feasible is None:
            raise SweepError(f"no feasible part of the arc to cut to: {self.failure}")
        lo, hi = self.failure.feasible
        keep = (self.angles >= lo - 1e-12) & (self.angles <= hi + 1e-12)
        return plan_sweep(self.system, self.target, arc_deg=math.degrees(hi - lo), n_views=int(keep.sum()),
                          patient=list(self.obstacles), q_start=self.q_plain[keep][0], joint=self._joint_spec(),
                          distance=self.distance, compensate=self.compensated, margin=self.margin)

    def _joint_spec(self) -> dict:
        return {n: float(w) for n, w in zip(self.system.joint_names, self.weights) if w != 0.0}

    def summary(self) -> str:
        """Lines for people (mm, degrees)."""
        lines = [f"sweep: {self.n_views} frames over {math.degrees(self.arc):.1f}° "
                 f"({'compensated' if self.compensated else 'plain'} trajectory), target at "
                 f"{self.distance * 1e3:.1f} mm from the source",
                 _clearance_line(self),
                 f"plain rotation drift: max {self.drift.max() * 1e3:.3f} mm, mean {self.drift.mean() * 1e3:.3f} mm",
                 f"joint ranges allow φ = {math.degrees(self.joint_extent[0]):+.1f}° … "
                 f"{math.degrees(self.joint_extent[1]):+.1f}° (limited by {self.limiting_joint})",
                 f"short scan: {self.short_scan}"]
        lines += _timing_lines(self)
        if not self.success:
            lines.append(f"NOT feasible: {self.failure}")
        elif self.timing is not None and self.timing.status is motion.Follow.TOO_FAST:
            lines.append(f"NOT feasible at a {self.timing.acquisition_time:g} s acquisition: {self.timing.joint} "
                         "cannot follow it (the arc itself is clear and in range)")
        else:
            lines.append("feasible")
        return "\n".join(lines)


def _timing_lines(sweep: Sweep) -> list[str]:
    """The approach and the sweep's timing for people (s)."""
    lines = [f"approach: {sweep.approach}"] if sweep.approach is not None else []
    timing = sweep.timing
    if timing is None:
        return lines + ["timing: none (a frame has no joints in range)"]
    lines.append(f"timing: {timing}")
    if timing.duration is not None:
        acquisition = timing.duration - timing.run_up - timing.run_out
        lines.append(f"sweep duration {timing.duration:.1f} s (run-up {timing.run_up:.1f} s, acquisition "
                     f"{acquisition:.1f} s, stop {timing.run_out:.1f} s)")
    return lines


def _clearance_line(sweep: Sweep) -> str:
    """The swept clearance for people: certified over the whole arc, or why there is none."""
    if math.isnan(sweep.min_clearance):
        return "swept clearance: none (a frame has no joints in range: the arc is not a path of the machine)"
    below = "" if sweep.min_clearance >= sweep.margin else " — BELOW the margin"
    return (f"swept clearance: {sweep.min_clearance * 1e3:.2f} mm certified over the whole arc{below} (margin "
            f"{sweep.margin * 1e3:.1f} mm; {sweep.clearance_samples} distance samples)")


def _patient(patient, system) -> tuple:
    """The patient's obstacles; a patient model must rest on the table top (``check_placement``)."""
    obstacles = as_obstacles(patient, SweepError)
    check_placement = getattr(patient, "check_placement", None)
    if callable(check_placement):
        check_placement(system)
    return obstacles


def _reference(system, w: np.ndarray, q_start, target, distance):
    """q_ref (nq,) putting the target on the axis with the orientation of the start (or centre) joints."""
    centred = q_start is None
    if centred:
        guess = np.clip(np.zeros(system.nq), system.lower, system.upper)
        moving = w != 0
        guess[moving] = 0.5 * (system.lower + system.upper)[moving]
    else:
        guess = real_array(q_start, "q_start", (system.nq,), error=SweepError, unit="m, rad")
    R = system.fk(guess)[None, :3, :3]
    q, reached = tr.solve_poses(system, tr.aligned_poses(R, target, distance), guess[None])
    if not reached[0]:
        raise SweepError(f"target {np.round(target * 1e3, 1).tolist()} mm cannot be put on the principal axis at "
                         f"{distance * 1e3:.1f} mm with the start orientation")
    return q[0], centred


def _excess(system, q: np.ndarray) -> np.ndarray:
    """Signed excess (n, nq) of joint values beyond their ranges (0 inside, tolerance included)."""
    return np.stack([r.excess(q[:, j]) for j, r in enumerate(system.joint_ranges)], axis=1)


def _joint_extent(system, q_ref, w, phi, target, distance, compensate) -> tuple[tuple[float, float], str | None]:
    """φ interval (rad) allowed by the joint ranges on this trajectory (the in-range run overlapping the planned
    arc most), and the joint that bounds it nearest to the planned ends (None when nothing is in range)."""
    moving = np.flatnonzero(w)
    lo_all = (np.where(w[moving] > 0, system.lower[moving], system.upper[moving]) - q_ref[moving]) / w[moving]
    hi_all = (np.where(w[moving] > 0, system.upper[moving], system.lower[moving]) - q_ref[moving]) / w[moving]
    lo, hi = float(lo_all.max()), float(hi_all.min())
    names = system.joint_names
    lo_joint, hi_joint = names[moving[int(lo_all.argmax())]], names[moving[int(hi_all.argmin())]]
    if not compensate or hi <= lo:
        return (lo, hi), (lo_joint if phi[0] - lo <= hi - phi[-1] else hi_joint)
    step = max(float(phi[1] - phi[0]), math.radians(0.25))
    grid = np.union1d(np.union1d(np.arange(lo, hi, step), [lo, hi]), phi[(phi >= lo) & (phi <= hi)])
    q, reached = tr.compensated(system, tr.plain(q_ref, w, grid), target, distance)
    good = ~np.any(_excess(system, np.where(np.isfinite(q), q, 0.0)) != 0, axis=1) & reached
    runs, start = [], None
    for k in range(len(grid)):
        if good[k] and start is None:
            start = k
        if start is not None and (not good[k] or k == len(grid) - 1):
            runs.append((start, k if good[k] else k - 1))
            start = None
    if not runs:
        return (math.nan, math.nan), _worst(system, q[int(np.argmin(np.abs(grid - phi.mean())))])
    overlap = [min(grid[b], phi[-1]) - max(grid[a], phi[0]) for a, b in runs]
    a, b = runs[int(np.argmax(overlap))]
    lo_joint = lo_joint if a == 0 else _worst(system, q[a - 1])
    hi_joint = hi_joint if b == len(grid) - 1 else _worst(system, q[b + 1])
    lo, hi = float(grid[a]), float(grid[b])
    return (lo, hi), (lo_joint if phi[0] - lo <= hi - phi[-1] else hi_joint)


def _worst(system, q: np.ndarray) -> str | None:
    ex = _excess(system, q[None])[0]
    if not np.all(np.isfinite(q)) or not np.any(ex):
        return None
    return system.joint_names[int(np.argmax(np.abs(ex)))]


def plan_sweep(system, target, arc_deg: float = 190.0, n_views: int = 100, patient=None, q_start=None, *,
               joint="orbital", distance: float | None = None, compensate: bool = True,
               margin: float = DEFAULT_MARGIN, tolerance: float = DEFAULT_TOLERANCE,
               acquisition_time_s: float | None = None) -> Sweep:
    """Plan a sweep of ``n_views`` frames over ``arc_deg`` degrees about ``joint`` around ``target``.

    ``target`` (3,) m in the table frame; ``patient``: the toolkit's patient model
    (:class:`carmkin.patient.ParametricPatient`, :class:`carmkin.patient.CTPatient`) or a list of
    :class:`carmkin.robot.collision.Obstacle` (e.g. a box patient) checked with the table and the floor; ``q_start`` (nq,): joints whose orientation
    starts the arc (default: the arc is centred on the rotating joints' mid-range, other revolute joints at 0
    where in range); ``joint``: a revolute joint name or a mapping of names to weights (combined motion);
    ``distance``: source-to-target distance (m, default the C-arm's source-to-orbital-axis L = l2 + a1, the
    isocentre distance); ``compensate``: frames keep the target on the principal axis at ``distance`` (the
    virtual isocentre; else the plain joint rotation is planned); ``margin`` (m) kept along the whole arc,
    certified by conservative advancement (``tolerance``: how far below the true minimum the reported
    swept clearance may be, m). An arc that does not fit is not an exception: ``success`` is False and
    ``failure`` names the joint limit, contact or unreachable pose, where, and the largest feasible arc.
    ``acquisition_time_s`` (s, > 0): the time the views are acquired over; ``timing`` then says whether the
    joints can follow it (speed and acceleration, :func:`carmkin.model.motion.follow`) and, if not, which
    joint and by how much — as data, not an exception (the sweep's clearance is unaffected).
    """
    require_system(system, SweepError)
    target = target_point(target, "target", error=SweepError)
    compensate = flag(compensate, "compensate", error=SweepError)
    arc = math.radians(real_scalar(arc_deg, "arc_deg", error=SweepError, low=1e-6, high=360.0, unit="deg"))
    if isinstance(n_views, bool) or not isinstance(n_views, (int, np.integer)) or not 2 <= n_views <= MAX_VIEWS:
        raise SweepError(f"n_views must be an integer in [2, {MAX_VIEWS}], got {n_views!r}")
    margin = real_scalar(margin, "margin", error=SweepError, low=0.0, high=1.0, unit="m")
    tolerance = real_scalar(tolerance, "tolerance", error=SweepError, low=1e-6, high=0.1, unit="m")
    if acquisition_time_s is not None:
        acquisition_time_s = motion.check_acquisition_time(acquisition_time_s, SweepError)
    distance = system.carm.source_to_orbital_axis if distance is None else real_scalar(
        distance, "distance", error=SweepError, low=1e-3, high=10.0, unit="m")
    obstacles = _patient(patient, system)
    w = tr.joint_weights(system, joint)
    q_ref, centred = _reference(system, w, q_start, target, distance)
    phi = tr.frame_angles(arc, int(n_views), centred)
    q_plain = tr.plain(q_ref, w, phi)
    T_plain = system.fk(q_plain, check_units=False)  # solver output
    drift = tr.drift(T_plain, target, distance)
    if compensate:
        q, reached = tr.compensated(system, q_plain, target, distance)
    else:
        q, reached = q_plain, np.ones(len(phi), dtype=bool)
    extent, limiting = _joint_extent(system, q_ref, w, phi, target, distance, compensate)
    fan = tr.fan_angle(system, tr.rotation_axis(system, q_ref, w))

    # frames: reachable and in range; segments: swept clearance
    ok = reached & np.all(np.isfinite(q), axis=1)
    excess = np.where(ok[:, None], _excess(system, np.where(ok[:, None], q, 0.0)), 0.0)
    ok &= ~np.any(excess != 0, axis=1)
    world = World(system, obstacles)
    first: SweepFailure | None = None
    frame_ok = ok.copy()
    seg_ok = np.zeros(max(len(phi) - 1, 0), dtype=bool)
    bound, sampled, samples = np.inf, np.inf, 0
    frame_clearance = np.full(len(phi), np.nan)
    for k in range(len(phi)):
        if not ok[k]:
            kind = Limit.UNREACHABLE if not reached[k] else Limit.JOINT_LIMIT
            first = first or SweepFailure(kind, float(phi[k]), k, None, joint=_worst(system, q[k]))
            continue
        if k and ok[k - 1]:  # the segment from the previous frame, certified over its whole length
            check = world.swept(q[k - 1], q[k], margin=margin, tolerance=tolerance, path_min=sampled)
            samples += check.samples
            sampled = min(sampled, check.sampled_min)
            bound = min(bound, check.min_distance)
            seg_ok[k - 1] = check.clear
            if check.contact_t is not None and first is None:
                angle = float(phi[k - 1] + check.contact_t * (phi[k] - phi[k - 1]))
                first = SweepFailure(Limit.CONTACT, angle, k - 1, None, pair=world.link_pairs()[check.contact_pair],
                                     distance=check.contact_distance)
        d = world.distances(q=q[k])
        frame_clearance[k] = float(d.min())
        samples += 1
        sampled = min(sampled, float(d.min()))
        bound = min(bound, float(d.min()))
        if d.min() < margin:
            frame_ok[k] = False
            i = int(np.argmin(d))
            first = first or SweepFailure(Limit.CONTACT, float(phi[k]), k, None, pair=world.link_pairs()[i],
                                          distance=float(d[i]))
    if first is not None:
        first = SweepFailure(first.kind, first.angle, first.frame, _largest_run(phi, frame_ok, seg_ok), first.joint,
                             first.pair, first.distance)
    poses = system.fk(np.where(np.isfinite(q), q, 0.0), check_units=False)
    from carmkin.imaging.projection import view_intrinsics

    K = view_intrinsics(system, np.where(np.isfinite(q), q, 0.0))  # H K per view for a calibrated system
    R_t = np.transpose(poses[:, :3, :3], (0, 2, 1))
    P = K @ np.concatenate((R_t, -R_t @ poses[:, :3, 3:4]), axis=2)
    # The swept minimum of the whole arc: defined only where every frame has joints in range (else NaN).
    bound = bound if np.all(ok) and np.isfinite(bound) else math.nan
    approach_motion = None
    if q_start is not None and first is None and system.motion is not None:
        approach_motion = _approach_motion(system, world, q_start, q[0], margin)
    return Sweep(system, q, phi, poses, P, target, float(distance), bool(compensate), w, q_plain, drift,
                 float(bound), float(sampled), samples, float(margin), limiting, extent,
                 ShortScan(arc, fan), frame_clearance, first, obstacles, *_timing(system, q, q_start, ok,
                                                                                  acquisition_time_s),
                 approach_motion)


def _approach_motion(system, world, q_start, q_first, margin: float):
    """The certified motion from ``q_start`` to the first frame keeping half the margin, or a failed trajectory
    saying why (a start closer than that to something, or none found in time)."""
    from carmkin.errors import MotionPlanError
    from carmkin.motion import MotionPlanner

    planner = MotionPlanner(system, margin=0.5 * margin, world=world)
    try:
        return planner.plan(np.asarray(q_start, float), q_first)
    except MotionPlanError as exc:
        return planner.failed(q_start, str(exc))


#: Why a sweep has no approach time.
NO_START = "no q_start: the sweep has no approach move"
NO_FIRST_FRAME = "the first frame has no joints in range"


def _timing(system, q: np.ndarray, q_start, ok: np.ndarray, acquisition_time_s):
    """``(approach, timing)`` of a sweep (see :class:`Sweep`)."""
    if q_start is None or not ok[0]:
        approach = motion.unknown(reason=NO_START if q_start is None else NO_FIRST_FRAME)
    else:
        approach = motion.system_move(system, np.asarray(q_start, float), q[0])
    if not np.all(ok):
        return approach, None
    return approach, motion.follow(system.motion, q, acquisition_time_s, system.prismatic)


def _largest_run(phi, frame_ok, seg_ok) -> tuple[float, float] | None:
    """(φ_first, φ_last) of the longest run of feasible frames joined by feasible segments."""
    best, start, out = -1.0, None, None
    for k in range(len(phi)):
        if not frame_ok[k]:
            start = None
            continue
        if start is None or not seg_ok[k - 1]:
            start = k
        if phi[k] - phi[start] > best:
            best, out = phi[k] - phi[start], (float(phi[start]), float(phi[k]))
    return out
