"""Every configuration that puts the beam through a target along a direction, in closed form, vectorised.

A view fixes the beam axis (target t, unit direction d from source to detector, table frame 0) and leaves
two things free: the roll about the beam and the source–target distance s. Parametrise the roll by the
wigwag θ2 (the joint with the narrowest range, sampled over it). With the other table joints held
(``E``, identity without a motorized table) the source pose is ``Tz(d0) · E · K · Tz(d1) · 2T_xray``, K the
C-arm base frame (:attr:`CArmSystem.carm_base_pose`). In the base frame rotated by −θ2 (five_dof's
derivation, checked against :meth:`CArmSystem.fk` in the tests)::

    U = Rz(−θ2) (EK)ᵀ d = (s4 c5, s5, c4 c5)                                    → θ5 = atan2(U_y, σ·hypot(U_x, U_z)),
                                                                                   θ4 = atan2(σ U_x, σ U_z)
    τ − s U − d0 G = (s4 g, M − L s5 + a2 c5, c4 g) + (0, d3, d1),   g = a1 − L c5 − a2 s5

with ``τ = Rz(−θ2) (EK)⁻¹ t`` and ``G = Rz(−θ2) (EK)ᵀ e_z``. The first row is one linear equation in
(s, d0): a line ``(s, d0) = P0 + λ v``; d3 and d1 are affine in λ. Intersecting the ranges of s, d0, d1,
d3 gives each (θ2, σ) family its interval of λ — the distance is searched exactly, not sampled, and the
singular poses of the pose IK (orbital axis ∥ wigwag) are not special here. Lengths in m, angles in rad.

A stand whose vertical and horizontal travels are locked (an angiography C-arm: min = max) leaves the line
one point, and only the wigwag values that put it there: for an isocentric C-arm (a1 = a2 = 0) the equation
reads, turned back by θ2, ``t − (s − L) z − d0 g = Rz(θ2) (0, M + d3, d1)`` in the base frame — the
isocentre on the circle of radius M + d3 at height d1 — a line in (s, d0) met with a circle:
:func:`locked_theta2` gives its (at most two) wigwag values in closed form, added to the samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from carmkin.model.params import JOINT_RANGE_TOLERANCE
from carmkin.transforms import wrap_angle

#: In the singular family, a residual of the first row below this (m) counts as satisfied.
PLANE_TOLERANCE = 1e-12
#: Ranges are met to half the joint-range tolerance, so that the rounding of the joints computed from λ
#: keeps them within :data:`~carmkin.model.params.JOINT_RANGE_TOLERANCE` (a value on a limit is in range).
INTERVAL_TOLERANCE = 0.5 * JOINT_RANGE_TOLERANCE
#: A fixed roll's wigwag values are refined until they bracket it this tightly (rad).
ROLL_ROOT_TOLERANCE = 1e-13
#: A family has a fixed roll where its source's x axis is this close to the wanted one (rad).
ROLL_TOLERANCE = 1e-9
#: Below this, |(U_x, G_x)| leaves the distance line undefined (the family is skipped; its neighbours in θ2
#: are not) and |cos θ5| makes θ4 a free roll (it keeps the reference value).
DEGENERATE = 1e-12


@dataclass(frozen=True)
class Families:
    """Per cell n, wigwag sample k and sign σ (``[n, k, σ]``): the joints that do not depend on the distance
    (θ2, θ4, θ5), the line ``(s, d0) = P0 + λ v`` and (d1, d3) affine in λ, and the λ interval
    [``lo``, ``hi``] meeting every range (empty: ``lo > hi``)."""

    theta: np.ndarray  # (N, K, 2, 3) θ2, θ4, θ5
    base: np.ndarray  # (N, K, 2, 4) s, d0, d1, d3 at λ = 0
    slope: np.ndarray  # (N, K, 2, 4) their derivatives in λ
    lo: np.ndarray  # (N, K, 2)
    hi: np.ndarray  # (N, K, 2)
    angle_excess: np.ndarray  # (N, K, 2) normalised excess of θ4, θ5 (0: in range)

    @property
    def feasible(self) -> np.ndarray:
        return (self.lo <= self.hi) & (self.angle_excess == 0)

    def at(self, lam: np.ndarray) -> np.ndarray:
        """(s, d0, d1, d3) (..., 4) at λ broadcast against the family axes."""
        return self.base + self.slope * lam[..., None]


def _interval(alpha, beta, low, high):
    """λ with ``low ≤ α λ + β ≤ high`` as (lo, hi); all or nothing where α ≈ 0."""
    tiny = np.abs(alpha) < DEGENERATE
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (low - beta) / np.where(tiny, 1.0, alpha)
        b = (high - beta) / np.where(tiny, 1.0, alpha)
    inside = (beta >= low) & (beta <= high)
    lo = np.where(tiny, np.where(inside, -np.inf, np.inf), np.minimum(a, b))
    hi = np.where(tiny, np.where(inside, np.inf, -np.inf), np.maximum(a, b))
    return lo, hi


def _representative(theta, lower, upper, reference):
    """θ or θ ∓ 2π: the one in [lower, upper] nearest ``reference``; NaN-free excess (rad) of the better."""
    alt = theta - 2 * np.pi * np.sign(theta)
    tol = INTERVAL_TOLERANCE

    def excess(x):
        return np.maximum(lower - tol - x, 0) + np.maximum(x - upper - tol, 0)

    e0, e1 = excess(theta), excess(alt)
    take_alt = (e1 < e0) | ((e1 == 0) & (e0 == 0) & (np.abs(alt - reference) < np.abs(theta - reference)))
    return np.where(take_alt, alt, theta), np.where(take_alt, e1, e0)


def families(system, targets, directions, theta2, frame, q_ref, distance_range) -> Families:
    """The families of cells ``targets``/``directions`` (N, 3) for wigwag samples ``theta2`` (K,) or
    (N, K), with the held table joints in ``frame`` (the pose (4, 4) of the C-arm base frame at d0 = 0 in
    the table frame, ``E·K``), ``q_ref`` (nq,) the reference for angle representatives, ``distance_range``
    (N, 2) the source–target distance interval (m)."""
    carm = system.carm
    L, M, a1, a2 = carm.source_to_orbital_axis, carm.arm_length, carm.a1, carm.a2
    lower, upper = system.lower, system.upper
    B, o = frame[:3, :3], frame[:3, 3]
    t1 = (targets - o) @ B  # (N, 3) in the base frame
    z1 = directions @ B
    g1 = B[2]  # e_z of the table frame in base axes (row 2 of B = Bᵀ e_z)
    th2 = np.broadcast_to(np.asarray(theta2, dtype=float), (len(targets), np.shape(theta2)[-1]))
    c2, s2 = np.cos(th2), np.sin(th2)

    def rot(v):  # Rz(−θ2) v for v (N, 3) or (3,) → (N, K, 3)
        v = np.broadcast_to(v, (len(targets), 3))[:, None, :]
        return np.stack((c2 * v[..., 0] + s2 * v[..., 1], -s2 * v[..., 0] + c2 * v[..., 1],
                         np.broadcast_to(v[..., 2], c2.shape)), axis=-1)

    tau, U, G = rot(t1), rot(z1), rot(g1)
    sigma = np.array([1.0, -1.0])
    h = np.hypot(U[..., 0], U[..., 2])[..., None]  # (N, K, 1)
    Ux, Uy, Uz = (U[..., i][..., None] for i in range(3))
    c5 = sigma * h
    s5 = np.broadcast_to(Uy, c5.shape)
    theta5 = np.arctan2(s5, c5)
    j4, j5 = system.nq - 2, system.nq - 1
    theta4 = np.where(h > DEGENERATE, np.arctan2(sigma * Ux, sigma * Uz), wrap_angle(q_ref[j4]))
    theta4, e4 = _representative(theta4, lower[j4], upper[j4], q_ref[j4])
    tol = INTERVAL_TOLERANCE
    e5 = np.maximum(lower[j5] - tol - theta5, 0) + np.maximum(theta5 - upper[j5] - tol, 0)
    s4, c4 = np.sin(theta4), np.cos(theta4)
    g = a1 - L * c5 - a2 * s5
    cx, cy, cz = s4 * g, M - L * s5 + a2 * c5, c4 * g
    tx, ty, tz = (np.broadcast_to(tau[..., i][..., None], c5.shape) for i in range(3))
    Gx, Gy, Gz = (np.broadcast_to(G[..., i][..., None], c5.shape) for i in range(3))
    Ux, Uy, Uz = (np.broadcast_to(u, c5.shape) for u in (Ux, Uy, Uz))
    n2 = Ux * Ux + Gx * Gx
    ok = n2 > DEGENERATE ** 2
    n2 = np.where(ok, n2, 1.0)
    r = tx - cx
    P0s, P0d = r * Ux / n2, r * Gx / n2
    norm = np.sqrt(n2)
    vs, vd = -Gx / norm, Ux / norm
    # The singular family (U_x = G_x = 0: beam and table axis in the arm's plane, e.g. θ4 = 0 with the wigwag
    # on the table's axis): the first row reads 0 = r. Where it holds, every (s, d0) does; d0 keeps the
    # reference value (within its range) and s runs along the line.
    plane = ~ok & (np.abs(r) <= PLANE_TOLERANCE)
    d0_ref = np.clip(q_ref[0], lower[0], upper[0])
    P0s, P0d = np.where(plane, 0.0, P0s), np.where(plane, d0_ref, P0d)
    vs, vd = np.where(plane, 1.0, vs), np.where(plane, 0.0, vd)
    ok = ok | plane
    # (s, d0, d1, d3) at λ = 0 and their slopes.
    base = np.stack((P0s, P0d, tz - cz - Uz * P0s - Gz * P0d, ty - cy - Uy * P0s - Gy * P0d), axis=-1)
    slope = np.stack((vs, vd, -(Uz * vs + Gz * vd), -(Uy * vs + Gy * vd)), axis=-1)
    j1, j3 = system.nq - 5, system.nq - 3
    lows = (distance_range[:, 0, None, None], lower[0] - tol, lower[j1] - tol, lower[j3] - tol)
    highs = (distance_range[:, 1, None, None], upper[0] + tol, upper[j1] + tol, upper[j3] + tol)
    lo, hi = np.full(c5.shape, -np.inf), np.full(c5.shape, np.inf)
    for i in range(4):
        a, b = _interval(slope[..., i], base[..., i], lows[i], highs[i])
        lo, hi = np.maximum(lo, a), np.minimum(hi, b)
    lo = np.where(ok, lo, np.inf)
    hi = np.where(ok, hi, -np.inf)
    span4 = max(upper[j4] - lower[j4], 1e-9)
    span5 = max(upper[j5] - lower[j5], 1e-9)
    theta = np.stack((np.broadcast_to(th2[..., None], c5.shape), theta4, theta5), axis=-1)
    return Families(theta, base, slope, lo, hi, e4 / span4 + e5 / span5)


def locked_theta2(system, targets, directions, frame) -> np.ndarray | None:
    """(N, 2) the wigwag values (rad, NaN where none) at which an isocentric C-arm whose vertical and horizontal
    joints are locked (range width within :data:`~carmkin.model.params.JOINT_RANGE_TOLERANCE`) puts the beam
    ``directions`` (N, 3) through ``targets`` (N, 3) (table frame, the held table joints in ``frame``, see
    :func:`families`); None for any other system (its line keeps a free λ: the samples find it). Where the
    beam and the table axis are both level in the base frame, or the isocentre's circle meets the line
    everywhere, the values are NaN: the samples cover that one-parameter family."""
    carm = system.carm
    if not (carm.is_isocentric and carm.vertical.locked and carm.horizontal.locked):
        return None
    d1, d3 = 0.5 * (carm.vertical.lower + carm.vertical.upper), 0.5 * (carm.horizontal.lower + carm.horizontal.upper)
    B, o = frame[:3, :3], frame[:3, 3]
    t, z, g = (targets - o) @ B, directions @ B, np.broadcast_to(B[2], targets.shape)
    # w(s', d0) = t − s' z − d0 g with w_z = d1: (s', d0) = P + μ v on that line, then |w_xy|² = (M + d3)².
    nz = np.stack((z[:, 2], g[:, 2]), axis=1)
    nn = np.einsum("ij,ij->i", nz, nz)
    ok = nn > DEGENERATE ** 2
    nn = np.where(ok, nn, 1.0)
    P = ((t[:, 2] - d1) / nn)[:, None] * nz
    v = np.stack((-nz[:, 1], nz[:, 0]), axis=1) / np.sqrt(nn)[:, None]
    w0 = t - P[:, :1] * z - P[:, 1:] * g
    wv = -(v[:, :1] * z + v[:, 1:] * g)
    a = np.einsum("ij,ij->i", wv[:, :2], wv[:, :2])
    b = 2.0 * np.einsum("ij,ij->i", w0[:, :2], wv[:, :2])
    c = np.einsum("ij,ij->i", w0[:, :2], w0[:, :2]) - (carm.arm_length + d3) ** 2
    ok &= a > DEGENERATE ** 2
    a = np.where(ok, a, 1.0)
    disc = b * b - 4.0 * a * c
    ok &= disc >= 0.0
    root = np.sqrt(np.where(ok, disc, 0.0))
    mu = (-b[:, None] + np.stack((root, -root), axis=1)) / (2.0 * a[:, None])  # (N, 2)
    w = w0[:, None, :] + mu[..., None] * wv[:, None, :]
    theta2 = np.arctan2(-w[..., 0], w[..., 1])
    wigwag = carm.wigwag
    theta2, excess = _representative(theta2, wigwag.lower, wigwag.upper, 0.5 * (wigwag.lower + wigwag.upper))
    return np.where(ok[:, None] & (excess == 0), theta2, np.nan)


def base_frame(system, q_hold) -> np.ndarray:
    """``E·G·K`` (4, 4): the C-arm base frame at d0 = 0 in the table frame with the table and mount joints of
    ``q_hold`` (nq,) held (``K`` alone without a motorized table or a mount)."""
    if system.nq == 6:
        return system.carm_base_pose
    q = np.array(q_hold, dtype=float)
    q[0] = 0.0
    return system.base_motion(q) @ system.carm_base_pose


def joints(system, fam: Families, index, lam, q_hold) -> np.ndarray:
    """Configurations (M, nq) of families ``index`` (tuple of (M,) index arrays into [n, k, σ]) at λ (M,),
    the table joints between d0 and d1 held at ``q_hold`` (nq,)."""
    theta = fam.theta[index]
    values = fam.base[index] + fam.slope[index] * lam[:, None]
    q = np.repeat(np.asarray(q_hold, dtype=float)[None], len(lam), axis=0)
    nq = system.nq
    q[:, 0] = values[:, 1]
    q[:, nq - 5] = values[:, 2]
    q[:, nq - 4] = theta[:, 0]
    q[:, nq - 3] = values[:, 3]
    q[:, nq - 2] = theta[:, 1]
    q[:, nq - 1] = theta[:, 2]
    locked = system.upper == system.lower  # a locked joint is its value, not that value ± round-off
    q[:, locked] = system.lower[locked]
    return q


def source_x_axes(theta2, theta4, frame) -> np.ndarray:
    """The source's x axis (..., 3) in the table frame for wigwag θ2 and angular θ4 (rad, arrays of one
    shape): (−c2 c4, −s2 c4, s4) in the C-arm base frame (:class:`~carmkin.model.kinematics.ClosedFormFK`),
    turned by the base frame's rotation ``frame[:3, :3]``."""
    c4 = np.cos(theta4)
    x = np.stack((-np.cos(theta2) * c4, -np.sin(theta2) * c4, np.sin(theta4)), axis=-1)
    return x @ np.asarray(frame)[:3, :3].T


def roll_error(directions, x_axes, theta2, frame) -> np.ndarray:
    """(N, K, 2) signed angle (rad) about each beam from the wanted x axis ``x_axes`` (N, 3) (unit, ⊥ the
    beam) to the source's x axis of the family (θ2 ``theta2`` (N, K), sign σ); NaN where θ4 is a free roll."""
    B = np.asarray(frame)[:3, :3]
    z1 = directions @ B
    c2, s2 = np.cos(theta2), np.sin(theta2)
    Ux = c2 * z1[:, :1] + s2 * z1[:, 1:2]
    Uz = np.broadcast_to(z1[:, 2:3], Ux.shape)
    sigma = np.array([1.0, -1.0])
    theta4 = np.arctan2(sigma * Ux[..., None], sigma * Uz[..., None])
    degenerate = (np.hypot(Ux, Uz) <= DEGENERATE)[..., None]
    x = source_x_axes(np.broadcast_to(theta2[..., None], theta4.shape), theta4, frame)
    wanted = x_axes[:, None, None, :]
    sine = np.einsum("nksi,ni->nks", np.cross(wanted, x), directions)
    cosine = np.einsum("nksi,nksi->nks", np.broadcast_to(wanted, x.shape), x)
    return np.where(degenerate, np.nan, np.arctan2(sine, cosine))


def theta2_for_roll(directions, x_axes, theta2, frame) -> np.ndarray:
    """(N, R) wigwag values (rad, NaN-padded) at which a family of the beam ``directions`` (N, 3) has the
    source's x axis along ``x_axes`` (N, 3): sign changes of :func:`roll_error` over the samples ``theta2``
    (K,), refined by bisection to :data:`ROLL_ROOT_TOLERANCE` (vectorised over every bracket)."""
    N = len(directions)
    grid = np.broadcast_to(np.asarray(theta2, dtype=float), (N, len(theta2)))
    e = roll_error(directions, x_axes, grid, frame)  # (N, K, 2)
    with np.errstate(invalid="ignore"):
        exact = np.abs(e) <= ROLL_ROOT_TOLERANCE
        # A zero crossing, not the ±π wrap: the two ends are within π of each other across zero.
        crossing = (np.sign(e[:, :-1]) * np.sign(e[:, 1:]) < 0) & (np.abs(e[:, :-1]) + np.abs(e[:, 1:]) < np.pi)
    n, k, sigma = np.nonzero(crossing)
    a, b = grid[n, k].copy(), grid[n, k + 1].copy()
    ea = e[n, k, sigma]
    for _ in range(200):
        if not len(a) or np.max(b - a) <= ROLL_ROOT_TOLERANCE:
            break
        m = 0.5 * (a + b)
        em = roll_error(directions[n], x_axes[n], m[:, None], frame)[np.arange(len(m)), 0, sigma]
        left = np.sign(em) == np.sign(ea)
        a, ea = np.where(left, m, a), np.where(left, em, ea)
        b = np.where(left, b, m)
    ne, ke, _ = np.nonzero(exact)
    cells = np.r_[n, ne]
    values = np.r_[0.5 * (a + b), grid[ne, ke]]
    out = np.full((N, max(1, int(np.bincount(cells, minlength=N).max()) if len(cells) else 1)), np.nan)
    order = np.lexsort((values, cells))
    cells, values = cells[order], values[order]
    slot = np.arange(len(cells)) - np.searchsorted(cells, cells, "left")
    out[cells, slot] = values
    return out


def with_roll(fam: Families, directions, x_axes, frame, rows) -> Families:
    """``fam`` with only the families of cells ``rows`` (bool (N,)) whose source x axis is along ``x_axes``
    (to :data:`ROLL_TOLERANCE`) left feasible there (the others' λ intervals emptied)."""
    import dataclasses

    idx = np.flatnonzero(rows)
    e = roll_error(directions[idx], x_axes[idx], fam.theta[idx, :, 0, 0], frame)
    off = np.zeros(fam.lo.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        off[idx] = ~(np.abs(e) <= ROLL_TOLERANCE)
    return dataclasses.replace(fam, lo=np.where(off, np.inf, fam.lo), hi=np.where(off, -np.inf, fam.hi))
