"""Reachability maps: which XA views of a target a system can take, with the patient in the world.

:func:`reach_map` searches every (primary, secondary) cell with the one search of
:mod:`carmkin.views.search` — the same as :func:`~carmkin.views.plan_view` with no ``q_current`` — all
cells at once: closed-form families over the wigwag samples with their exact distance intervals, a cheap
bounding-volume score, exact coal distances only for the candidates that decide. A robot that holds the C is
freed by its closed form (:mod:`carmkin.views.mount`), a mount without one by the QP cell by cell
(:func:`free_mount`). Angles in degrees at the boundary, lengths in m.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from carmkin.errors import ViewError
from carmkin.validation import integer, real_array, real_scalar

from . import mount, refine, search
from .plan import DEFAULT_MARGIN, _table_samples, beam_directions, reference, world_for
from .view import _patient_frame, _point


@dataclass(frozen=True)
class ReachMap:
    """``primary_deg`` (P,), ``secondary_deg`` (S,); per cell ``reachable`` (P, S), ``q`` (P, S, nq) (NaN
    where unreachable), ``clearance`` (P, S) exact (m), ``distance`` (P, S) source–target (m), ``binding``
    (P, S) the constraint that binds an unreachable cell (a joint group or ``"contact"``), ``reason`` (P, S)
    its sentence; ``directions`` (P, S, 3) the beams (table frame), ``target`` (3,) m; ``rank`` (P, S) the
    answer's position in its cell's search order (0: the first candidate; −1: unreachable;
    :data:`~carmkin.views.search.MAX_EXACT_CHECKS`: found by the polish between the samples,
    :mod:`carmkin.views.polish`; :data:`QP_RANK`: by the QP; a robot's cell found by its closed form: its
    place in that search's order, :mod:`carmkin.views.mount`)."""

    primary_deg: np.ndarray
    secondary_deg: np.ndarray
    target: np.ndarray
    directions: np.ndarray
    reachable: np.ndarray
    q: np.ndarray
    clearance: np.ndarray
    distance: np.ndarray
    binding: np.ndarray
    reason: np.ndarray
    rank: np.ndarray

    @property
    def fraction(self) -> float:
        """Share of the cells that are reachable."""
        return float(self.reachable.mean())


def _angles(value, name, low, high) -> np.ndarray:
    a = real_array(value, name, error=ViewError, unit="deg")
    a = np.atleast_1d(a)
    if a.ndim != 1 or not len(a):
        raise ViewError(f"{name} must be a non-empty 1-D array of angles (deg), got shape {a.shape}")
    if np.any(a < low) or np.any(a > high):
        raise ViewError(f"{name} must lie in [{low:g}, {high:g}] deg, got {a.min():g}..{a.max():g}")
    return a


def reach_map(system, target, primary_deg=np.arange(-90, 91), secondary_deg=np.arange(-45, 46), patient=None, *,
              position=None, margin: float = DEFAULT_MARGIN, table_samples=None, workers: int | None = None) -> ReachMap:
    """The map of ``target`` (3,) m (table frame) over ``primary_deg`` × ``secondary_deg`` (XA angles, deg,
    LAO +, CRA +) for a patient (model or list of Obstacle) in ``position`` (a Patient Position code or
    pose; default the patient model's, else HFS). ``table_samples``: configurations (k, nq) whose table joints
    a motorized table takes (default: mid-range; :func:`carmkin.views.compare.table_samples`).
    ``workers``: processes for a large map (default: the cores this process may use); every cell's answer is
    the same for any number (its clearance to coal's round-off)."""
    target = _point(target, "target")
    p = _angles(primary_deg, "primary_deg", -180.0, 180.0)
    s = _angles(secondary_deg, "secondary_deg", -90.0, 90.0)
    if position is None:
        position = patient if patient is not None and hasattr(patient, "pose") else "HFS"
    R = _patient_frame(position)[:3, :3]
    P, S = np.meshgrid(np.radians(p), np.radians(s), indexing="ij")
    directions = beam_directions(R, P.ravel(), S.ravel())
    world = world_for(system, patient)
    margin = real_scalar(margin, "margin", error=ViewError, low=0.0, high=1.0, unit="m")
    ctx = search.make_context(system, world, margin, reference(system, None), _table_samples(system, table_samples))
    n = len(directions)
    ranges = np.tile([0.0, system.carm.source_to_detector], (n, 1))
    targets = np.tile(target, (n, 1))
    out = search.solve_cells(ctx, targets, directions, ranges, workers=_workers(workers))
    if system.mount.joints:
        out = free_mount(ctx, targets, directions, ranges, out, _workers(workers))
    shape = (len(p), len(s))
    return ReachMap(p, s, target, directions.reshape(shape + (3,)), out.reachable.reshape(shape),
                    out.q.reshape(shape + (system.nq,)), out.clearance.reshape(shape), out.distance.reshape(shape),
                    out.binding.reshape(shape), out.reason.reshape(shape), out.rank.reshape(shape))


#: ``rank`` of a cell that only the QP with every joint free reached (:func:`carmkin.views.refine.refine`): after
#: every place of the closed-form search order (:data:`carmkin.views.search.MAX_EXACT_CHECKS` is its last).
QP_RANK = search.MAX_EXACT_CHECKS + 1

#: What the forked workers of :func:`_with_qp` solve: set before the fork, read by :func:`_refine_block`.
_FORKED = None


def _refine_block(cells):
    ctx, target, directions, ranges = _FORKED
    return [refine.refine(ctx, target, directions[k], ranges[k]) for k in cells]


def _with_qp(ctx, target, directions, ranges, out, workers: int):
    """``out`` with the cells it left unreachable tried by the QP with every joint free (a mount's too): a cell
    it reaches gets the QP's q, exact clearance and distance, rank :data:`QP_RANK`; the others keep their
    reason. Over ``workers`` forked processes for many cells (cells are independent: the same answers)."""
    import dataclasses
    import multiprocessing

    global _FORKED
    cells = np.flatnonzero(~out.reachable)
    if not len(cells):
        return out
    blocks = [cells[a:a + 8] for a in range(0, len(cells), 8)]
    _FORKED = (ctx, target, directions, ranges)
    try:
        if workers > 1 and len(blocks) > 1 and "fork" in multiprocessing.get_all_start_methods():
            with multiprocessing.get_context("fork").Pool(min(workers, len(blocks))) as pool:
                found = [f for part in pool.map(_refine_block, blocks, chunksize=1) for f in part]
        else:
            found = [f for block in blocks for f in _refine_block(block)]
    finally:
        _FORKED = None
    fields = {f.name: getattr(out, f.name).copy() for f in dataclasses.fields(out)}
    for k, answer in zip(cells.tolist(), found):
        if answer is not None:
            q, clearance, distance = answer
            fields["reachable"][k], fields["q"][k] = True, q
            fields["clearance"][k], fields["distance"][k] = clearance, distance
            fields["reason"][k], fields["binding"][k], fields["rank"][k] = None, "", QP_RANK
    return type(out)(**fields)


def free_mount(ctx, targets, directions, ranges, out, workers: int):
    """``out`` (the search with a mount's joints held, a robot's) with the cells it left unreachable freed: by the
    mount's closed form (:mod:`carmkin.views.mount`) where the robot has one, else by the QP cell by cell
    (:func:`_with_qp`; the targets are one point). The closed form's sampled search is the map's answer for
    such a robot: it reached every cell the QP reached on the benchmark maps (benchmarks/bench_robot_reach.py)
    at a fraction of its cost; :func:`~carmkin.views.plan_view` still asks the QP for a view it leaves
    unreachable."""
    if mount.applies(ctx.system):
        return mount.with_mount(ctx, out, targets, directions, ranges, workers=workers)
    return _with_qp(ctx, targets[0], directions, ranges, out, workers)


def default_workers() -> int:
    """The processes a large map uses by default: the cores this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def _workers(value) -> int:
    return default_workers() if value is None else integer(value, "workers", low=1, error=ViewError)


def carm_alone(system):
    """``system`` with the table translation held at 0 (range [0, 0]): the 5-DOF C-arm of §4.6.1 beside a
    fixed table, as a system of the same joints."""
    import dataclasses

    from carmkin.model.params import JointRange

    return system.replace(table=dataclasses.replace(system.table, translation=JointRange(0.0, 0.0, "table_translation")))
