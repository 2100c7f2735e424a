"""Foreshortening-free views of a segment (a vessel, a screw): the best reachable beam perpendicular to it.

A segment a–b is seen at its full length by every beam perpendicular to it: a one-parameter family of
directions (:meth:`View.perpendicular_to`). :func:`plan_perpendicular` searches the whole family at once,
as a map does its cells (:func:`carmkin.views.search.solve_cells`), and plans the reachable member with the
most clearance — or, with ``prefer``, the one nearest a preferred beam direction. When the closed form reaches
no member, the QP tries :data:`QP_TRIES` members spread over the family (as :func:`plan_view` falls back to
it). Lengths in m, angles in rad.
"""

from __future__ import annotations

import numpy as np

from carmkin.errors import ViewError
from carmkin.validation import integer, real_scalar

from . import search
from .plan import DEFAULT_MARGIN, ViewPlan, _table_samples, distance_range, plan_view, reference, world_for
from .view import View, _unit

#: Directions of the family searched by default (1° apart).
FAMILY_SIZE = 360
#: Members of the family the QP tries, evenly spread, when the closed-form search reaches none (a system whose
#: closed form lacks a joint the QP moves: angio-lateral's locked wigwag leaves a vertical offset to the
#: table's height, which only the QP moves). Bounded: a family unreachable everywhere costs this many QPs.
QP_TRIES = 12


def plan_perpendicular(system, a, b, patient=None, q_current=None, *, prefer=None, count: int = FAMILY_SIZE,
                       margin: float = DEFAULT_MARGIN, table_samples=None) -> ViewPlan:
    """The plan of the view through the segment's midpoint, perpendicular to a–b (m, table frame), that is
    reachable and clear with the most clearance; with ``prefer`` (a beam direction (3,) or a :class:`View`),
    the reachable one whose beam is nearest it. ``count`` directions over the full turn. When no member is
    reachable, an unreachable plan of the member nearest ``prefer`` (or the first) says so."""
    count = integer(count, "count", low=3, high=36000, error=ViewError)
    margin = real_scalar(margin, "margin", error=ViewError, low=0.0, high=1.0, unit="m")
    family = View.perpendicular_to(a, b, count)
    preferred = None
    if prefer is not None:
        preferred = prefer.axis if isinstance(prefer, View) else _unit(prefer, "prefer")
    world = world_for(system, patient)
    ctx = search.make_context(system, world, margin, reference(system, q_current), _table_samples(system, table_samples))
    targets = np.array([v.target for v in family])
    directions = np.array([v.direction for v in family])
    ranges = np.vstack([distance_range(system, v) for v in family])
    out = search.solve_cells(ctx, targets, directions, ranges)
    if system.mount.joints:  # the search holds a mount's joints (a robot's): freed as reach_map frees them
        from .maps import _workers, free_mount

        out = free_mount(ctx, targets, directions, ranges, out, _workers(None))
    if preferred is not None:
        order = np.argsort(-(directions @ preferred), kind="stable")  # nearest the preferred beam first
    else:
        order = np.argsort(-np.where(out.reachable, out.clearance, -np.inf), kind="stable")
    reachable = order[out.reachable[order]]
    chosen = family[int(reachable[0] if len(reachable) else order[0])]
    plan = plan_view(system, chosen, patient, q_current, margin=margin, nearest=False, table_samples=table_samples,
                     qp=bool(system.mount.joints), motion_plan=False)
    if not len(reachable) and not system.mount.joints:
        plan = _qp_member(system, family, patient, q_current, margin, table_samples, preferred, directions) or plan
    if not plan.success:
        from dataclasses import replace

        plan = replace(plan, reason=f"no view perpendicular to the segment is reachable ({count} directions "
                                    f"searched, {min(QP_TRIES, count)} by the QP); this one: {plan.reason}")
    return plan


def _qp_member(system, family, patient, q_current, margin, table_samples, preferred, directions):
    """The plan of a member the QP reaches, among :data:`QP_TRIES` spread over the family (nearest ``preferred``
    first when given, else the most clearance), or None."""
    tries = np.unique(np.linspace(0, len(family), min(QP_TRIES, len(family)), endpoint=False).astype(int))
    if preferred is not None:
        tries = tries[np.argsort(-(directions[tries] @ preferred), kind="stable")]
    plans = [plan_view(system, family[int(k)], patient, q_current, margin=margin, nearest=False,
                       table_samples=table_samples, qp=True, motion_plan=False) for k in tries]
    good = [p for p in plans if p.success]
    if not good:
        return None
    return good[0] if preferred is not None else max(good, key=lambda p: p.clearance)
