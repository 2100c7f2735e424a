"""The one search behind :func:`~carmkin.views.plan_view` and :func:`~carmkin.views.reach_map`.

For N cells (target, beam direction, distance range) at once:

1. every (held table sample, wigwag sample θ2, sign σ) family in closed form with its exact interval of
   distances (:mod:`carmkin.views.closed_form`);
2. each feasible family scored by the cheap bound of :meth:`World.beam_bound` at its best distance (the free
   roll and distance are used for clearance first), ties (within :data:`CLEARANCE_BIN`) broken by the least
   normalised motion from the reference configuration;
3. per cell, the candidates in that order checked exactly (:meth:`World.clearance`) until one keeps the
   margin; the first that does is the answer, with its exact clearance.

A cell with no feasible family is unreachable by the joint ranges; one whose candidates all touch is
unreachable by contact (the nearest pair is named). Lengths in m, angles in rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import closed_form

#: Wigwag samples are at most this far apart (rad) — finer than the 1° roll steps of the acceptance check.
THETA2_STEP = math.radians(0.5)
#: Distances scored per cell for the clearance ranking.
DISTANCE_SAMPLES = 9
#: Clearances within this (m) rank as equal; the least motion decides between them.
CLEARANCE_BIN = 0.01
#: Distances tried per family besides the best-scored one, as fractions of its interval (ends included).
DISTANCE_CHOICES = (0.0, 1.0, 0.5, 0.25, 0.75, 0.125, 0.875)
#: Cells searched together.
CHUNK = 256
#: Candidates per cell screened together (vectorised) before their exact checks, at most.
ROUND = 32
#: Rows screened in a search's first round, at least (up to ROUND per cell).
MIN_ROWS = 1024
#: Exact checks per cell before it is declared unreachable by contact.
MAX_EXACT_CHECKS = 96


@dataclass
class Context:
    """What stays fixed over a search: the system, its :class:`~carmkin.views.clearance.World`, the margin
    (m), the reference configuration (nq,), the held table samples (list of q (nq,)) and the θ2 samples."""

    system: object
    world: object
    margin: float
    q_ref: np.ndarray
    holds: list
    theta2: np.ndarray
    max_checks: int = 0  # exact checks per cell (0: MAX_EXACT_CHECKS)


def make_context(system, world, margin, q_ref, table_samples=None) -> Context:
    lower, upper = system.lower, system.upper
    j2 = system.nq - 4
    count = max(2, int(math.ceil((upper[j2] - lower[j2]) / THETA2_STEP)) + 1)
    theta2 = np.linspace(lower[j2], upper[j2], count)
    holds = [np.asarray(q_ref, dtype=float)] if table_samples is None else [np.asarray(h, float) for h in table_samples]
    return Context(system, world, margin, np.asarray(q_ref, dtype=float), holds, theta2)


@dataclass
class Outcome:
    """Per cell: ``reachable`` (N,), ``q`` (N, nq) (NaN where unreachable), ``clearance`` (N,) exact (m,
    NaN where unreachable), ``distance`` (N,) source–target (m), ``reason`` (N,) text for unreachable cells
    (None where reachable), ``binding`` (N,) the constraint that binds: a joint name, ``"contact"`` or ``""``."""

    reachable: np.ndarray
    q: np.ndarray
    clearance: np.ndarray
    distance: np.ndarray
    reason: np.ndarray
    binding: np.ndarray


def _frame(system, q_hold) -> np.ndarray:
    if not system.table.joints:
        return system.carm_base_pose
    _, q_table = system.split(q_hold)
    return system.table_motion(q_table) @ system.carm_base_pose


def _lambda_at(fam, idx, s):
    """λ (M,) of the families ``idx`` where the distance is ``s`` (M,), kept in their intervals."""
    base, slope = fam.base[idx][:, 0], fam.slope[idx][:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.where(np.abs(slope) > closed_form.DEGENERATE, (s - base) / slope, 0.5 * (fam.lo[idx] + fam.hi[idx]))
    return np.clip(lam, fam.lo[idx], fam.hi[idx])


def solve_cells(ctx: Context, targets, directions, distance_range) -> Outcome:
    """Search N cells: targets/directions (N, 3) in the table frame, distance_range (N, 2) (m), in chunks of
    :data:`CHUNK` cells (the candidate arrays of a chunk stay in cache)."""
    if len(targets) <= CHUNK:
        return _solve_chunk(ctx, targets, directions, distance_range)
    parts = [_solve_chunk(ctx, targets[a:a + CHUNK], directions[a:a + CHUNK], distance_range[a:a + CHUNK])
             for a in range(0, len(targets), CHUNK)]
    return Outcome(*(np.concatenate([getattr(p, f) for p in parts]) for f in
                     ("reachable", "q", "clearance", "distance", "reason", "binding")))


def _solve_chunk(ctx: Context, targets, directions, distance_range) -> Outcome:
    system, world = ctx.system, ctx.world
    N = len(targets)
    span = np.maximum(system.upper - system.lower, 1e-9)
    cand = []  # (cell, score, motion, q)
    s_grid = distance_range[:, :1] + (distance_range[:, 1:] - distance_range[:, :1]) * np.linspace(0, 1, DISTANCE_SAMPLES)
    sources = targets[:, None, :] - s_grid[..., None] * directions[:, None, :]
    grid_score = world.beam_bound(sources.reshape(-1, 3), np.repeat(directions, DISTANCE_SAMPLES, axis=0))
    grid_score = grid_score.reshape(N, DISTANCE_SAMPLES)
    angle_excess = np.full(N, np.inf)
    line_empty = np.zeros(N, dtype=bool)
    for hold in ctx.holds:
        fam = closed_form.families(system, targets, directions, ctx.theta2, _frame(system, hold), ctx.q_ref,
                                   distance_range)
        angle_excess = np.minimum(angle_excess, fam.angle_excess.min(axis=(1, 2)))
        line_empty |= np.any((fam.angle_excess == 0) & (fam.lo > fam.hi), axis=(1, 2))
        idx = np.nonzero(fam.feasible)
        if not len(idx[0]):
            continue
        n = idx[0]
        s0, s1 = fam.base[idx][:, 0] + fam.slope[idx][:, 0] * fam.lo[idx], fam.base[idx][:, 0] + fam.slope[idx][:, 0] * fam.hi[idx]
        s_lo, s_hi = np.minimum(s0, s1), np.maximum(s0, s1)
        inside = (s_grid[n] >= s_lo[:, None] - 1e-12) & (s_grid[n] <= s_hi[:, None] + 1e-12)
        masked = np.where(inside, grid_score[n], -np.inf)
        best = np.argmax(masked, axis=1)
        has = inside.any(axis=1)
        s_star = np.where(has, s_grid[n, best], 0.5 * (s_lo + s_hi))
        score = np.where(has, masked[np.arange(len(n)), best], np.nan)
        if not has.all():
            miss = ~has
            score[miss] = world.beam_bound(targets[n[miss]] - s_star[miss, None] * directions[n[miss]], directions[n[miss]])
        # Distance choices per family: the best-scored one and points spread over its interval (the
        # bound ranks loosely: the candidates are tried round-robin over these choices).
        choices = [s_star] + [s_lo + f * (s_hi - s_lo) for f in DISTANCE_CHOICES]
        for kind, s_try in enumerate(choices):
            if kind:
                score = world.beam_bound(targets[n] - s_try[:, None] * directions[n], directions[n])
            lam = _lambda_at(fam, idx, s_try)
            q = closed_form.joints(system, fam, idx, lam, hold)
            motion = np.sum(np.abs(q - ctx.q_ref) / span, axis=1)
            cand.append((n, score, motion, q, np.full(len(n), kind)))
    reachable = np.zeros(N, dtype=bool)
    q_out = np.full((N, system.nq), np.nan)
    clearance = np.full(N, np.nan)
    distance = np.full(N, np.nan)
    reason = np.full(N, None, dtype=object)
    binding = np.full(N, "", dtype=object)
    contact = np.full(N, None, dtype=object)
    if cand:
        n = np.concatenate([c[0] for c in cand])
        score = np.concatenate([c[1] for c in cand])
        motion = np.concatenate([c[2] for c in cand])
        q = np.concatenate([c[3] for c in cand])
        kind = np.concatenate([c[4] for c in cand])
        order = np.lexsort((motion, -np.floor(score / CLEARANCE_BIN), kind, n))
        n, q, kind = n[order], q[order], kind[order]
        # Round-robin over the distance choices: the k-th best of each choice before the (k+1)-th of any.
        group = np.flatnonzero(np.r_[True, (n[1:] != n[:-1]) | (kind[1:] != kind[:-1])])
        rank = np.arange(len(n)) - np.repeat(group, np.diff(np.r_[group, len(n)]))
        order = np.lexsort((kind, rank, n))
        n, q = n[order], q[order]
        starts = np.flatnonzero(np.r_[True, n[1:] != n[:-1]])
        position = np.arange(len(n)) - np.repeat(starts, np.diff(np.r_[starts, len(n)]))
        checks = np.zeros(N, dtype=int)
        limit = ctx.max_checks or MAX_EXACT_CHECKS
        closest = {}
        first, size = 0, int(np.clip(MIN_ROWS // N, 1, ROUND))
        while first <= int(position.max()):
            # Rounds grow to ROUND candidates per cell from one (MIN_ROWS or more cells; most are decided by
            # their first candidates) or more (few cells: a round's cost is then its fixed cost).
            rows = np.flatnonzero((position >= first) & (position < first + size) & ~reachable[n]
                                  & (checks[n] < limit))
            first, size = first + size, min(2 * size, ROUND)
            if not len(rows):
                break
            # Candidates that certainly touch (a sphere inside a moving part already within the margin of the
            # table or the patient) never reach coal.
            rows = rows[~world.certainly_closer(q[rows], ctx.margin)]
            for k in rows.tolist():
                cell = int(n[k])
                if reachable[cell] or checks[cell] >= limit:
                    continue
                checks[cell] += 1
                d, pair = world.clearance(q[k], stop_below=ctx.margin)
                if d >= ctx.margin:
                    reachable[cell], q_out[cell], clearance[cell] = True, q[k], d
                elif d < closest.get(cell, (np.inf, -1))[0]:
                    closest[cell] = (d, pair)
        if reachable.any():
            T = system.fk(q_out[reachable])
            distance[reachable] = np.einsum("ij,ij->i", targets[reachable] - T[:, :3, 3], T[:, :3, 2])
        for cell in np.unique(n).tolist():
            if not reachable[cell]:
                contact[cell] = closest.get(cell, (-np.inf, -1))
    for cell in np.flatnonzero(~reachable).tolist():
        if contact[cell] is not None:
            d, pair = contact[cell]
            if pair < 0:
                reason[cell] = (f"contact: every roll and distance in range brings a part of the C-arm within the "
                                f"margin ({ctx.margin * 1e3:.1f} mm) of the table or the patient")
            else:
                a, b = world.pair_names(pair)
                reason[cell] = f"contact: {a} – {b} at {d * 1e3:.1f} mm (margin {ctx.margin * 1e3:.1f} mm)"
            binding[cell] = "contact"
        elif np.isfinite(angle_excess[cell]) and angle_excess[cell] > 0 and not line_empty[cell]:
            reason[cell] = "joint limits: no roll puts the beam along the view within the angular and orbital ranges"
            binding[cell] = "angular/orbital"
        else:
            reason[cell] = ("joint limits: no distance in the range puts the beam through the target within the "
                            "translation ranges (table translation, vertical, horizontal)")
            binding[cell] = "translations"
    return Outcome(reachable, q_out, clearance, distance, reason, binding)
