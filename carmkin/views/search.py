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

from carmkin.sweeps.clearance import accuracy

from . import closed_form

SCREEN = False

#: Wigwag samples are at most this far apart (rad) — finer than the 1° roll steps of the acceptance check.
THETA2_STEP = math.radians(0.5)
#: Distances scored per cell for the clearance ranking.
DISTANCE_SAMPLES = 9
#: Distances sampled per cell for the scores of the other distance choices (a 1-Lipschitz lower envelope).
FINE_DISTANCE_SAMPLES = 49
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


def _candidates(ctx: Context, chunk, kinds, cells=None):
    """Candidates of the families of ``chunk`` (only of ``cells`` (N,) bool, when given), one per family and
    distance choice ``kind`` in ``kinds``: arrays (cell, score, motion, q, kind, distance)."""
    system, world = ctx.system, ctx.world
    targets, directions, s_grid, grid_score, fams = chunk.targets, chunk.directions, chunk.s_grid, chunk.grid_score, chunk.families
    span = np.maximum(system.upper - system.lower, 1e-9)
    out = []
    e1, e2 = _roll_basis(directions)
    for hold, fam, idx in fams:
        if cells is not None:
            keep = cells[idx[0]]
            idx = tuple(i[keep] for i in idx)
        if not len(idx[0]):
            continue
        n = idx[0]
        base, slope = fam.base[idx][:, 0], fam.slope[idx][:, 0]
        s0, s1 = base + slope * fam.lo[idx], base + slope * fam.hi[idx]
        s_lo, s_hi = np.minimum(s0, s1), np.maximum(s0, s1)
        inside = (s_grid[n] >= s_lo[:, None] - 1e-12) & (s_grid[n] <= s_hi[:, None] + 1e-12)
        masked = np.where(inside, grid_score[n], -np.inf)
        best = np.argmax(masked, axis=1)
        has = inside.any(axis=1)
        s_star = np.where(has, s_grid[n, best], 0.5 * (s_lo + s_hi))
        # The roll about the beam, the same for every distance of a family: the source's x axis is
        # (−c2 c4, −s2 c4, s4) in the C-arm base frame (ClosedFormFK), turned by the base frame.
        th2, th4 = fam.theta[idx][:, 0], fam.theta[idx][:, 1]
        x = (np.stack((-np.cos(th2) * np.cos(th4), -np.sin(th2) * np.cos(th4), np.sin(th4)), axis=1)
             @ _frame(system, hold)[:3, :3].T)
        roll = np.arctan2(np.einsum("ij,ij->i", x, e2[n]), np.einsum("ij,ij->i", x, e1[n]))
        for kind in kinds:
            # Distance choices per family: the best-scored one and points spread over its interval (the
            # bound ranks loosely: the candidates are tried round-robin over these choices).
            if kind == 0:
                s_try = s_star
                score = np.where(has, masked[np.arange(len(n)), best], np.nan)
                if not has.all():
                    miss = ~has
                    score[miss] = world.beam_bound(targets[n[miss]] - s_star[miss, None] * directions[n[miss]],
                                                   directions[n[miss]])
            else:
                s_try = s_lo + DISTANCE_CHOICES[kind - 1] * (s_hi - s_lo)
                score = chunk.fine_bound(world, n, s_try, cells)
            q = closed_form.joints(system, fam, idx, _lambda_at(fam, idx, s_try), hold)
            motion = np.sum(np.abs(q - ctx.q_ref) / span, axis=1)
            out.append((n, score, motion, q, np.full(len(n), kind), np.stack((s_try, roll), axis=1)))
    if not out:
        return None
    return tuple(np.concatenate([c[i] for c in out]) for i in range(6))


def _roll_basis(directions):
    """Unit vectors e1, e2 (N, 3) with (e1, e2, d) right-handed: the roll about beam d is measured from e1."""
    helper = np.where(np.abs(directions[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(directions, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(directions, e1)


def _ordered(cand):
    """The candidates in search order: per cell, by clearance bin (best first) then least motion within each
    distance choice, and round-robin over the choices (the k-th of each before the (k+1)-th of any). Returns
    (cell, q, distance, position in its cell)."""
    n, score, motion, q, kind, s = cand
    order = np.lexsort((motion, -np.floor(score / CLEARANCE_BIN), kind, n))
    n, q, kind, s = n[order], q[order], kind[order], s[order]
    group = np.flatnonzero(np.r_[True, (n[1:] != n[:-1]) | (kind[1:] != kind[:-1])])
    rank = np.arange(len(n)) - np.repeat(group, np.diff(np.r_[group, len(n)]))
    order = np.lexsort((kind, rank, n))
    n, q, s = n[order], q[order], s[order]
    starts = np.flatnonzero(np.r_[True, n[1:] != n[:-1]])
    position = np.arange(len(n)) - np.repeat(starts, np.diff(np.r_[starts, len(n)]))
    return n, q, s, position


@dataclass
class _Chunk:
    targets: np.ndarray
    directions: np.ndarray
    s_grid: np.ndarray
    grid_score: np.ndarray
    families: list  # (hold, Families, feasible index)
    distance_range: np.ndarray
    fine: np.ndarray | None = None

    def fine_bound(self, world, n, s, cells=None) -> np.ndarray:
        """The beam bound (:meth:`World.beam_bound`) at distances s (M,) of cells n (M,), from below: it moves by
        at most |Δs| when the source does, so ``g(s_j) − |s − s_j|`` at the two samples about s bounds it.
        Samples :data:`FINE_DISTANCE_SAMPLES` per cell (of ``cells``, when given) on first use."""
        lo, hi = self.distance_range[:, 0], self.distance_range[:, 1]
        if self.fine is None:
            self.fine = np.full((len(lo), FINE_DISTANCE_SAMPLES), np.nan)
            rows = np.arange(len(lo)) if cells is None else np.flatnonzero(cells)
            grid = lo[rows, None] + (hi - lo)[rows, None] * np.linspace(0, 1, FINE_DISTANCE_SAMPLES)
            d = np.repeat(self.directions[rows], FINE_DISTANCE_SAMPLES, axis=0)
            self.fine[rows] = world.beam_bound((self.targets[rows, None, :] - grid[..., None] * self.directions[rows, None, :])
                                               .reshape(-1, 3), d).reshape(len(rows), FINE_DISTANCE_SAMPLES)
        step = (hi - lo)[n] / (FINE_DISTANCE_SAMPLES - 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.where(step > 0, (s - lo[n]) / step, 0.0)
        j = np.clip(np.floor(u).astype(int), 0, FINE_DISTANCE_SAMPLES - 2)
        frac = np.clip(u - j, 0.0, 1.0) * step
        return np.maximum(self.fine[n, j] - frac, self.fine[n, j + 1] - (step - frac))


@dataclass
class _State:
    reachable: np.ndarray
    q: np.ndarray
    clearance: np.ndarray
    checks: np.ndarray
    closest: dict
    found_at: np.ndarray  # position of the answer in its cell's search order (-1: none)
    regions: "_Regions"


def _check(ctx: Context, chunk: _Chunk, state: _State, n, q, s, position, screen: bool = True) -> None:
    """Try candidates (cells n, configurations q, distances s) given in search order: each cell takes its
    first candidate that keeps the margin, after at most ``max_checks`` exact checks. Candidates inside a
    certified contact region of their cell (:class:`_Regions`) are not checked."""
    world, margin = ctx.world, ctx.margin
    limit = ctx.max_checks or MAX_EXACT_CHECKS
    rows = np.flatnonzero(~state.reachable[n] & (state.checks[n] < limit))
    if len(rows):
        rows = rows[~state.regions.contain(n[rows], s[rows])]
    if screen and len(rows):
        # Candidates that certainly touch never reach coal: a ball on the beam axis inside the source housing
        # or the detector (whatever the roll) or a ball inside a moving part already within the margin.
        d = chunk.directions[n[rows]]
        rows = rows[~world.beam_certainly_closer(chunk.targets[n[rows]] - s[rows, :1] * d, d, margin)]
        rows = rows[~world.certainly_closer(q[rows], margin)]
    if not len(rows):
        return
    distance, pair = world.clearances(q[rows], stop_below=margin)
    touching = []
    for k, dk, pk in zip(rows.tolist(), distance.tolist(), pair.tolist()):
        cell = int(n[k])
        if state.reachable[cell] or state.checks[cell] >= limit:
            continue
        state.checks[cell] += 1
        if dk >= margin:
            state.reachable[cell], state.q[cell], state.clearance[cell] = True, q[k], dk
            state.found_at[cell] = position[k]
        else:
            touching.append(k)
            if dk < state.closest.get(cell, (np.inf, -1))[0]:
                state.closest[cell] = (dk, pk)
    if touching:
        touching = np.array(touching)
        state.regions.add(n[touching], s[touching], distance[np.searchsorted(rows, touching)],
                          pair[np.searchsorted(rows, touching)])


class _Regions:
    """Certified contact regions of a cell's candidates. Everything the orbital joint carries (source housing,
    detector, C-arc) is one rigid body whose pose, for a view, is set by the distance s and the roll ρ about
    the beam alone: a point of it moves by at most ``|Δs| + r |Δρ|``, r its distance from the beam axis. A
    candidate (s_c, ρ_c) whose pair k (such a part against the fixed table or patient, convex shapes) is at
    d_k < margin keeps that pair closer than the margin wherever ``|s − s_c| + r_k |ρ − ρ_c| < margin − d_k``
    (signed distances of convex shapes change no faster than their points move), less coal's accuracy."""

    def __init__(self, world, margin: float) -> None:
        self.world, self.margin = world, margin
        self.cell = np.zeros(0, dtype=int)
        self.where = np.zeros((0, 2))
        self.lever = np.zeros(0)
        self.slack = np.zeros(0)

    def add(self, cells, where, distances, pairs) -> None:
        lever = self.world.roll_lever[np.maximum(pairs, 0)]
        keep = (pairs >= 0) & np.isfinite(lever)
        if not keep.any():
            return
        d = distances[keep]
        self.cell = np.r_[self.cell, cells[keep]]
        self.where = np.vstack((self.where, where[keep]))
        self.lever = np.r_[self.lever, lever[keep]]
        self.slack = np.r_[self.slack, self.margin - d - accuracy(np.abs(d))]

    def contain(self, cells, where) -> np.ndarray:
        """(M,) True where candidate (s, ρ) ``where[m]`` lies in a region of cell ``cells[m]``."""
        out = np.zeros(len(cells), dtype=bool)
        if not len(self.cell):
            return out
        order = np.argsort(self.cell, kind="stable")
        sorted_cells = self.cell[order]
        start = np.searchsorted(sorted_cells, cells, "left")
        count = np.searchsorted(sorted_cells, cells, "right") - start
        total = int(count.sum())
        if not total:
            return out
        row = np.repeat(np.arange(len(cells)), count)
        region = order[np.arange(total) - np.repeat(np.cumsum(count) - count, count) + np.repeat(start, count)]
        delta = np.abs(where[row] - self.where[region])
        delta[:, 1] = np.minimum(delta[:, 1], 2 * np.pi - delta[:, 1])
        reach = delta[:, 0] + self.lever[region] * delta[:, 1]
        out[row[reach < self.slack[region]]] = True
        return out


def _solve_chunk(ctx: Context, targets, directions, distance_range) -> Outcome:
    system, world = ctx.system, ctx.world
    N = len(targets)
    s_grid = distance_range[:, :1] + (distance_range[:, 1:] - distance_range[:, :1]) * np.linspace(0, 1, DISTANCE_SAMPLES)
    sources = targets[:, None, :] - s_grid[..., None] * directions[:, None, :]
    grid_score = world.beam_bound(sources.reshape(-1, 3), np.repeat(directions, DISTANCE_SAMPLES, axis=0))
    chunk = _Chunk(targets, directions, s_grid, grid_score.reshape(N, DISTANCE_SAMPLES), [], distance_range)
    angle_excess = np.full(N, np.inf)
    line_empty = np.zeros(N, dtype=bool)
    for hold in ctx.holds:
        fam = closed_form.families(system, targets, directions, ctx.theta2, _frame(system, hold), ctx.q_ref,
                                   distance_range)
        angle_excess = np.minimum(angle_excess, fam.angle_excess.min(axis=(1, 2)))
        line_empty |= np.any((fam.angle_excess == 0) & (fam.lo > fam.hi), axis=(1, 2))
        idx = np.nonzero(fam.feasible)
        if len(idx[0]):
            chunk.families.append((hold, fam, idx))
    state = _State(np.zeros(N, dtype=bool), np.full((N, system.nq), np.nan), np.full(N, np.nan),
                   np.zeros(N, dtype=int), {}, np.full(N, -1), _Regions(world, ctx.margin))
    searched = np.zeros(N, dtype=bool)
    # Most cells are decided by their first candidate: it is found among the best-scored distances alone, and
    # only the cells it leaves undecided get every candidate.
    first = _candidates(ctx, chunk, (0,))
    if first is not None:
        n, q, s, position = _ordered(first)
        searched[n] = True
        head = position == 0
        _check(ctx, chunk, state, n[head], q[head], s[head], position[head], screen=False)
        left = searched & ~state.reachable
        rest = _candidates(ctx, chunk, range(len(DISTANCE_CHOICES) + 1), cells=left) if left.any() else None
        if rest is not None:
            n, q, s, position = _ordered(rest)
            keep = position > 0
            n, q, s, position = n[keep], q[keep], s[keep], position[keep]
            first, size = 1, 1
            while len(n) and first <= int(position.max()):
                # Rounds grow to ROUND candidates per cell (a round's cost is mostly fixed).
                rows = np.flatnonzero((position >= first) & (position < first + size))
                first, size = first + size, min(2 * size, ROUND)
                _check(ctx, chunk, state, n[rows], q[rows], s[rows], position[rows], screen=SCREEN)
    reachable, q_out, clearance = state.reachable, state.q, state.clearance
    distance = np.full(N, np.nan)
    reason = np.full(N, None, dtype=object)
    binding = np.full(N, "", dtype=object)
    if reachable.any():
        T = system.fk(q_out[reachable])
        distance[reachable] = np.einsum("ij,ij->i", targets[reachable] - T[:, :3, 3], T[:, :3, 2])
    for cell in np.flatnonzero(~reachable).tolist():
        if searched[cell]:
            d, pair = state.closest.get(cell, (-np.inf, -1))
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
    global LAST_FOUND_AT
    LAST_FOUND_AT = state.found_at
    return Outcome(reachable, q_out, clearance, distance, reason, binding)
