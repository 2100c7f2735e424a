"""Plan two views at once: the frontal plane's view and the lateral plane's, the planes clear of each other.

:func:`plan_biplane` runs the one view search (:func:`carmkin.views.plan_view`) once per plane, in two
passes: the first plane is planned against the patient; the second against the patient **and the first
plane's links at their planned configuration** (each geometry an obstacle fixed in the table frame), with
the table held where the first plane put it (the table is one: its translation range pinned to that value,
a motorized table's joints held at it, no joint of the table freed). The pair is then checked exactly
(:class:`carmkin.biplane.world.BiplaneWorld`: every link of one plane against every link of the other,
each plane against table, floor and patient). The frontal plane goes first; if that fails, the lateral.
A plan that keeps ``margin`` everywhere is returned; otherwise the typed reason (:class:`Failure`).

The lateral view is given, or the frontal one turned by an angle (:func:`lateral_view`). Lengths in m,
angles in rad (the reason texts speak mm and degrees).
"""

from __future__ import annotations

import dataclasses
import enum
import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import BiplaneError, CarmkinError, ViewError
from carmkin.model.biplane import Biplane
from carmkin.model.params import JointRange
from carmkin.validation import real_scalar
from carmkin.views import View, plan_view
from carmkin.views.plan import DEFAULT_MARGIN, ViewPlan, patient_obstacles
from carmkin.views.standard import standard_view
from carmkin.views.view import _patient_frame
from carmkin.world import Obstacle
from carmkin.world.between import BODY_LINKS

from .world import BiplaneWorld

#: Links of the first plane that become obstacles of the second plane's search: its moving parts (its base,
#: the cart or stand, sits beside the table by construction; the exact check of the pair covers it).
OBSTACLE_LINKS = tuple(link for link in BODY_LINKS if link != "carm_cart")


class Failure(enum.Enum):
    """Why a biplane plan failed."""

    FRONTAL_UNREACHABLE = "the frontal view is unreachable"
    LATERAL_UNREACHABLE = "the lateral view is unreachable"
    PLANES_COLLIDE = "the planes cannot take both views clear of each other"


@dataclass(frozen=True)
class BiplanePlan:
    """Two planned views. ``success``; ``q`` the biplane configuration (nq,) (NaN when it failed);
    ``frontal`` and ``lateral`` each plane's :class:`~carmkin.views.ViewPlan` (``lateral`` ``None`` when the
    frontal view was unreachable); ``clearance`` the exact clearance (m) between the planes (NaN unless both
    views were planned) and ``pair`` its nearest (frontal, lateral) geometries; ``angle`` (rad) between the two
    planned beams; ``failure`` and ``reason`` when it failed; ``order`` the plane planned first; ``motion``: with
    ``q_current``, both planes moved together to ``q`` (a :class:`carmkin.motion.Trajectory`, the planes certified
    clear of each other and of table, floor and patient along it), or None."""

    success: bool
    q: np.ndarray
    frontal: ViewPlan
    lateral: ViewPlan | None
    clearance: float
    pair: tuple | None
    angle: float
    failure: Failure | None = None
    reason: str | None = None
    order: str = "frontal"
    motion: object = None


def lateral_view(frontal: View, angle_deg: float = 90.0, position="HFS", name: str = "") -> View:
    """The frontal view's beam turned by ``angle_deg`` about the patient's long axis (its superior axis S of
    ``position``, a Patient Position code, LPS pose or patient model) projected across the beam, through the
    same target: the two beams are exactly ``angle_deg`` apart, and +90° from AP is the lateral view with the
    detector at the patient's left (XA primary +90°)."""
    if not isinstance(frontal, View):
        raise ViewError(f"frontal must be a carmkin.views.View, got {type(frontal).__name__}")
    angle = math.radians(real_scalar(angle_deg, "angle_deg", error=ViewError, low=-180.0, high=180.0, unit="deg"))
    d = frontal.axis
    superior = _patient_frame(position)[:3, 2]
    axis = superior - (superior @ d) * d
    if np.linalg.norm(axis) < 1e-6:
        raise ViewError(f"the frontal view {frontal.name or np.round(d, 3).tolist()} runs along the patient's long "
                        "axis: turning it about that axis is undefined; give the lateral view itself")
    axis /= np.linalg.norm(axis)
    turned = math.cos(angle) * d + math.sin(angle) * np.cross(axis, d)  # Rodrigues' formula, axis ⟂ d
    return View(frontal.target, tuple(turned), None, name or f"{frontal.name or 'frontal'} + {math.degrees(angle):g}°")


def _resolve(view, patient, what: str) -> View:
    if isinstance(view, View):
        return view
    if isinstance(view, str):
        return standard_view(view, position=patient if patient is not None and hasattr(patient, "pose") else "HFS")
    raise ViewError(f"{what} must be a carmkin.views.View or a standard view name, got {type(view).__name__}")


def _pinned(system, d0: float):
    """``system`` with its table translation range pinned to ``d0`` (m): the other plane has put the table there."""
    table = dataclasses.replace(system.table, translation=JointRange(d0, d0, system.table.translation.name))
    return system.replace(table=table)


def _links_as_obstacles(world, q, prefix: str) -> list:
    """The :data:`OBSTACLE_LINKS` geometries of ``world``'s system at ``q`` as obstacles in the table frame."""
    import pinocchio as pin

    from carmkin.world import link_of

    data = world.model.createData()
    geometry_data = pin.GeometryData(world.geometry_model)
    pin.forwardKinematics(world.model, data, np.asarray(q, dtype=float))
    pin.updateGeometryPlacements(world.model, data, world.geometry_model, geometry_data)
    out = []
    for k, g in enumerate(world.geometry_model.geometryObjects):
        if link_of(g.name) in OBSTACLE_LINKS:
            out.append(Obstacle.box(f"{prefix}.{g.name}", 2.0 * np.asarray(g.geometry.halfSide),
                                    geometry_data.oMg[k].translation, geometry_data.oMg[k].rotation))
    return out


def _plan_pair(biplane, world, views, q_ref, patient, margin, first: str):
    """Plan plane ``first`` then the other against it; ``(plans by plane, failure, reason)``."""
    systems = {"frontal": biplane.frontal, "lateral": biplane.lateral}
    second = "lateral" if first == "frontal" else "frontal"
    refs = dict(zip(("frontal", "lateral"), biplane.planes_q(q_ref)))
    plans = {first: plan_view(systems[first], views[first], patient, refs[first], margin=margin, nearest=False,
                              motion_plan=False)}
    if not plans[first].success:
        return plans, Failure[f"{first.upper()}_UNREACHABLE"], plans[first].reason
    k = biplane.table_nq
    q_first = plans[first].q
    obstacles = list(patient_obstacles(patient)) + _links_as_obstacles(getattr(world, first), q_first, first)
    q_second = refs[second].copy()
    q_second[:k] = q_first[:k]
    pinned = _pinned(systems[second], float(q_first[0]))
    plan = plan_view(pinned, views[second], obstacles, q_second, margin=margin, nearest=False, qp=False,
                     motion_plan=False)
    plans[second] = plan
    if not plan.success:
        reason = (f"with the table where the {first} view puts it ({biplane.joint_names[0]} = "
                  f"{q_first[0] * 1e3:.1f} mm) and clear of the {first} plane: {plan.reason}")
        return plans, Failure[f"{second.upper()}_UNREACHABLE"], reason
    return plans, None, None


def _motion(biplane: Biplane, patient, q_from, q_to):
    """Both planes moved together from ``q_from`` to ``q_to`` keeping the moves' path clearance (as
    :func:`carmkin.views.plan_view` does), or a failed trajectory saying why."""
    from carmkin.errors import MotionPlanError
    from carmkin.motion import MotionPlanner
    from carmkin.views.plan import PATH_CLEARANCE

    planner = MotionPlanner(biplane, patient, PATH_CLEARANCE)
    try:
        return planner.plan(q_from, q_to)
    except MotionPlanError as exc:
        return planner.failed(q_from, str(exc))


def plan_biplane(biplane: Biplane, frontal_view, lateral=90.0, patient=None, q_current=None, *,
                 margin: float = DEFAULT_MARGIN) -> BiplanePlan:
    """Plan ``frontal_view`` on the frontal plane and ``lateral`` on the lateral plane at once.

    ``frontal_view``: a :class:`~carmkin.views.View` or a standard view's name (through the table origin);
    ``lateral``: a View, a standard view's name, or the angle (deg) between the beams (:func:`lateral_view`,
    about the patient's long axis; default 90°). ``patient``: a patient model or a list of obstacles (its
    position, if it has one, orients the standard views and the turn). ``q_current``: the biplane
    configuration (nq,) the least motion is counted from (default ``biplane.rest``), and with it both planes'
    certified motion there (``BiplanePlan.motion``). Every pair — plane to
    plane, each plane to table, floor and patient — keeps ``margin`` (m).

    Returns a :class:`BiplanePlan`; it never raises for an unreachable pair (``failure`` says why)."""
    if not isinstance(biplane, Biplane):
        raise BiplaneError(f"biplane must be a carmkin.model.biplane.Biplane (carmkin.biplane.load_biplane(...)), "
                           f"got {type(biplane).__name__}")
    margin = real_scalar(margin, "margin", error=ViewError, low=0.0, high=1.0, unit="m")
    frontal = _resolve(frontal_view, patient, "frontal_view")
    position = patient if patient is not None and hasattr(patient, "pose") else "HFS"
    if isinstance(lateral, (View, str)):
        lateral = _resolve(lateral, patient, "lateral")
    elif isinstance(lateral, (int, float, np.floating, np.integer)) and not isinstance(lateral, bool):
        lateral = lateral_view(frontal, lateral, position)
    else:
        raise ViewError(f"lateral must be a View, a standard view name or an angle in degrees, got {lateral!r:.60}")
    q_ref = np.array(biplane.rest) if q_current is None else biplane.check(q_current, "q_current")
    world = BiplaneWorld(biplane, patient)
    views = {"frontal": frontal, "lateral": lateral}
    failures = []
    for first in ("frontal", "lateral"):
        try:
            plans, failure, reason = _plan_pair(biplane, world, views, q_ref, patient, margin, first)
        except CarmkinError as exc:  # a plane's links as obstacles refused (e.g. one sunk into the table)
            plans, failure, reason = {}, Failure.PLANES_COLLIDE, str(exc)
        if failure is None:
            q = biplane.join(plans["frontal"].q, plans["lateral"].q)
            check = world.clearance(q)
            if check.minimum >= margin:
                return BiplanePlan(True, q, plans["frontal"], plans["lateral"], check.planes, check.pair,
                                   plans["frontal"].view.angle_to(plans["lateral"].view), order=first,
                                   motion=None if q_current is None else _motion(biplane, patient, q_ref, q))
            failure, reason = Failure.PLANES_COLLIDE, (
                f"{check.pair[0]} (frontal) and {check.pair[1]} (lateral) {check.planes * 1e3:.1f} mm apart, "
                f"below the margin of {margin * 1e3:.0f} mm")
        failures.append((plans, failure, reason))
        if failure is Failure[f"{first.upper()}_UNREACHABLE"]:  # the plane planned first fails alone: the reason
            break
    plans, failure, reason = failures[-1] if failures[-1][1].name.startswith(first.upper()) else failures[0]
    frontal_plan = plans.get("frontal") or plan_view(biplane.frontal, frontal, patient, biplane.planes_q(q_ref)[0],
                                                     margin=margin, nearest=False, motion_plan=False)
    return BiplanePlan(False, np.full(biplane.nq, np.nan), frontal_plan, plans.get("lateral"), math.nan, None,
                       math.nan, failure, f"{failure.value}: {reason}")
