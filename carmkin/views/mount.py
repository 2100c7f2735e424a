"""The view search of a robot-held C-arm: the mount's closed form (:mod:`carmkin.analytic.mount`) per sampled roll.

A view fixes the beam (target t, direction d) and leaves its roll ψ about the beam and the source–target
distance s free; a robot that holds the C adds the C's own free joint, the orbital slide θ5. With those
three chosen, the source pose is fixed — origin ``t − s d``, z axis d, x axis ``cos ψ e1 + sin ψ e2`` (the
roll basis of :mod:`carmkin.views.search`) — and the robot's six joints follow in closed form: up to eight
branches (:func:`carmkin.analytic.mount.branches`), every other joint (table translation, the C-arm's
stand joints) held at the reference configuration. The free parameters are **sampled**, in passes from the
likeliest to the rarest (:data:`PASSES`):

1. the isocentric distance (the target at the C's isocentre, ``s`` = the source–isocentre distance
   ``carm.orbital_offset``, or the nearest distance of the view's range), the reference orbital, rolls every
   :data:`ROLL_STEP_DEG` × :data:`FIRST_ROLLS_EVERY` (60°), then the rolls between them;
2. the other orbital values of :data:`ORBITAL_OFFSETS_DEG` (from the reference, those in range), every roll;
3. the other distances of :data:`DISTANCE_FRACTIONS` of the view's range, every roll and orbital value.

A view with a fixed roll samples that roll only. In each pass a cell's candidates (branches within every
joint's range) are ordered by the least normalised motion from the reference configuration and checked
exactly (:meth:`carmkin.world.World.nearest`, stopping at the first pair within the margin) in rounds of
growing size, at most :data:`PASS_CHECKS` a pass and :data:`MAX_CHECKS` a cell; the first that keeps the
margin is the cell's answer, with its exact clearance. The samples are a choice, not a proof: a view this
search leaves unreachable goes on to the QP with every joint free in :func:`~carmkin.views.plan_view`
(:mod:`carmkin.views.refine`); a map does not ask the QP (about 0.4 s a cell against about 2 ms), and on every
map measured (``benchmarks/bench_robot_reach.py``, docs/views.md) the QP reached no cell this search missed.
Lengths in m, angles in rad.
"""

from __future__ import annotations

import math
import multiprocessing

import numpy as np

from carmkin.analytic import mount as mount_ik
from carmkin.errors import UnsupportedMountError

from . import search
from .search import Outcome, _roll_basis

#: Roll samples about the beam are this far apart (deg): 24 a turn.
ROLL_STEP_DEG = 15.0
#: The first pass samples every this many rolls (every 60°: most cells are answered there), the second the rest.
FIRST_ROLLS_EVERY = 4
#: Orbital values tried after the reference's, as offsets from it (deg); those out of range are skipped.
ORBITAL_OFFSETS_DEG = (30.0, -30.0, 60.0, -60.0, 90.0, -90.0)
#: Source–target distances tried after the isocentric one, as fractions of the view's distance range.
DISTANCE_FRACTIONS = (0.5, 0.3, 0.7)
#: Exact checks per cell and pass, and in all, before the cell is declared unreachable (plan_view then asks the QP).
PASS_CHECKS = 4
MAX_CHECKS = 48
#: A pass's rounds of exact checks: each cell's candidates at these places of its order (1, 1, then 2).
_ROUNDS = ((0, 1), (1, 2), (2, PASS_CHECKS))


def applies(system) -> bool:
    """Whether ``system`` has a mount with the closed form of :mod:`carmkin.analytic.mount`."""
    if not system.mount.joints:
        return False
    try:
        mount_ik.solver_for(system)
    except UnsupportedMountError:
        return False
    return True


def _passes(system, q_ref) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The passes: ``(distance choice, orbital values (rad), roll samples (rad))``, each pass every pair of its
    orbital values and rolls; a distance choice is ``"iso"`` or a fraction of the range (as text)."""
    rolls = np.radians(np.arange(0.0, 360.0, ROLL_STEP_DEG))
    orbital = system.joint_names.index("orbital")
    ref = float(q_ref[orbital])
    lo, hi = system.lower[orbital], system.upper[orbital]
    others = [ref + math.radians(o) for o in ORBITAL_OFFSETS_DEG if lo <= ref + math.radians(o) <= hi]
    first = rolls[0::FIRST_ROLLS_EVERY]
    out = [("iso", np.array([ref]), first), ("iso", np.array([ref]), np.setdiff1d(rolls, first))]
    out += [("iso", np.array([value]), rolls) for value in others]
    out += [(str(f), np.array([ref] + others), rolls) for f in DISTANCE_FRACTIONS]
    return out


def _distances(system, choice: str, distance_range) -> np.ndarray:
    lo, hi = distance_range[:, 0], distance_range[:, 1]
    if choice == "iso":
        return np.clip(system.carm.orbital_offset, lo, hi)
    return lo + float(choice) * (hi - lo)


def _poses(targets, directions, s, x_axes) -> np.ndarray:
    """Source poses (N, 4, 4): origin ``t − s d``, z = d, x = ``x_axes`` (N, 3)."""
    T = np.zeros((len(targets), 4, 4))
    T[:, :3, 0] = x_axes
    T[:, :3, 1] = np.cross(directions, x_axes)
    T[:, :3, 2] = directions
    T[:, :3, 3] = targets - s[:, None] * directions
    T[:, 3, 3] = 1.0
    return T


def solve_cells(ctx, targets, directions, distance_range, x_axes=None) -> Outcome:
    """Search N cells (targets/directions (N, 3), distance_range (N, 2), ``x_axes`` (N, 3) a fixed roll's
    source x axis or NaN rows) with the mount's closed form: an :class:`~carmkin.views.search.Outcome` whose
    unreachable cells carry the reason of this search (``binding`` ``"contact"`` or ``"mount"``)."""
    system, world, margin = ctx.system, ctx.world, ctx.margin
    N, nq = len(targets), system.nq
    x_axes = np.full((N, 3), np.nan) if x_axes is None else np.asarray(x_axes, dtype=float)
    fixed = np.all(np.isfinite(x_axes), axis=1)
    e1, e2 = _roll_basis(directions)
    span = np.maximum(system.upper - system.lower, 1e-9)
    orbital = system.joint_names.index("orbital")
    reachable = np.zeros(N, dtype=bool)
    q_out = np.full((N, nq), np.nan)
    clearance = np.full(N, np.nan)
    checks = np.zeros(N, dtype=int)
    rank = np.full(N, -1)
    closest = np.full(N, np.inf)
    closest_pair = np.full(N, -1)
    contact_q = np.full((N, system.nq), np.nan)  # the configuration of each cell's closest contact
    any_branch = np.zeros(N, dtype=bool)
    for choice, orbitals, rolls in _passes(system, ctx.q_ref):
        open_ = np.flatnonzero(~reachable & (checks < MAX_CHECKS))
        if not len(open_):
            break
        # per open cell, its rolls (a fixed roll: its own, on the passes that start at roll 0) and orbital values
        cells, x = [], []
        free = open_[~fixed[open_]]
        if len(free):
            c, psi = np.repeat(free, len(rolls)), np.tile(rolls, len(free))
            cells.append(c)
            x.append(np.cos(psi)[:, None] * e1[c] + np.sin(psi)[:, None] * e2[c])
        held = open_[fixed[open_]]
        if len(held) and rolls[0] == 0.0:
            cells.append(held)
            x.append(x_axes[held])
        if not cells:
            continue
        cells, x = np.repeat(np.concatenate(cells), len(orbitals)), np.repeat(np.concatenate(x), len(orbitals), axis=0)
        s = _distances(system, choice, distance_range[cells])
        T = _poses(targets[cells], directions[cells], s, x)
        q_hold = np.repeat(ctx.q_ref[None], len(cells), axis=0)
        q_hold[:, orbital] = np.tile(orbitals, len(cells) // len(orbitals))
        out = mount_ik.branches(system, T, q_hold)
        any_branch[cells[out.reachable.any(axis=1)]] = True
        pose, branch = np.nonzero(out.within_limits)
        if not len(pose):
            continue
        cell, q = cells[pose], out.q[pose, branch]
        motion = np.abs((q - ctx.q_ref) / span).sum(axis=1)
        order = np.lexsort((motion, cell))
        cell, q = cell[order], q[order]
        starts = np.flatnonzero(np.r_[True, cell[1:] != cell[:-1]])
        position = np.arange(len(cell)) - np.repeat(starts, np.diff(np.r_[starts, len(cell)]))
        for lo, hi in _ROUNDS:
            rows = np.flatnonzero((position >= lo) & (position < hi))
            rows = rows[~reachable[cell[rows]] & (checks[cell[rows]] < MAX_CHECKS)]
            if not len(rows):
                continue
            distance, pair = world.nearest(q[rows], stop_below=margin)
            for k, dk, pk in zip(rows.tolist(), distance.tolist(), pair.tolist()):
                c = int(cell[k])
                if reachable[c] or checks[c] >= MAX_CHECKS:
                    continue
                checks[c] += 1
                if dk >= margin:
                    reachable[c], q_out[c], clearance[c], rank[c] = True, q[k], dk, checks[c] - 1
                elif dk < closest[c]:
                    closest[c], closest_pair[c], contact_q[c] = dk, pk, q[k]
    distance = np.full(N, np.nan)
    if reachable.any():
        F = system.fk(q_out[reachable])
        distance[reachable] = np.einsum("ij,ij->i", targets[reachable] - F[:, :3, 3], F[:, :3, 2])
    reason = np.full(N, None, dtype=object)
    binding = np.full(N, "", dtype=object)
    for c in np.flatnonzero(~reachable).tolist():
        if closest_pair[c] >= 0:
            a, b = world.pair_names(int(closest_pair[c]))
            reason[c] = (f"contact: {a} – {b} at {closest[c] * 1e3:.1f} mm (margin {margin * 1e3:.1f} mm), the "
                         "closest of the robot's sampled rolls, distances and orbital values")
            binding[c] = "contact"
        else:
            reason[c] = ("joint limits: the robot reaches no sampled roll, distance and orbital value of this beam "
                         "within its joint ranges" if any_branch[c] else
                         "out of reach: no sampled source pose of this beam is within the robot's arm")
            binding[c] = "mount"
    contact_q[binding != "contact"] = np.nan
    return Outcome(reachable, q_out, clearance, distance, reason, binding, rank, contact_q)


def with_mount(ctx, out: Outcome, targets, directions, distance_range, x_axes=None, workers: int = 1) -> Outcome:
    """``out`` (the search with the mount held, :func:`carmkin.views.search.solve_cells`) with the cells it left
    unreachable searched by :func:`solve_cells`: a cell either reaches keeps its answer (the held search's
    first), the others the reason of this search. ``out`` unchanged where the mount has no closed form. With
    ``workers`` > 1 and at least :data:`~carmkin.views.search.PARALLEL_MIN_CELLS` cells, in blocks over that
    many forked processes (cells are independent: the same answers)."""
    import dataclasses

    cells = np.flatnonzero(~out.reachable)
    if not len(cells) or not applies(ctx.system):
        return out
    x = np.full((len(cells), 3), np.nan) if x_axes is None else np.asarray(x_axes, dtype=float)[cells]
    args = (targets[cells], directions[cells], distance_range[cells], x)
    if workers > 1 and len(cells) >= search.PARALLEL_MIN_CELLS and "fork" in multiprocessing.get_all_start_methods():
        found = _parallel(ctx, args, workers)
    else:
        found = solve_cells(ctx, *args)
    fields = {f.name: getattr(out, f.name).copy() for f in dataclasses.fields(out)}
    for name in fields:
        fields[name][cells] = getattr(found, name)
    return type(out)(**fields)


#: What the forked workers of :func:`_parallel` search: set before the fork, read by :func:`_block`.
_FORKED = None


def _block(bounds) -> Outcome:
    ctx, args = _FORKED
    a, b = bounds
    return solve_cells(ctx, *(v[a:b] for v in args))


def _parallel(ctx, args, workers: int) -> Outcome:
    """:func:`solve_cells` in blocks of :data:`~carmkin.views.search.CHUNK` cells over ``workers`` forked
    processes that inherit the world (coal's shapes cannot be pickled)."""
    import dataclasses

    global _FORKED
    N, size = len(args[0]), search.CHUNK
    blocks = [(a, min(a + size, N)) for a in range(0, N, size)]
    _FORKED = (ctx, args)
    try:
        with multiprocessing.get_context("fork").Pool(min(workers, len(blocks))) as pool:
            parts = pool.map(_block, blocks, chunksize=1)
    finally:
        _FORKED = None
    return Outcome(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in dataclasses.fields(Outcome)))
