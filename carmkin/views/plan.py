"""Plan one view: joints, clearance, the moves from where the C-arm is, and the nearest view when it fails.

:func:`plan_view` runs the search of :mod:`carmkin.views.search` on one cell (so it answers exactly as
:func:`~carmkin.views.reach_map` does for that cell), then

* with ``q_current``: the joint-by-joint moves to the plan in the manual order of
  :data:`carmkin.world.DEFAULT_ORDER`, each swept for collision by the world's certified conservative
  advancement (:meth:`carmkin.world.World.moves`, as repositioning does);
* when the view is unreachable: the **nearest reachable view** (smallest angle between beam axes, same
  target; for a view with a fixed roll, first the same beam with any roll), searched in bands of :data:`NEAREST_BAND` of angle; each band holds rings of directions
  about the axis and the integer-degree (primary, secondary) grid directions of the patient in that band,
  so the answer is never farther than the nearest reachable cell of an integer-degree map.

A reachable plan reports its ``duration`` (:class:`carmkin.model.motion.Duration`): with ``q_current``, the
time of its joint-by-joint moves at the system's joint speeds (one joint after another, each from rest to
rest: the order the moves are certified in; the whole sequence to ``plan.q``, also when a move is blocked; the synchronized time, every joint at once, is
``carmkin.model.motion.move_duration(system.motion, q_current, plan.q)``); unknown, with the reason, without
``q_current`` or without joint speeds.

Lengths in m, angles in rad (the reason texts speak mm and degrees).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import PatientModelError, ViewError
from carmkin.model import motion
from carmkin.validation import real_array, real_scalar
from carmkin.world import DEFAULT_MARGIN, DEFAULT_PATH_CLEARANCE, Move, Obstacle, World  # noqa: F401 (Move: views.Move)
from carmkin.world.obstacles import as_obstacles

from . import mount, refine, search
from .view import View, _patient_frame

#: Clearance (m) kept along the swept moves (below the margin, so the goal's neighbourhood is reachable).
PATH_CLEARANCE = DEFAULT_PATH_CLEARANCE
#: Why a plan without ``q_current`` has no duration.
NO_MOVE = "no q_current: the plan has no move to time"
#: A patient may rest on the table top but not sink into it by more than this (m).
PATIENT_TABLE_TOLERANCE = 0.001
#: Angular band (rad) of the nearest-view search, and its last angle.
NEAREST_BAND = math.radians(2.0)
NEAREST_LIMIT = math.radians(180.0)
#: Ring directions of the nearest-view search: azimuth spacing (deg) and exact checks per direction (the grid
#: directions get the full search of a map cell, so the answer is never behind an integer-degree map).
RING_SPACING_DEG = 2.0
RING_CHECKS = 8


@dataclass(frozen=True)
class ViewPlan:
    """A planned view. ``success``; ``q`` (nq,) (NaN when unreachable); ``clearance`` exact (m) to patient,
    table and floor; ``distance`` source–target (m); ``reason`` and ``binding`` (a joint group or
    ``"contact"``) when unreachable; ``moves`` from ``q_current``; ``nearest``: the plan of the nearest
    reachable view (unreachable views only) and ``angle`` (rad) between the beams; ``solver``: ``"closed
    form"`` or ``"qp"`` (a motorized table's joints freed, :mod:`carmkin.views.refine`). Reachable plans also
    carry ``x_axis`` (3,) the roll chosen (the source frame's x axis, table frame), ``clearance_to`` the exact
    clearance (m) to each of ``"patient"`` (every obstacle), ``"table"`` and ``"floor"``, and ``validity``
    the :class:`~carmkin.robot.validity.ValidityReport` at the margin, and ``duration`` (:class:`Duration
    <carmkin.model.motion.Duration>`): the time of the moves from ``q_current`` (see the module docstring);
    ``motion``: with ``q_current``, the certified multi-joint motion to the plan (a
    :class:`carmkin.motion.Trajectory`: the straight line when it is clear, else planned with OMPL; ``success``
    False with the reason when none was found in time), or None. ``q_contact``: a view unreachable by contact
    (``binding`` ``"contact"``) carries the configuration, joints in range, whose contact its ``reason`` names
    (what a picture of the failure draws); None otherwise."""

    view: View
    success: bool
    q: np.ndarray
    clearance: float
    distance: float
    reason: str | None
    binding: str
    moves: tuple = ()
    nearest: "ViewPlan | None" = None
    angle: float = 0.0
    solver: str = "closed form"
    x_axis: np.ndarray | None = None
    clearance_to: dict | None = None
    validity: object = None
    duration: motion.Duration | None = None
    motion: object = None
    q_contact: np.ndarray | None = None


def patient_obstacles(patient) -> tuple:
    """``patient`` as obstacles: None, a list of :class:`Obstacle`, or a model with ``obstacles()``."""
    return as_obstacles(patient, PatientModelError)


def _key(system, obstacles):
    return system, tuple((o.name, o.shape, o.size, o.pose.tobytes()) for o in obstacles)


@functools.lru_cache(maxsize=8)
def _world_cached(key):
    system, described = key
    obstacles = [Obstacle(n, s, z, np.frombuffer(p).reshape(4, 4)) for n, s, z, p in described]
    world = World(system, obstacles)
    _check_resting(world, obstacles)
    return world


@functools.lru_cache(maxsize=8)
def _model_key(system, patient):
    return _key(system, patient_obstacles(patient))


def world_for(system, patient):
    """The collision world of ``system`` with ``patient`` (cached per system and obstacle list; a frozen
    dataclass patient model's obstacles are built once per model)."""
    import dataclasses

    from carmkin.robot.validity import require_system

    require_system(system, ViewError)
    check_placement = getattr(patient, "check_placement", None)
    if callable(check_placement):  # a patient model rests on the table top
        check_placement(system)
    if dataclasses.is_dataclass(patient) and patient.__dataclass_params__.frozen:
        try:
            return _world_cached(_model_key(system, patient))
        except TypeError:  # unhashable fields (arrays): build its obstacles
            pass
    return _world_cached(_key(system, patient_obstacles(patient)))


def _check_resting(world, obstacles) -> None:
    import coal

    objects = world.geometry_model.geometryObjects
    table = [o for o in objects if o.name.startswith("table_")]
    for obstacle in obstacles:
        geometry, pose = obstacle.geometry(), coal.Transform3s(obstacle.pose[:3, :3], obstacle.pose[:3, 3])
        for t in table:
            request, result = coal.DistanceRequest(), coal.DistanceResult()
            request.enable_signed_distance = True
            tf = coal.Transform3s(t.placement.rotation, t.placement.translation)
            d = coal.distance(geometry, pose, t.geometry, tf, request, result)
            if d < -PATIENT_TABLE_TOLERANCE:
                raise PatientModelError(f"patient part {obstacle.name!r} sinks {-d * 1e3:.1f} mm into the table top "
                                        f"(at most {PATIENT_TABLE_TOLERANCE * 1e3:.0f} mm): place it on the table")


def reference(system, q_current) -> np.ndarray:
    """The search's reference configuration: ``q_current`` or the middle of the ranges."""
    if q_current is None:
        return 0.5 * (system.lower + system.upper)
    from carmkin.errors import InvalidConfigurationError
    from carmkin.validation import JOINT_VALUE_LIMIT

    q = real_array(q_current, "q_current", (system.nq,), error=InvalidConfigurationError, limit=JOINT_VALUE_LIMIT,
                   unit="m, rad")
    # The machine cannot be outside its ranges, and the joints a search holds (a motorized table's) would carry
    # the excess into the plan: refuse, naming the joint and the amount (a value on a limit is in range).
    for r, v, prismatic in zip(system.joint_ranges, q.tolist(), system.prismatic):
        if not r.contains(v):
            scale, unit = (1e3, "mm") if prismatic else (math.degrees(1.0), "°")
            raise InvalidConfigurationError(
                f"q_current: {r.name} = {v * scale:.6g} {unit} is outside its range [{r.lower * scale:.6g}, "
                f"{r.upper * scale:.6g}] {unit} by {r.excess(v) * scale:+.3g} {unit}")
    return q


def _table_samples(system, value) -> list | None:
    """``value`` as held configurations: None, or (k, nq) finite and within the joint ranges (m, rad)."""
    if value is None:
        return None
    from carmkin.validation import JOINT_VALUE_LIMIT

    samples = real_array(value, "table_samples", (None, system.nq), error=ViewError, limit=JOINT_VALUE_LIMIT,
                         unit="m, rad")
    if not len(samples):
        raise ViewError(f"table_samples must hold at least one configuration ({system.nq},), got none")
    for k, r in enumerate(system.joint_ranges):
        outside = [float(v) for v in samples[:, k] if not r.contains(v)]
        if outside:
            raise ViewError(f"table_samples: {r.name} = {outside[0]:g} is outside its range [{r.lower:g}, {r.upper:g}] "
                            "(m or rad)")
    return list(samples)


def distance_range(system, view: View) -> np.ndarray:
    """(1, 2) source–target distances (m): the view's, or the target anywhere between source and detector."""
    if view.distance is not None:
        return np.array([[view.distance, view.distance]])
    return np.array([[0.0, system.carm.source_to_detector]])


def _resolve(view, patient) -> View:
    if isinstance(view, View):
        return view
    if isinstance(view, str):
        from .standard import standard_view

        return standard_view(view, position=patient if patient is not None and hasattr(patient, "pose") else "HFS")
    raise ViewError(f"view must be a carmkin.views.View or a standard view name, got {type(view).__name__}")


def plan_view(system, view, patient=None, q_current=None, *, margin: float = DEFAULT_MARGIN,
              nearest: bool = True, table_samples=None, qp: bool = True, motion_plan: bool = True) -> ViewPlan:
    """Plan ``view`` (a :class:`View`, or a standard view's name: its target is then the table origin) on
    any ``system``: free roll and distance used for clearance (≥ ``margin``, m), then least motion from
    ``q_current`` (nq,) (default mid-range). ``patient``: a patient model or a list of
    :class:`~carmkin.robot.collision.Obstacle`. ``table_samples``: held configurations (k, nq) whose table
    joints a motorized table may take (default: those of the reference). A robot that holds the C (mount
    joints) is freed by its closed form (:mod:`carmkin.views.mount`), the answer nearest ``q_current`` among
    its sampled rolls, distances and orbital values. ``qp``: when the closed form leaves the view unreachable on
    a motorized table or a robot, try again with every joint free (:mod:`carmkin.views.refine`;
    :func:`reach_map` holds a table's joints, and frees a robot's by its closed form only). ``motion_plan``: with
    ``q_current``, also plan the certified motion to the view (:func:`carmkin.motion.plan_motion`, keeping
    :data:`PATH_CLEARANCE`); False when ``q_current`` is only the reference of least motion."""
    view = _resolve(view, patient)
    margin = real_scalar(margin, "margin", error=ViewError, low=0.0, high=1.0, unit="m")
    world = world_for(system, patient)
    q_ref = reference(system, q_current)
    ctx = search.make_context(system, world, margin, q_ref, _table_samples(system, table_samples))
    plan = _plan_cells(ctx, [view])[0]
    if not plan.success and qp and view.x_axis is None and refine.frees_joints(system):
        found = refine.refine(ctx, np.array(view.target), view.axis, distance_range(system, view)[0])
        if found is not None:
            q, clearance, distance = found
            plan = _replace(plan, success=True, q=q, clearance=clearance, distance=distance, reason=None, binding="",
                            solver="qp", q_contact=None)
    if plan.success:
        plan = _with_report(plan, system, world, margin)
    if plan.success and q_current is not None:
        plan = _with_moves(plan, system, world, q_ref)
        if motion_plan and system.motion is not None:
            plan = _with_motion(plan, system, world, q_ref)
    if plan.success:
        plan = _replace(plan, duration=motion.unknown(motion.Timing.JOINT_BY_JOINT, NO_MOVE) if q_current is None
                        else motion.system_move(system, q_ref, plan.q, motion.Timing.JOINT_BY_JOINT))
    if not plan.success and nearest:
        plan = _with_nearest(plan, ctx, view, patient)
    return plan


def _plan_cells(ctx, views) -> list[ViewPlan]:
    targets = np.array([v.target for v in views])
    directions = np.array([v.direction for v in views])
    ranges = np.vstack([distance_range(ctx.system, v) for v in views])
    x_axes = np.array([v.x_axis if v.x_axis is not None else (np.nan,) * 3 for v in views], dtype=float)
    out = _solve_cells(ctx, targets, directions, ranges, x_axes)
    return [ViewPlan(v, bool(out.reachable[i]), out.q[i], float(out.clearance[i]), float(out.distance[i]),
                     out.reason[i], str(out.binding[i]),
                     q_contact=out.contact_q[i].copy() if str(out.binding[i]) == "contact"
                     and np.isfinite(out.contact_q[i]).all() else None) for i, v in enumerate(views)]


def _solve_cells(ctx, targets, directions, ranges, x_axes):
    out = search.solve_cells(ctx, targets, directions, ranges, x_axes)
    if ctx.system.mount.joints:  # the search holds a robot's joints: its closed form frees them
        out = mount.with_mount(ctx, out, targets, directions, ranges, x_axes)
    return out


def _reached_directions(ctx, view: View, directions) -> list[ViewPlan]:
    """The plans of the beams ``directions`` (N, 3, unit) through ``view``'s target at its distance (free roll)
    that the search reaches; a :class:`View` is built only for those (issue 41: building and checking one per
    direction was half the 27 s of CPU a view unreachable everywhere took)."""
    n = len(directions)
    out = _solve_cells(ctx, np.tile(view.target, (n, 1)), directions, np.tile(distance_range(ctx.system, view), (n, 1)),
                       np.full((n, 3), np.nan))
    name = f"nearest to {view.name}".strip()
    return [ViewPlan(View(view.target, tuple(directions[i]), view.distance, name), True, out.q[i],
                     float(out.clearance[i]), float(out.distance[i]), out.reason[i], str(out.binding[i]))
            for i in np.nonzero(out.reachable)[0]]


def _with_report(plan: ViewPlan, system, world, margin: float) -> ViewPlan:
    """The roll chosen, the exact clearance to patient, table and floor, and the validity report at the margin."""
    from carmkin.robot import validity

    clearance_to = world.grouped(plan.q)
    report = validity.check(system, plan.q, margin=margin, world=world)
    return _replace(plan, x_axis=system.fk(plan.q)[:3, 0], clearance_to=clearance_to, validity=report)


def _with_moves(plan: ViewPlan, system, world, q_from) -> ViewPlan:
    """The joint-by-joint moves from ``q_from`` to the plan (:meth:`carmkin.world.World.moves`)."""
    return _replace(plan, moves=world.moves(q_from, plan.q, clearance=PATH_CLEARANCE))


def _with_motion(plan: ViewPlan, system, world, q_from) -> ViewPlan:
    """The certified motion from ``q_from`` to the plan, keeping :data:`PATH_CLEARANCE` (as the moves do): a
    start closer than that to something has none (its reason says so)."""
    from carmkin.errors import MotionPlanError
    from carmkin.motion import MotionPlanner

    planner = MotionPlanner(system, margin=PATH_CLEARANCE, world=world)
    try:
        return _replace(plan, motion=planner.plan(q_from, plan.q))
    except MotionPlanError as exc:
        return _replace(plan, motion=planner.failed(q_from, str(exc)))


def _replace(plan, **changes):
    import dataclasses

    return dataclasses.replace(plan, **changes)


def _band_directions(view: View, lo: float, hi: float, frame) -> tuple[np.ndarray, np.ndarray]:
    """``(rings, grid)``: directions at angles [lo, hi) from the view's axis — rings every 1° of angle with
    azimuths ≤ :data:`RING_SPACING_DEG` apart, and the integer-degree grid of XA angles in the patient ``frame``."""
    z = view.axis
    e1 = np.cross(z, np.eye(3)[int(np.argmin(np.abs(z)))])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(z, e1)
    rings = [np.zeros((0, 3))]
    for a in np.arange(max(lo, math.radians(1.0)), hi, math.radians(1.0)):
        n = max(8, int(math.ceil(360 * math.sin(a) / RING_SPACING_DEG)))
        phi = np.linspace(0, 2 * math.pi, n, endpoint=False)[:, None]
        rings.append(math.cos(a) * z + math.sin(a) * (np.cos(phi) * e1 + np.sin(phi) * e2))
    grid = _grid_directions(frame.tobytes())
    angle = np.arccos(np.clip(grid @ z, -1, 1))
    return np.vstack(rings), grid[(angle >= lo) & (angle < hi)]


@functools.lru_cache(maxsize=4)
def _grid_directions(frame_bytes) -> np.ndarray:
    R = np.frombuffer(frame_bytes).reshape(4, 4)[:3, :3]
    p, s = np.meshgrid(np.radians(np.arange(-180, 180)), np.radians(np.arange(-90, 91)), indexing="ij")
    return beam_directions(R, p.ravel(), s.ravel())


def beam_directions(R_patient, primary, secondary) -> np.ndarray:
    """Beam directions (N, 3, table frame) of XA angles (rad, arrays (N,)) for a patient whose LPS axes are
    the columns of ``R_patient``: minus the positioner's Yp (:mod:`carmkin.interop.dicom`), i.e.
    ``(sin p cos s, −cos p cos s, sin s)`` in LPS."""
    d = np.column_stack((np.sin(primary) * np.cos(secondary), -np.cos(primary) * np.cos(secondary), np.sin(secondary)))
    return d @ np.asarray(R_patient).T


def _with_nearest(plan: ViewPlan, ctx, view: View, patient) -> ViewPlan:
    import dataclasses

    if view.x_axis is not None:  # the same beam with any roll first
        free = _plan_cells(ctx, [dataclasses.replace(view, x_axis=None, name=f"{view.name} (any roll)".strip())])[0]
        if free.success:
            return _replace(plan, nearest=free, angle=0.0)
    frame = _patient_frame(patient if patient is not None and hasattr(patient, "pose") else "HFS")
    quick = dataclasses.replace(ctx, max_checks=RING_CHECKS)
    lo = 0.0
    while lo < NEAREST_LIMIT:
        hi = lo + NEAREST_BAND
        rings, grid = _band_directions(view, lo, hi, frame)
        plans = []
        for directions, context in ((grid, ctx), (rings, quick)):
            if len(directions):
                plans += [p for p in _reached_directions(context, view, directions) if p.success]
        if plans:
            best = min(plans, key=lambda p: (round(view.angle_to(p.view), 12), -p.clearance))
            return _replace(plan, nearest=best, angle=view.angle_to(best.view))
        lo = hi
    return plan
