"""The one search behind :func:`~carmkin.views.plan_view` and :func:`~carmkin.views.reach_map`.

For N cells (target, beam direction, distance range) at once:

1. every (held table sample, wigwag sample θ2, sign σ) family in closed form with its exact interval of
   distances (:mod:`carmkin.views.closed_form`);
2. per family, candidates at :data:`DISTANCE_CHOICES` of its interval and at its best-scored distance, each
   scored by the cheap bound of :meth:`carmkin.world.beam.BeamScreen.bound` (the free roll and distance are used for clearance
   first), ties (within :data:`CLEARANCE_BIN`) broken by the least normalised motion from the reference
   configuration, tried round-robin over the distance choices;
3. per cell, the candidates in that order checked exactly (:meth:`carmkin.world.World.nearest`) until one keeps the
   margin; the first that does is the answer, with its exact clearance. A candidate inside a certified
   contact region of an earlier one (:mod:`carmkin.views.regions`) touches and is not checked.
4. per cell that every candidate left in contact, with its best exact clearance within
   :data:`carmkin.views.polish.WINDOW` of the margin: an ascent of the exact clearance between the samples
   (continuous wigwag, the distance anywhere in its family's exact interval) from its best candidates
   (:mod:`carmkin.views.polish`); a point that keeps the margin is the answer.

The sampled passes alone missed valid configurations between their samples (issue 31: 2 of 153 views called
unreachable); with step 4 a brute force that shares none of this code (``tests/views/bruteforce.py``, run by
``python benchmarks/bruteforce_views.py``) finds none on the views it calls unreachable — a check, not a
proof (docs/views.md has the numbers).

Most cells are answered by their first candidate, so it is found and checked for every cell first (the
best-scored distances alone), and only the cells it leaves open get the rest of their candidates. The
answer of a cell does not depend on the other cells searched with it (:func:`plan_view` and
:func:`reach_map` agree cell by cell).

A cell with no feasible family is unreachable by the joint ranges; one whose candidates all touch is
unreachable by contact (the nearest pair is named). Lengths in m, angles in rad.
"""

from __future__ import annotations

import dataclasses
import math
import multiprocessing
from dataclasses import dataclass, field

import numpy as np

from . import closed_form, polish
from .regions import Regions

#: Wigwag samples are at most this far apart (rad) — finer than the 1° roll steps of the acceptance check.
THETA2_STEP = math.radians(0.5)
#: Distances scored per cell to pick each family's best-scored distance.
DISTANCE_SAMPLES = 9
#: Distances sampled per cell for the scores of the other distance choices (a 1-Lipschitz lower envelope).
FINE_DISTANCE_SAMPLES = 49
#: Clearances within this (m) rank as equal; the least motion decides between them.
CLEARANCE_BIN = 0.01
#: Distances tried per family besides the best-scored one, as fractions of its interval (ends included).
DISTANCE_CHOICES = (0.0, 1.0, 0.5, 0.25, 0.75, 0.125, 0.875)
#: Cells searched together.
CHUNK = 256
#: Candidates per cell checked together (vectorised), at most; rounds grow 1, 2, 4, … to it.
ROUND = 32
#: Exact checks per cell before it is declared unreachable by contact.
MAX_EXACT_CHECKS = 96
#: Cells a search splits over worker processes, at least (below, starting the workers costs more than it saves).
PARALLEL_MIN_CELLS = 2048


@dataclass
class Context:
    """What stays fixed over a search: the system, its :class:`carmkin.world.World`, the margin
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
    (None where reachable), ``binding`` (N,) the constraint that binds: a joint name, ``"contact"`` or ``""``;
    ``contact_q`` (N, nq): for a cell unreachable by contact, the configuration (joints in range) of the exact
    check its ``reason`` reports (the pair and distance named there), NaN elsewhere."""

    reachable: np.ndarray
    q: np.ndarray
    clearance: np.ndarray
    distance: np.ndarray
    reason: np.ndarray
    binding: np.ndarray
    rank: np.ndarray  # (N,) the answer's place in its cell's search order (-1: unreachable; MAX_EXACT_CHECKS: polished)
    contact_q: np.ndarray | None = None

    def __post_init__(self):
        if self.contact_q is None:
            self.contact_q = np.full(np.shape(self.q), np.nan)


def _lambda_at(fam, idx, s):
    """λ (M,) of the families ``idx`` where the distance is ``s`` (M,), kept in their intervals."""
    base, slope = fam.base[idx][:, 0], fam.slope[idx][:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.where(np.abs(slope) > closed_form.DEGENERATE, (s - base) / slope, 0.5 * (fam.lo[idx] + fam.hi[idx]))
    return np.clip(lam, fam.lo[idx], fam.hi[idx])


def _candidates(ctx: Context, chunk, kinds):
    """Candidates of the families of ``chunk``, one per family and distance choice ``kind`` in ``kinds``:
    arrays (chunk cell, score, motion, q, kind, (distance, roll)); None without any."""
    system, world = ctx.system, ctx.world
    targets, directions, s_grid, grid_score = chunk.targets, chunk.directions, chunk.s_grid, chunk.grid_score
    span = np.maximum(system.upper - system.lower, 1e-9)
    out = []
    e1, e2 = _roll_basis(directions)
    for hold, fam, idx in chunk.families:
        n = idx[0]
        base, slope = fam.base[idx][:, 0], fam.slope[idx][:, 0]
        s0, s1 = base + slope * fam.lo[idx], base + slope * fam.hi[idx]
        s_lo, s_hi = np.minimum(s0, s1), np.maximum(s0, s1)
        inside = (s_grid[n] >= s_lo[:, None] - 1e-12) & (s_grid[n] <= s_hi[:, None] + 1e-12)
        masked = np.where(inside, grid_score[n], -np.inf)
        best = np.argmax(masked, axis=1)
        has = inside.any(axis=1)
        s_star = np.where(has, s_grid[n, best], 0.5 * (s_lo + s_hi))
        # The roll about the beam, the same for every distance of a family.
        frame = closed_form.base_frame(system, hold)
        x = closed_form.source_x_axes(fam.theta[idx][:, 0], fam.theta[idx][:, 1], frame)
        roll = np.arctan2(np.einsum("ij,ij->i", x, e2[n]), np.einsum("ij,ij->i", x, e1[n]))
        for kind in kinds:
            # Distance choices per family: the best-scored one and points spread over its interval (the
            # bound ranks loosely: the candidates are tried round-robin over these choices).
            if kind == 0:
                s_try = s_star
                score = np.where(has, masked[np.arange(len(n)), best], np.nan)
                if not has.all():
                    miss = ~has
                    score[miss] = world.beam.bound(targets[n[miss]] - s_star[miss, None] * directions[n[miss]],
                                                   directions[n[miss]])
            else:
                s_try = s_lo + DISTANCE_CHOICES[kind - 1] * (s_hi - s_lo)
                score = chunk.fine_bound(world, n, s_try)
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
    (cell, q, (distance, roll), position in its cell)."""
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
    index: np.ndarray  # the chunk's cells in the whole search
    fine: np.ndarray | None = None

    def fine_bound(self, world, n, s) -> np.ndarray:
        """The beam bound (:meth:`carmkin.world.beam.BeamScreen.bound`) at distances s (M,) of cells n (M,), from below: it moves by
        at most |Δs| when the source does, so ``g(s_j) − |s − s_j|`` at the two samples about s bounds it.
        Samples :data:`FINE_DISTANCE_SAMPLES` per cell on first use."""
        lo, hi = self.distance_range[:, 0], self.distance_range[:, 1]
        if self.fine is None:
            grid = lo[:, None] + (hi - lo)[:, None] * np.linspace(0, 1, FINE_DISTANCE_SAMPLES)
            sources = self.targets[:, None, :] - grid[..., None] * self.directions[:, None, :]
            d = np.repeat(self.directions, FINE_DISTANCE_SAMPLES, axis=0)
            self.fine = world.beam.bound(sources.reshape(-1, 3), d).reshape(len(lo), FINE_DISTANCE_SAMPLES)
        step = (hi - lo)[n] / (FINE_DISTANCE_SAMPLES - 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.where(step > 0, (s - lo[n]) / step, 0.0)
        j = np.clip(np.floor(u).astype(int), 0, FINE_DISTANCE_SAMPLES - 2)
        frac = np.clip(u - j, 0.0, 1.0) * step
        return np.maximum(self.fine[n, j] - frac, self.fine[n, j + 1] - (step - frac))


@dataclass
class _State:
    """Per cell of the whole search (global indices)."""

    reachable: np.ndarray
    q: np.ndarray
    clearance: np.ndarray
    checks: np.ndarray
    rank: np.ndarray
    searched: np.ndarray  # some family is feasible
    angle_excess: np.ndarray
    line_empty: np.ndarray
    regions: Regions
    no_roll: np.ndarray  # a fixed roll that no wigwag value in range gives
    closest: dict = field(default_factory=dict)  # cell -> (distance, pair, q) of its closest exact check
    touched: list = field(default_factory=list)  # (cells, distances, q) of the exact checks below the margin

    @classmethod
    def empty(cls, N: int, nq: int, regions: Regions) -> "_State":
        flags = [np.zeros(N, dtype=bool) for _ in range(4)]
        return cls(flags[0], np.full((N, nq), np.nan), np.full(N, np.nan), np.zeros(N, dtype=int), np.full(N, -1),
                   flags[1], np.full(N, np.inf), flags[2], regions, flags[3])


def _chunk(ctx: Context, targets, directions, distance_range, x_axes, index, state: _State) -> _Chunk:
    """The families of cells ``index`` (global), their scores on :data:`DISTANCE_SAMPLES` distances, and what
    the reasons need (into ``state``). A cell with a fixed roll (a finite row of ``x_axes``) gets the wigwag
    values of that roll instead of the samples, and only the families that have it. A stand with locked vertical
    and horizontal joints also gets its exact wigwag values (:func:`closed_form.locked_theta2`)."""
    system, world = ctx.system, ctx.world
    targets, directions, distance_range = targets[index], directions[index], distance_range[index]
    x_axes = x_axes[index]
    fixed = np.all(np.isfinite(x_axes), axis=1)
    N = len(index)
    lo, hi = distance_range[:, :1], distance_range[:, 1:]
    s_grid = lo + (hi - lo) * np.linspace(0, 1, DISTANCE_SAMPLES)
    sources = targets[:, None, :] - s_grid[..., None] * directions[:, None, :]
    grid_score = world.beam.bound(sources.reshape(-1, 3), np.repeat(directions, DISTANCE_SAMPLES, axis=0))
    chunk = _Chunk(targets, directions, s_grid, grid_score.reshape(N, DISTANCE_SAMPLES), [], distance_range, index)
    for hold in ctx.holds:
        frame = closed_form.base_frame(system, hold)
        theta2 = ctx.theta2
        if fixed.any():
            roots = closed_form.theta2_for_roll(directions[fixed], x_axes[fixed], ctx.theta2, frame)
            theta2 = np.full((N, max(len(ctx.theta2), roots.shape[1])), np.nan)
            theta2[~fixed, :len(ctx.theta2)] = ctx.theta2
            theta2[fixed, :roots.shape[1]] = roots
            state.no_roll[index[fixed][np.all(np.isnan(roots), axis=1)]] = True
        locked = closed_form.locked_theta2(system, targets, directions, frame)
        if locked is not None:  # the exact wigwag values of a locked stand, beside the samples
            theta2 = np.concatenate((np.broadcast_to(theta2, (N, np.shape(theta2)[-1])), locked), axis=1)
        with np.errstate(invalid="ignore"):  # NaN-padded wigwag values make empty families
            fam = closed_form.families(system, targets, directions, theta2, frame, ctx.q_ref, distance_range)
            if fixed.any():
                fam = closed_form.with_roll(fam, directions, x_axes, frame, fixed)
        excess = np.where(np.isnan(fam.angle_excess), np.inf, fam.angle_excess).min(axis=(1, 2))
        state.angle_excess[index] = np.minimum(state.angle_excess[index], excess)
        state.line_empty[index] |= np.any((fam.angle_excess == 0) & (fam.lo > fam.hi), axis=(1, 2))
        idx = np.nonzero(fam.feasible)
        if len(idx[0]):
            chunk.families.append((hold, fam, idx))
            state.searched[index[idx[0]]] = True
    return chunk


def _check(ctx: Context, state: _State, n, q, where, rank) -> None:
    """Try candidates (global cells n, configurations q, (distance, roll) ``where``, ranks) given in search
    order: each cell takes its first candidate that keeps the margin, after at most ``max_checks`` exact
    checks. Candidates inside a certified contact region of their cell are not checked (they touch)."""
    margin = ctx.margin
    limit = ctx.max_checks or MAX_EXACT_CHECKS
    rows = np.flatnonzero(~state.reachable[n] & (state.checks[n] < limit))
    rows = rows[~state.regions.contain(n[rows], where[rows])]
    if not len(rows):
        return
    distance, pair = ctx.world.nearest(q[rows], stop_below=margin)
    touching = []
    for i, (k, dk, pk) in enumerate(zip(rows.tolist(), distance.tolist(), pair.tolist())):
        cell = int(n[k])
        if state.reachable[cell] or state.checks[cell] >= limit:
            continue
        state.checks[cell] += 1
        if dk >= margin:
            state.reachable[cell], state.q[cell], state.clearance[cell], state.rank[cell] = True, q[k], dk, rank[k]
        else:
            touching.append(i)
            if dk < state.closest.get(cell, (np.inf, -1, None))[0]:
                state.closest[cell] = (dk, pk, q[k])
    if touching:
        state.regions.add(n[rows[touching]], where[rows[touching]], distance[touching], pair[touching])
        state.touched.append((n[rows[touching]], distance[touching], q[rows[touching]]))


def solve_cells(ctx: Context, targets, directions, distance_range, x_axes=None, workers: int = 1) -> Outcome:
    """Search N cells: targets/directions (N, 3) in the table frame, distance_range (N, 2) (m), ``x_axes``
    (N, 3): the source's x axis where a cell's roll is fixed (unit, ⊥ its beam), NaN rows (or None) where it
    is free; in chunks of :data:`CHUNK` cells (the candidate arrays of a chunk stay in cache); with
    ``workers`` > 1 and at least :data:`PARALLEL_MIN_CELLS` cells, in blocks over that many forked processes
    (cells are independent)."""
    x_axes = np.full((len(targets), 3), np.nan) if x_axes is None else np.asarray(x_axes, dtype=float)
    if workers > 1 and len(targets) >= PARALLEL_MIN_CELLS and "fork" in multiprocessing.get_all_start_methods():
        return _solve_parallel(ctx, targets, directions, distance_range, x_axes, workers)
    return _solve(ctx, targets, directions, distance_range, x_axes)


#: What the forked workers search: set by :func:`_solve_parallel` before the fork, read by :func:`_solve_block`.
_FORKED = None


def _solve_block(bounds) -> Outcome:
    ctx, targets, directions, distance_range, x_axes = _FORKED
    a, b = bounds
    return _solve(ctx, targets[a:b], directions[a:b], distance_range[a:b], x_axes[a:b])


def _solve_parallel(ctx: Context, targets, directions, distance_range, x_axes, workers: int) -> Outcome:
    """Blocks of :data:`CHUNK` · 4 cells, handed out one at a time (contact cells cluster on a map), over
    ``workers`` forked processes that inherit the search's world (coal's shapes cannot be pickled)."""
    global _FORKED
    N, size = len(targets), 4 * CHUNK
    blocks = [(a, min(a + size, N)) for a in range(0, N, size)]
    _FORKED = (ctx, targets, directions, distance_range, x_axes)
    try:
        with multiprocessing.get_context("fork").Pool(min(workers, len(blocks))) as pool:
            parts = pool.map(_solve_block, blocks, chunksize=1)
    finally:
        _FORKED = None
    return Outcome(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in dataclasses.fields(Outcome)))


def _solve(ctx: Context, targets, directions, distance_range, x_axes) -> Outcome:
    system = ctx.system
    N = len(targets)
    state = _State.empty(N, system.nq, Regions(ctx.world, ctx.margin))
    # Every cell's first candidate: the best-scored distance of its best family.
    for a in range(0, N, CHUNK):
        chunk = _chunk(ctx, targets, directions, distance_range, x_axes, np.arange(a, min(a + CHUNK, N)), state)
        first = _candidates(ctx, chunk, (0,))
        if first is not None:
            n, q, where, rank = _ordered(first)
            head = rank == 0
            _check(ctx, state, chunk.index[n[head]], q[head], where[head], rank[head])
    # The rest, for the cells their first candidate left open, in rounds of growing size (their families are
    # built again: cheaper than keeping every chunk's for the few cells that need them).
    left = np.flatnonzero(state.searched & ~state.reachable)
    for a in range(0, len(left), CHUNK):
        chunk = _chunk(ctx, targets, directions, distance_range, x_axes, left[a:a + CHUNK], state)
        rest = _candidates(ctx, chunk, range(len(DISTANCE_CHOICES) + 1))
        if rest is None:
            continue
        n, q, where, rank = _ordered(rest)
        keep = rank > 0
        n, q, where, rank = chunk.index[n[keep]], q[keep], where[keep], rank[keep]
        start, size = 1, 1
        while len(n) and start <= int(rank.max()):
            rows = np.flatnonzero((rank >= start) & (rank < start + size))
            start, size = start + size, min(2 * size, ROUND)
            _check(ctx, state, n[rows], q[rows], where[rows], rank[rows])
    _polish(ctx, state, targets, directions, distance_range, x_axes)
    return _outcome(ctx, state, targets)


def _polish(ctx: Context, state: _State, targets, directions, distance_range, x_axes) -> None:
    """The cells every sampled candidate left in contact, within :data:`carmkin.views.polish.WINDOW` of the
    margin: ascend from their best candidates between the samples (:mod:`carmkin.views.polish`); a cell
    whose ascent keeps the margin is reachable there (its rank: after every sampled candidate)."""
    if not state.touched:
        return
    cells, distances, q = (np.concatenate([part[i] for part in state.touched]) for i in range(3))
    keep = ~state.reachable[cells] & (distances >= ctx.margin - polish.WINDOW)
    cells, distances, q = cells[keep], distances[keep], q[keep]
    rows = polish.seeds(cells, distances, q, ctx.system)
    if not len(rows):
        return
    cells, distances, q = cells[rows], distances[rows], q[rows]
    fixed = np.all(np.isfinite(x_axes[cells]), axis=1)
    found, q_new, clearance = polish.polish(ctx, cells, targets[cells], directions[cells], distance_range[cells],
                                            fixed, q, distances)
    for k in np.flatnonzero(found).tolist():
        cell = int(cells[k])
        if not state.reachable[cell] or clearance[k] > state.clearance[cell]:
            state.reachable[cell], state.q[cell], state.clearance[cell] = True, q_new[k], clearance[k]
            state.rank[cell] = MAX_EXACT_CHECKS


def _outcome(ctx: Context, state: _State, targets) -> Outcome:
    system, world, margin = ctx.system, ctx.world, ctx.margin
    N = len(targets)
    reachable = state.reachable
    distance = np.full(N, np.nan)
    reason = np.full(N, None, dtype=object)
    binding = np.full(N, "", dtype=object)
    contact_q = np.full((N, system.nq), np.nan)
    if reachable.any():
        T = system.fk(state.q[reachable])
        distance[reachable] = np.einsum("ij,ij->i", targets[reachable] - T[:, :3, 3], T[:, :3, 2])
    for cell in np.flatnonzero(~reachable).tolist():
        if state.searched[cell]:
            d, pair, q_contact = state.closest.get(cell, (-np.inf, -1, None))
            if q_contact is not None:
                contact_q[cell] = q_contact
            if pair < 0:
                reason[cell] = (f"contact: every roll and distance in range brings a part of the C-arm within the "
                                f"margin ({margin * 1e3:.1f} mm) of the table or the patient")
            else:
                a, b = world.pair_names(pair)
                reason[cell] = f"contact: {a} – {b} at {d * 1e3:.1f} mm (margin {margin * 1e3:.1f} mm)"
            binding[cell] = "contact"
        elif state.no_roll[cell]:
            reason[cell] = "joint limits: no wigwag within its range gives this rotation about the beam"
            binding[cell] = "wigwag"
        elif np.isfinite(state.angle_excess[cell]) and state.angle_excess[cell] > 0 and not state.line_empty[cell]:
            reason[cell] = "joint limits: no roll puts the beam along the view within the angular and orbital ranges"
            binding[cell] = "angular/orbital"
        else:
            reason[cell] = ("joint limits: no distance in the range puts the beam through the target within the "
                            "translation ranges (table translation, vertical, horizontal)")
            binding[cell] = "translations"
    return Outcome(reachable, state.q, state.clearance, distance, reason, binding, state.rank, contact_q)
