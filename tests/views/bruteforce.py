"""A brute-force oracle for "this view is unreachable": independent of :mod:`carmkin.views.search`.

A view (target t, unit beam direction d, table frame 0, m) leaves the source–target distance s and the roll
ρ about the beam free. The oracle sweeps them on a grid much finer than the search's (ρ every
:data:`ROLL_STEP_DEG` over the whole turn, s every :data:`DISTANCE_STEP` over [0, SID]), solves every source
pose with the pose IK (:func:`carmkin.analytic_ik.solve_batch`, both branches), keeps the solutions within the
joint ranges that reach the pose, and asks the collision world (:meth:`carmkin.world.World.nearest`) whether
one keeps the margin. Where none does, it maximises the clearance locally (Nelder–Mead over (s, ρ), the IK
branch of the seed) from the :data:`SEEDS` best grid points: a valid configuration between grid points is
found too. Nothing of the views' closed form, sampling or ranking is used.

A motorized table is held where the search holds it (mid-range); the oracle needs that hold to be the
identity motion (true of the preset: every table joint's range is symmetric about 0) and then solves the
six-joint chain of the same C-arm and table top, checking the FK of the full system against the pose.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import minimize

from carmkin import analytic_ik

#: Roll step of the grid (deg): five times finer than the search's wigwag samples.
ROLL_STEP_DEG = 0.1
#: Distance step of the grid (m).
DISTANCE_STEP = 0.002
#: Roll step (deg) of the first pass that finds the rolls with in-range solutions (the grid is fine within
#: 1.5 of these steps of them; all rolls where the first pass finds none).
COARSE_ROLL_DEG = 1.0
#: Where that pass finds none, every roll of the grid is tried at this distance step (m) before the view is
#: taken to have no in-range solution but on the singular family.
COARSE_DISTANCE = 0.01
#: Grid points (best exact clearance first, at least this far apart in roll) each maximised locally.
SEEDS = 6
#: Grid solutions whose exact clearance ranks the seeds, at most (evenly strided).
EXACT_POINTS = 4000
#: Grid solutions checked together.
CHUNK = 2048
#: Clearance evaluations of one local maximisation, at most.
MAX_EVALUATIONS = 200
#: Seeds closer than this in roll (rad) count as one.
SEED_SEPARATION = np.radians(1.0)
#: A beam within this (cos) of ⊥ the wigwag axis gets the singular family's rolls in the grid.
FAMILY_ALIGNMENT = 1e-9
#: The FK of a held motorized system must give the solved pose to this (m, rad).
HOLD_TOLERANCE = 1e-9


def six_joint(system):
    """``(system6, expand)``: the six-joint chain the pose IK solves and ``expand(q6 (N, 6)) -> q (N, nq)``
    (a motorized table held at mid-range, which must be the identity motion)."""
    k = len(system.table.joints)
    if not k:
        return system, lambda q6: q6
    hold = 0.5 * (system.lower + system.upper)[1:1 + k]
    assert np.allclose(system.table_motion(hold), np.eye(4), atol=HOLD_TOLERANCE), "held table is not the identity"
    system6 = system.replace(table=dataclasses.replace(system.table, joints=()))

    def expand(q6):
        return np.concatenate((q6[:, :1], np.tile(hold, (len(q6), 1)), q6[:, 1:]), axis=1)

    return system6, expand


def _basis(direction):
    """(e1, e2) ⊥ the beam, (e1, e2, d) right-handed: the roll ρ is measured from e1."""
    helper = np.eye(3)[int(np.argmin(np.abs(direction)))]
    e1 = np.cross(direction, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(direction, e1)


def _poses(target, direction, s, rho):
    """Source poses (M, 4, 4): z along the beam, x at roll ρ (M,) from e1, at distance s (M,)."""
    e1, e2 = _basis(direction)
    x = np.cos(rho)[:, None] * e1 + np.sin(rho)[:, None] * e2
    T = np.zeros((len(s), 4, 4))
    T[:, :3, 0], T[:, :3, 1], T[:, :3, 2] = x, np.cross(direction, x), direction
    T[:, :3, 3] = target - s[:, None] * direction
    T[:, 3, 3] = 1.0
    return T


def family_rolls(system, direction) -> np.ndarray:
    """The rolls (rad) of the singular family (orbital axis ∥ wigwag axis: the source's x axis along ±the
    wigwag axis, which must then be ⊥ the beam); empty where the beam is not ⊥ the wigwag axis."""
    axis = system.carm_base_pose[:3, 2]
    if abs(axis @ direction) > FAMILY_ALIGNMENT:
        return np.zeros(0)
    e1, e2 = _basis(direction)
    rho = np.arctan2(axis @ e2, axis @ e1)
    return np.array([rho, rho + np.pi]) % (2 * np.pi)


def _solve(system6, expand, target, direction, s, rho, theta2=None):
    """Within-range solutions: (q (M', nq), (s, ρ, branch, θ2 reference) (M', 4)). A pose on the singular
    family (only θ2 ± θ5 fixed, θ2 taken from ``q_current``) is solved again for every ``theta2`` (rad) as the
    reference (NaN reference: a regular pose); ``theta2`` None: the reference 0 only."""
    T = _poses(target, direction, s, rho)
    r = analytic_ik.solve_batch(system6, T)
    qs, wheres = [], []

    def keep(r, s, rho, ref):
        ok = r.within_limits & r.reached & np.all(np.isfinite(r.solutions), axis=2)  # (2, M)
        branch, index = np.nonzero(ok)
        qs.append(expand(r.solutions[branch, index]))
        wheres.append(np.stack((s[index], rho[index], branch, np.broadcast_to(ref, s.shape)[index]), axis=1))

    on_family = r.singular[:, 1]
    if theta2 is None or not on_family.any():
        keep(r, s, rho, np.nan)
    else:
        regular = ~on_family
        keep(analytic_ik.solve_batch(system6, T[regular]), s[regular], rho[regular], np.nan)
        count = int(on_family.sum())
        ps, pr = np.tile(s[on_family], len(theta2)), np.tile(rho[on_family], len(theta2))
        q_current = np.zeros((count * len(theta2), 6))
        q_current[:, 2] = np.repeat(theta2, count)
        keep(analytic_ik.solve_batch(system6, np.tile(T[on_family], (len(theta2), 1, 1)), q_current), ps, pr,
             q_current[:, 2])
    return np.concatenate(qs), np.concatenate(wheres)


@dataclasses.dataclass
class Verdict:
    """``q`` (nq,) a configuration keeping the margin (None: none found), ``clearance`` the best exact
    clearance seen (m; −inf without any in-range solution), ``solutions`` in-range grid solutions."""

    q: np.ndarray | None
    clearance: float
    solutions: int


def brute(system, world, target, direction, margin, roll_step_deg=ROLL_STEP_DEG, distance_step=DISTANCE_STEP,
          seeds=SEEDS) -> Verdict:
    """Is there a configuration of ``system`` putting the beam through ``target`` along ``direction`` within the
    joint ranges with clearance ≥ ``margin`` (m) in ``world``? See the module docstring."""
    system6, expand = six_joint(system)
    target, direction = np.asarray(target, float), np.asarray(direction, float)
    sid = system.carm.source_to_detector
    s_values = np.linspace(0.0, sid, int(np.ceil(sid / distance_step)) + 1)
    # The rolls with any in-range solution, every COARSE_ROLL_DEG; then every roll_step_deg about them.
    coarse = np.radians(np.arange(0.0, 360.0, COARSE_ROLL_DEG))
    S, R = np.meshgrid(s_values, coarse, indexing="ij")
    _, found = _solve(system6, expand, target, direction, S.ravel(), R.ravel())
    fine = np.radians(np.arange(0.0, 360.0, roll_step_deg))
    if not len(found):  # every roll, with a coarser distance step: a set narrow in both is not looked for
        S, R = np.meshgrid(np.linspace(0.0, sid, int(np.ceil(sid / COARSE_DISTANCE)) + 1), fine, indexing="ij")
        _, found = _solve(system6, expand, target, direction, S.ravel(), R.ravel())
    if not len(found):
        fine = fine[:0]
    else:
        gap = np.abs((fine[:, None] - np.unique(found[:, 1])[None] + np.pi) % (2 * np.pi) - np.pi)
        fine = fine[gap.min(axis=1) <= np.radians(1.5 * COARSE_ROLL_DEG)]
    fine = np.r_[fine, family_rolls(system, direction)]
    S, R = np.meshgrid(s_values, fine, indexing="ij")
    theta2 = np.radians(np.arange(np.degrees(system6.lower[2]), np.degrees(system6.upper[2]) + 1e-9, roll_step_deg))
    q, where = _solve(system6, expand, target, direction, S.ravel(), R.ravel(), theta2)
    if not len(q):
        return Verdict(None, -np.inf, 0)
    T = system.fk(q)
    assert np.allclose(T[:, :3, 2], direction, atol=1e-9)
    for a in range(0, len(q), CHUNK):  # stops at the first chunk with a valid configuration
        distance, _ = world.nearest(q[a:a + CHUNK], exact_below=margin, stop_below=margin)
        good = np.flatnonzero(distance >= margin)
        if len(good):
            return Verdict(q[a + good[0]], float(distance[good[0]]), len(q))
    # Exact clearances (below the margin) on at most EXACT_POINTS grid solutions, to seed the local maximisation.
    sub = np.arange(0, len(q), max(1, len(q) // EXACT_POINTS))
    exact = world.clearance(q[sub], exact_below=margin)
    best = float(exact.max())
    # A seed's angle: its roll, or on the singular family its wigwag (the roll is fixed there).
    angle = np.where(np.isnan(where[sub, 3]), where[sub, 1], where[sub, 3])
    picked = []
    for i in np.argsort(-exact):
        if all(abs((angle[i] - angle[j] + np.pi) % (2 * np.pi) - np.pi) > SEED_SEPARATION for j in picked):
            picked.append(i)
        if len(picked) == seeds:
            break
    for i in picked:
        found = _maximise(system6, expand, world, target, direction, margin, where[sub[i]], sid)
        if found is not None:
            q_best, c = found
            best = max(best, c)
            if c >= margin:
                return Verdict(q_best, c, len(q))
    return Verdict(None, best, len(q))


class _Found(Exception):
    """The local maximisation met the margin."""


def _maximise(system6, expand, world, target, direction, margin, seed, sid):
    """Nelder–Mead on −clearance from the grid solution ``seed`` (s, ρ, branch, θ2 reference) on its IK
    branch: over (s, ρ), or over (s, θ2) at its roll on the singular family; out of range or off [0, SID]:
    the excess as a penalty. Returns (q, exact clearance) of the best point seen, or None."""
    s0, rho0, branch, ref = seed
    branch, family = int(branch), not np.isnan(ref)
    best = [None, -np.inf]

    def cost(x):
        s, a = float(x[0]), float(x[1])
        if not 0.0 <= s <= sid:
            return 1.0 + abs(s - np.clip(s, 0.0, sid))
        rho, q_current = (rho0, np.array([0, 0, a, 0, 0, 0.0])) if family else (a, np.zeros(6))
        r = analytic_ik.solve_batch(system6, _poses(target, direction, np.array([s]), np.array([rho])), q_current)
        excess = r.excess[branch, 0]
        if not (r.within_limits[branch, 0] and r.reached[branch, 0]):
            return 1.0 + float(np.abs(excess).sum()) if np.all(np.isfinite(excess)) else 2.0
        q = expand(r.solutions[branch, :1])
        c = float(world.clearance(q, exact_below=margin)[0])
        if c > best[1]:
            best[0], best[1] = q[0], c
        if c >= margin:
            raise _Found
        return -c

    a0 = ref if family else rho0
    try:
        minimize(cost, [s0, a0], method="Nelder-Mead",
                 options=dict(initial_simplex=[[s0, a0], [s0 + 0.01, a0], [s0, a0 + np.radians(0.3)]],
                              xatol=1e-5, fatol=1e-6, maxfev=MAX_EVALUATIONS))
    except _Found:
        pass
    return None if best[0] is None else (best[0], best[1])
