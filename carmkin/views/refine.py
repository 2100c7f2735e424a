"""The QP after the closed form: every joint free where the closed-form search holds some.

The view search (:mod:`carmkin.views.search`) solves the C-arm's joints and the table translation in closed
form and holds a motorized table's other joints (tilt, Trendelenburg, lateral, height, rotation) at the
reference configuration's values. When it leaves a view unreachable on such a system, :func:`refine` asks
:func:`carmkin.qp_ik.prepare`'s solver for the beam with every joint free: an
:class:`~carmkin.qp.targets.AxisTarget` (source on the beam line, beam along the view, roll free) at a few
source–target distances, from the reference configuration. An answer is kept only when, by independent
checks, its beam is the view's (FK, to :data:`QP_AXIS_TOLERANCE`) and its exact clearance keeps the margin.
Lengths in m, angles in rad.
"""

from __future__ import annotations

import weakref

import numpy as np

#: Source–target distances tried, as fractions of the view's distance range.
QP_DISTANCES = (0.5, 0.35, 0.65, 0.2, 0.8)
#: A QP answer's beam is along the view and through its target to this (rad, m): the QP's own tolerances
#: (1e-6) with room for its last step.
QP_AXIS_TOLERANCE = 2e-6

_PREPARED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def frees_joints(system) -> bool:
    """Whether the QP frees joints that the closed-form search holds (a motorized table's, a mount's)."""
    return system.nq > 6


def _solver(world, margin: float):
    from carmkin import qp_ik

    per_world = _PREPARED.setdefault(world, {})
    if margin not in per_world:
        per_world[margin] = qp_ik.prepare(world.system, options=qp_ik.QPIKOptions(safety_margin=margin),
                                          world=world)
    return per_world[margin]


def refine(ctx, target, direction, distance_range) -> tuple[np.ndarray, float, float] | None:
    """``(q, clearance, distance)`` of a configuration with every joint free whose beam passes through
    ``target`` (3,) along ``direction`` (3,) (table frame) at a source–target distance in ``distance_range``
    (2,) (m), keeping ``ctx.margin`` of exact clearance; None when the QP finds none."""
    from carmkin.qp_ik import AxisTarget

    system, world = ctx.system, ctx.world
    solver = _solver(world, ctx.margin)
    lo, hi = float(distance_range[0]), float(distance_range[1])
    for fraction in QP_DISTANCES if hi > lo else (0.0,):
        s = lo + fraction * (hi - lo)
        result = solver.solve(AxisTarget(tuple(target - s * direction), tuple(direction)), q_current=ctx.q_ref)
        if not result.success:
            continue
        q = np.asarray(result.q, dtype=float)
        T = system.fk(q)
        w = target - T[:3, 3]
        along = float(w @ T[:3, 2])
        if (np.linalg.norm(T[:3, 2] - direction) > QP_AXIS_TOLERANCE
                or np.linalg.norm(w - along * T[:3, 2]) > QP_AXIS_TOLERANCE
                or not lo - QP_AXIS_TOLERANCE <= along <= hi + QP_AXIS_TOLERANCE
                or np.any(q < system.lower) or np.any(q > system.upper)):
            continue
        d = float(world.clearance(q)[0])
        if d >= ctx.margin:
            return q, d, along
    return None
