"""Between the samples: a local maximisation of the clearance around the best candidates of a contact cell.

The sampled search (:mod:`carmkin.views.search`) checks configurations at the wigwag samples θ2 (every
:data:`~carmkin.views.search.THETA2_STEP`) and at a few distances of each family's exact interval. A valid
configuration can lie between them (issue 31: 2 of 153 views called unreachable had one). So a cell that
every sampled candidate leaves in contact, and whose best exact clearance is within :data:`WINDOW` of the
margin, is searched continuously before it is called unreachable. From its :data:`SEEDS` best candidates
(distinct families) an ascent over (θ2, u) — θ2 the wigwag within its range (held where the roll is fixed),
u ∈ [0, 1] the place of the distance in the family's exact interval at that θ2, recomputed in closed form at
every step (:func:`carmkin.views.closed_form.families`), so every point is within the joint ranges — moves
to the best of its four neighbours while the exact clearance (:meth:`carmkin.world.World.clearance`, exact
below the margin) grows and halves its steps when none does. It ends when a point keeps the margin (the cell
is reachable there, with its exact clearance), when the steps fall below :data:`MIN_STEP_THETA2` and
:data:`MIN_STEP_U`, or when what the remaining steps can move the machine (:data:`LEVER`) cannot close the
gap to the margin. All seeds of all cells move together (one clearance call a step).

What it guarantees, and what it does not: a valid configuration reached by an ascent from the best
sampled candidates is found; that none lies elsewhere is not proved but checked — by the brute force of
``tests/views/bruteforce.py`` (the pose IK on a grid 5× finer in roll and 2 mm in distance, the singular
family over its wigwag, then its own local maximisation; none of this module or the search):
``python benchmarks/bruteforce_views.py`` (numbers in docs/views.md). Lengths in m, angles in rad.
"""

from __future__ import annotations

import math

import numpy as np

from . import closed_form

#: Cells whose best exact clearance is this far (m) or more below the margin are not polished. Measured on
#: the 73 contact cells of the 5° map of the table origin (Iso-C 3D, parametric patient): where the brute
#: force's best clearance is within 40 mm of the margin, it exceeds the best sampled candidate's by at most
#: 12.7 mm; a cell with a valid configuration sits within that of the margin, 30 mm leaves twice the room.
WINDOW = 0.03
#: Best candidates (of distinct families) polished per cell.
SEEDS = 2
#: First steps of the ascent: half a wigwag sample and a sixteenth of the distance interval (half the
#: spacing of :data:`~carmkin.views.search.DISTANCE_CHOICES`).
STEP_THETA2 = math.radians(0.25)
STEP_U = 1.0 / 16.0
#: The ascent of a seed stops when its steps are below these (rad, fraction of the interval).
MIN_STEP_THETA2 = math.radians(0.02)
MIN_STEP_U = 1.0 / 256.0
#: A seed whose clearance is further below the margin than its remaining steps can plausibly move the machine,
#: ``2 (LEVER·Δθ2 + Δs)`` (the steps halve, so the rest of an ascent sums to less than twice the current
#: ones; θ2 swings the C-arc about the wigwag axis with about this lever (m) on the presets, s moves it along
#: the beam), is dropped. A stopping rule for the ascent, not a bound on the clearance.
LEVER = 1.5
#: Steps of the ascent, at most.
MAX_STEPS = 40


def seeds(cells, distances, q, system, limit=SEEDS):
    """The rows of touching candidates (``cells`` (M,), exact ``distances`` (M,), configurations ``q`` (M, nq))
    to polish: per cell its ``limit`` best of distinct families (wigwag value, sign of cos θ5, held joints)."""
    if not len(cells):
        return np.zeros(0, dtype=int)
    nq = system.nq
    key = np.round(np.c_[cells, q[:, nq - 4], np.sign(np.cos(q[:, nq - 1])), q[:, 1:nq - 5]], 12)
    # The best candidate of each (cell, family), then the best `limit` families of each cell.
    order = np.lexsort((-distances, *key.T[::-1]))
    key = key[order]
    first = np.r_[True, np.any(key[1:] != key[:-1], axis=1)]
    rows = order[first]
    rows = rows[np.lexsort((-distances[rows], cells[rows]))]
    c = cells[rows]
    start = np.r_[True, c[1:] != c[:-1]]
    place = np.arange(len(c)) - np.maximum.accumulate(np.where(start, np.arange(len(c)), 0))
    return rows[place < limit]


def polish(ctx, cells, targets, directions, distance_range, fixed, q0, distance0):
    """Ascend from configurations ``q0`` (M, nq) (exact clearance ``distance0`` (M,) below the margin) of
    ``cells`` (M,) with ``targets``/``directions`` (M, 3), ``distance_range`` (M, 2), ``fixed`` (M,) bool (a
    fixed roll: θ2 held); a cell's seeds stop when one of them keeps the margin. Returns (found (M,) bool,
    q (M, nq), clearance (M,) m: exact where found)."""
    system, world, margin = ctx.system, ctx.world, ctx.margin
    nq, M = system.nq, len(q0)
    j2, j5 = nq - 4, nq - 1
    lo2, hi2 = system.lower[j2], system.upper[j2]
    theta2 = q0[:, j2].copy()
    sigma = np.where(np.cos(q0[:, j5]) >= 0, 0, 1)
    hold = q0.copy()
    frames = {}
    for m in range(M):
        key = hold[m, 1:nq - 5].tobytes()
        if key not in frames:
            frames[key] = (closed_form.base_frame(system, hold[m]), [])
        frames[key][1].append(m)
    groups = [(frame, np.array(rows)) for frame, rows in frames.values()]

    def evaluate(rows, th, u):
        """Configurations (len(rows), nq) at wigwag th and fraction u of the distance interval; NaN rows where
        the family is empty there."""
        q = np.full((len(rows), nq), np.nan)
        for frame, members in groups:
            pick = np.flatnonzero(np.isin(rows, members))
            if not len(pick):
                continue
            r = rows[pick]
            with np.errstate(invalid="ignore"):
                fam = closed_form.families(system, targets[r], directions[r], th[pick, None], frame, ctx.q_ref,
                                           distance_range[r])
            idx = (np.arange(len(r)), np.zeros(len(r), dtype=int), sigma[r])
            lo, hi = fam.lo[idx], fam.hi[idx]
            ok = fam.feasible[idx] & np.isfinite(lo) & np.isfinite(hi)
            lo, hi = np.where(ok, lo, 0.0), np.where(ok, hi, 0.0)
            lam = lo + u[pick] * (hi - lo)
            values = closed_form.joints(system, fam, idx, lam, hold[r[0]])
            values[~ok] = np.nan
            q[pick] = values
        return q

    # The seeds' place u in their family's interval.
    base = evaluate(np.arange(M), theta2, np.zeros(M))
    top = evaluate(np.arange(M), theta2, np.ones(M))
    s0, s1 = _distance(system, base, targets, directions), _distance(system, top, targets, directions)
    s = _distance(system, q0, targets, directions)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.clip(np.where(np.abs(s1 - s0) > 0, (s - s0) / (s1 - s0), 0.5), 0.0, 1.0)
    u = np.where(np.isfinite(u), u, 0.5)
    span_s = np.where(np.isfinite(s1 - s0), np.abs(s1 - s0), distance_range[:, 1] - distance_range[:, 0])
    best = distance0.astype(float).copy()
    q = q0.copy()
    step_t = np.where(fixed, 0.0, STEP_THETA2)
    step_u = np.full(M, STEP_U)
    found = np.zeros(M, dtype=bool)
    moves = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]], dtype=float)
    for _ in range(MAX_STEPS):
        live = (step_t >= MIN_STEP_THETA2) | (step_u >= MIN_STEP_U)
        # What the rest of an ascent can still gain: its steps halve, so at most twice the current ones.
        live &= best + 2 * (LEVER * step_t + span_s * step_u) >= margin
        active = np.flatnonzero(live & ~np.isin(cells, cells[found]))
        if not len(active):
            break
        rows = np.repeat(active, len(moves))
        d = np.tile(moves, (len(active), 1))
        th = np.clip(theta2[rows] + d[:, 0] * step_t[rows], lo2, hi2)
        uu = np.clip(u[rows] + d[:, 1] * step_u[rows], 0.0, 1.0)
        trial = evaluate(rows, th, uu)
        ok = np.all(np.isfinite(trial), axis=1)
        c = np.full(len(rows), -np.inf)
        if ok.any():
            c[ok] = world.clearance(trial[ok], exact_below=margin)
        c = c.reshape(len(active), len(moves))
        pick = np.argmax(c, axis=1)
        gain = c[np.arange(len(active)), pick]
        better = gain > best[active]
        win = active[better]
        chosen = np.flatnonzero(better) * len(moves) + pick[better]
        theta2[win], u[win], q[win], best[win] = th[chosen], uu[chosen], trial[chosen], gain[better]
        found[win] = best[win] >= margin
        stay = active[~better]
        step_t[stay] *= 0.5
        step_u[stay] *= 0.5
    if found.any():
        best[found] = world.clearance(q[found])
    return found, q, best


def _distance(system, q, targets, directions):
    """Source–target distance (M,) of configurations q (M, nq) (NaN rows give NaN)."""
    out = np.full(len(q), np.nan)
    ok = np.all(np.isfinite(q), axis=1)
    if ok.any():
        T = system.fk(q[ok])
        out[ok] = np.einsum("ij,ij->i", targets[ok] - T[:, :3, 3], T[:, :3, 2])
    return out

