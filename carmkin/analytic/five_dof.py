"""Inverse kinematics of the 5-DOF C-arm for an X-ray source position and principal axis (§4.6.1).

After Matthäus et al. [130] as used in the simulation study of §4.6.1: the table is fixed and the roll
about the principal axis is free, so a target is the source position ``p`` (m) and the unit principal
axis ``z`` (Z of ``xray_source``), both in the **C-arm base frame**: frame 1 of the 5-DOF model, Z along
the vertical axis, origin where the vertical joint is zero (the chain ``kinematics.carm_rows(carm)``,
``kinematics.forward(rows, kinematics.xray_in_flange(carm), q5)``). Joints ``q5 = [d1, θ2, d3, θ4, θ5]``
(m, rad, m, rad, rad).

Derivation (from the chain, see :class:`carmkin.model.kinematics.ClosedFormFK`; L = l2 + a1, M = l1 − a2).
Rotating by −θ2 about Z, with ``P = Rz(−θ2) p`` and ``U = Rz(−θ2) z = (s4 c5, s5, c4 c5)``::

    P_x     = s4 g            g = a1 − L c5 − a2 s5
    P_y     = M + d3 − L s5 + a2 c5
    p_z − d1 = c4 g

so θ5 = atan2(U_y, σ·hypot(U_x, z_z)) with σ = ±1 the sign of cos θ5, θ4 = atan2(σ U_x, σ z_z), and d1, d3
follow linearly. θ2 is the only hard unknown; eliminating ``g`` between the x equation and the direction
gives one scalar equation in θ2::

    f_σ(θ2) = (P_x + L U_x) · σ·hypot(U_x, z_z) − U_x (a1 − a2 U_y) = 0.

* Isocentric C-arm (a1 = a2 = 0): ``f = 0`` ⇔ ``P_x + L U_x = 0``, i.e. the isocentre ``c = p + L z`` lies on
  the arm: ``θ2 = atan2(−c_x, c_y)`` (arm forward, M + d3 = +|c_xy|) or that + π (M + d3 = −|c_xy|),
  ``d1 = c_z``. Four branches: 2 (arm) × 2 (σ).
* General a1, a2: squaring ``f_σ = 0`` gives ``F(θ2) = A²(U_x² + z_z²) − U_x² C² = 0`` (A = P_x + L U_x,
  C = a1 − a2 U_y), a trigonometric polynomial of degree 4, i.e. a degree-8 polynomial in
  ``t = tan((θ2 − φ)/2)``. Its real roots, Newton-polished on the unsquared ``f_σ`` for both signs σ, give
  every solution (at most 8); each is verified by FK and duplicates are dropped.

Singular targets: ``cos θ5 = 0`` (principal axis along the angular axis Z4, whose rotation then only rolls
the image): θ4 is free in the isocentric case and set to 0; otherwise ``s4 = P_x / g`` gives two θ4 (one per σ
slot). Angles are returned wrapped to (−π, π].

Selection rule (the "unique solution" of §4.6.1, our reading): among the FK-verified branches take the one
with the X-ray beam in front of the column (``M + d3 > 0``) and ``cos θ5 ≥ 0`` (|θ5| ≤ 90°); if several (general
a1, a2) or none qualify, the least total normalized range excess, then the smallest normalized distance to
the middle of the ranges. For isocentric C-arms exactly one branch qualifies (two coincide when cos θ5 = 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from carmkin.errors import (
    CarmkinError,
    FiveDofTargetError,  # noqa: F401 (defined there, raised here)
)
from carmkin.model.kinematics import ClosedFormFK
from carmkin.model.params import PRISMATIC, CArmGeometry, TableSetup
from carmkin.transforms import wrap_angle

#: Targets with ``hypot(U_x, z_z)`` below this are treated as the cos θ5 = 0 singularity.
SINGULAR = 1e-12
#: Default FK residual (m for position, rad-like for the unit axis) below which a branch is accepted.
TOLERANCE = 1e-9
_NEWTON_STEPS = 10
_IMAG_TOLERANCE = 1e-4
#: Targets per batch of the polynomial solver (its de-duplication compares 16 x 16 branches per target).
CHUNK = 2048


@dataclass(frozen=True)
class FiveDofSolutions:
    """All 5-DOF branches of N targets.

    Attributes:
        q: (N, B, 5) joint values [d1, θ2, d3, θ4, θ5] (m, rad) of every branch; NaN in empty slots.
        valid: (N, B) True where the branch exists and its FK residual is ≤ the tolerance.
        residual: (N, B) FK residual: max(|p_fk − p| (m), |z_fk − z|); inf in empty slots.
        chosen: (N,) index of the selected branch (module docstring), −1 when no branch is valid.
    """

    q: np.ndarray
    valid: np.ndarray
    residual: np.ndarray
    chosen: np.ndarray

    @property
    def selected(self) -> np.ndarray:
        """(N, 5) joint values of the chosen branch, NaN rows where there is none."""
        rows = np.arange(len(self.chosen))
        out = self.q[rows, np.maximum(self.chosen, 0)].copy()
        out[self.chosen < 0] = np.nan
        return out


def check_targets(position, direction) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(p, z)`` as (N, 3) float arrays; ``direction`` must be unit length within 1e-6."""
    try:
        p = np.atleast_2d(np.asarray(position, dtype=float))
        z = np.atleast_2d(np.asarray(direction, dtype=float))
    except (TypeError, ValueError) as exc:
        raise FiveDofTargetError(f"position and direction must be numeric: {exc}") from exc
    for name, v in (("position", p), ("direction", z)):
        if v.ndim != 2 or v.shape[1] != 3:
            raise FiveDofTargetError(f"{name} must have shape (3,) or (N, 3), got {np.shape(v)}")
        if not np.all(np.isfinite(v)):
            raise FiveDofTargetError(f"{name} contains NaN or Inf")
    if p.shape != z.shape:
        raise FiveDofTargetError(f"position {p.shape} and direction {z.shape} must have the same shape")
    norm = np.linalg.norm(z, axis=1)
    if np.any(np.abs(norm - 1.0) > 1e-6):
        raise FiveDofTargetError(f"direction must be a unit vector, got norm {norm[np.argmax(np.abs(norm - 1))]:.6g}")
    return p, z / norm[:, None]


def targets_from_poses(T_base_xray) -> tuple[np.ndarray, np.ndarray]:
    """``(p, z)`` (N, 3) of source poses (4, 4) or (N, 4, 4) in the C-arm base frame: origin and Z column."""
    T = np.asarray(T_base_xray, dtype=float).reshape(-1, 4, 4)
    return T[:, :3, 3].copy(), T[:, :3, 2].copy()


def forward(carm: CArmGeometry, q5) -> tuple[np.ndarray, np.ndarray]:
    """Source position and principal axis (N, 3) in the C-arm base frame for joints q5 (5,) or (N, 5)."""
    q5 = np.atleast_2d(np.asarray(q5, dtype=float))
    q6 = np.concatenate((np.zeros((len(q5), 1)), q5), axis=1)
    T = _base_fk(carm).poses(q6)
    return T[:, :3, 3], T[:, :3, 2]


def _base_fk(carm: CArmGeometry) -> ClosedFormFK:
    # With a zero table setup the 6-DOF chain's first two rows are identity at d0 = d1 = 0: frame 0 is the
    # C-arm base frame and the table joint is inert (d0 = 0).
    return ClosedFormFK(carm, TableSetup(0.0, 0.0, 0.0, 0.0, 0.0, 0.0))


def residual(carm: CArmGeometry, q: np.ndarray, p: np.ndarray, z: np.ndarray) -> np.ndarray:
    """FK residual of joint values q (..., 5) against targets p, z broadcastable to (..., 3); NaN q → inf."""
    shape = q.shape[:-1]
    flat = q.reshape(-1, 5)
    ok = np.all(np.isfinite(flat), axis=1)
    out = np.full(flat.shape[0], np.inf)
    if ok.any():
        p_fk, z_fk = forward(carm, flat[ok])
        pb = np.broadcast_to(p, shape + (3,)).reshape(-1, 3)[ok]
        zb = np.broadcast_to(z, shape + (3,)).reshape(-1, 3)[ok]
        out[ok] = np.maximum(np.linalg.norm(p_fk - pb, axis=1), np.linalg.norm(z_fk - zb, axis=1))
    return out.reshape(shape)


def complete(carm: CArmGeometry, p: np.ndarray, z: np.ndarray, theta2: np.ndarray, sigma) -> np.ndarray:
    """Joint values (..., 5) for wigwag angles θ2 (...) and cos θ5 signs σ (±1), targets broadcast to (..., 3).

    Exact when θ2 solves ``f_σ(θ2) = 0`` (module docstring); otherwise the result misses the target and
    FK verification rejects it.
    """
    L, M, a1, a2 = carm.source_to_orbital_axis, carm.arm_length, carm.a1, carm.a2
    c2, s2 = np.cos(theta2), np.sin(theta2)
    Px = c2 * p[..., 0] + s2 * p[..., 1]
    Py = -s2 * p[..., 0] + c2 * p[..., 1]
    Ux = c2 * z[..., 0] + s2 * z[..., 1]
    Uy = -s2 * z[..., 0] + c2 * z[..., 1]
    zz = z[..., 2]
    sigma = np.broadcast_to(np.asarray(sigma, dtype=float), np.shape(theta2))
    h = np.hypot(Ux, zz)
    singular = h <= SINGULAR
    c5 = np.where(singular, 0.0, sigma * h)
    s5 = np.where(singular, np.sign(Uy) + (Uy == 0), Uy)
    theta5 = np.arctan2(s5, c5)
    g = a1 - L * c5 - a2 * s5
    # Regular: direction gives θ4. Singular: θ4 rolls about the principal axis; s4 = P_x / g when g ≠ 0.
    with np.errstate(divide="ignore", invalid="ignore"):
        s4_sing = np.where(np.abs(g) > SINGULAR, Px / np.where(g == 0, 1.0, g), 0.0)
        theta4_sing = np.where(sigma > 0, np.arcsin(s4_sing), np.pi - np.arcsin(s4_sing))
        theta4_sing = np.where(np.abs(g) > SINGULAR, theta4_sing, 0.0)
    theta4 = np.where(singular, theta4_sing, np.arctan2(sigma * Ux, sigma * zz))
    d1 = p[..., 2] - np.cos(theta4) * g
    d3 = Py - M + L * s5 - a2 * c5
    return np.stack((d1, wrap_angle(theta2), d3, wrap_angle(theta4), theta5), axis=-1)


def isocentric_branches(carm: CArmGeometry, p: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Closed form (a1 = a2 = 0): (N, 4, 5) branches [arm forward σ=+1, forward σ=−1, back σ=+1, back σ=−1]."""
    if not carm.is_isocentric:
        raise CarmkinError("isocentric_branches needs a1 = a2 = 0; use solve() for a general C-arm")
    c = p + carm.orbital_offset * z  # isocentre
    forward_arm = np.arctan2(-c[:, 0], c[:, 1])
    theta2 = np.stack((forward_arm, forward_arm, forward_arm + np.pi, forward_arm + np.pi), axis=1)
    sigma = np.array([1.0, -1.0, 1.0, -1.0])
    return complete(carm, p[:, None], z[:, None], theta2, sigma)


# --- general a1, a2: degree-8 polynomial in t = tan((θ2 − φ)/2) -------------------------------------------

def _linear_forms(carm: CArmGeometry, p: np.ndarray, z: np.ndarray) -> dict[str, tuple[np.ndarray, ...]]:
    """Coefficients (a, b, e) (each (N,)) of ``a cos θ2 + b sin θ2 + e`` for A, B = U_x and C."""
    L, a1, a2 = carm.source_to_orbital_axis, carm.a1, carm.a2
    zero = np.zeros(len(p))
    return {
        "A": (p[:, 0] + L * z[:, 0], p[:, 1] + L * z[:, 1], zero),
        "B": (z[:, 0], z[:, 1], zero),
        "C": (-a2 * z[:, 1], a2 * z[:, 0], zero + a1),
    }


def _squared_equation(forms, zz: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """``F(θ2) = A²(U_x² + z_z²) − U_x² C²`` at angles θ (N, K) or (1, K)."""
    A, _, B, _, C, _ = _forms_at(forms, theta)
    return A * A * (B * B + zz[:, None] ** 2) - B * B * C * C


def _quadratic(form, phi: np.ndarray) -> np.ndarray:
    """Numerator (N, 3), ascending powers of t, of a form at θ2 = φ + 2 atan t, times (1 + t²)."""
    a, b, e = form
    alpha = a * np.cos(phi) + b * np.sin(phi)
    beta = -a * np.sin(phi) + b * np.cos(phi)
    return np.stack((alpha + e, 2.0 * beta, e - alpha), axis=1)


def _polymul(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    out = np.zeros((x.shape[0], x.shape[1] + y.shape[1] - 1))
    for i in range(x.shape[1]):
        out[:, i:i + y.shape[1]] += x[:, i:i + 1] * y
    return out


def _wigwag_candidates(carm: CArmGeometry, p: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Candidate θ2 (N, 8) from the real roots of the squared equation, and a mask of real roots.

    Targets for which F vanishes identically (a continuum of solutions, e.g. the isocentre on the vertical
    axis of an isocentric arm) get no candidates and end up without a valid branch.
    """
    forms = _linear_forms(carm, p, z)
    zz = z[:, 2]
    # Offset φ so that t = ∞ (θ2 = φ + π) is far from a root: the leading coefficient is F(φ + π).
    trial = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
    values = np.abs(_squared_equation(forms, zz, trial[None, :] + np.pi))
    phi = trial[np.argmax(values, axis=1)]
    A, B, C = (_quadratic(forms[k], phi) for k in "ABC")
    W = np.tile([1.0, 0.0, 1.0], (len(p), 1))
    B2 = _polymul(B, B)
    poly = _polymul(_polymul(A, A), B2 + _polymul(W, W) * zz[:, None] ** 2) - _polymul(B2, _polymul(C, C))
    lead = poly[:, -1]
    scale = np.abs(poly).max(axis=1)
    degenerate = np.abs(lead) <= 1e-14 * np.maximum(scale, 1e-300)
    monic = poly[:, :-1] / np.where(degenerate, 1.0, lead)[:, None]
    companion = np.zeros((len(p), 8, 8))
    companion[:, 1:, :-1] = np.eye(7)
    companion[:, :, -1] = -monic
    roots = np.linalg.eigvals(companion)
    real = (np.abs(roots.imag) <= _IMAG_TOLERANCE * (1.0 + np.abs(roots))) & ~degenerate[:, None]
    theta2 = phi[:, None] + 2.0 * np.arctan(roots.real)
    return theta2, real


def _forms_at(forms, theta2: np.ndarray):
    """Values and θ2-derivatives of A, B, C at θ2 (N, K)."""
    out = []
    for k in "ABC":
        a, b, e = (v[:, None] for v in forms[k])
        c, s = np.cos(theta2), np.sin(theta2)
        out += [a * c + b * s + e, -a * s + b * c]
    return out


def _polish(forms, zz: np.ndarray, theta2: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Newton steps on the unsquared ``f_σ(θ2)`` for candidates θ2 (N, K), signs σ (N, K)."""
    zz = zz[:, None]
    for _ in range(_NEWTON_STEPS):
        A, dA, B, dB, C, dC = _forms_at(forms, theta2)
        h = np.hypot(B, zz)
        dh = np.where(h > 0, B * dB / np.where(h > 0, h, 1.0), 0.0)
        f = sigma * A * h - B * C
        df = sigma * (dA * h + A * dh) - dB * C - B * dC
        step = np.where(np.abs(df) > 1e-300, f / np.where(df == 0, 1.0, df), 0.0)
        theta2 = theta2 - np.clip(step, -0.5, 0.5)
    return theta2


def general_branches(carm: CArmGeometry, p: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All candidate branches (N, 16, 5) for any a1, a2 and a mask (N, 16) of candidates from real roots.

    Each real root of the squared equation is polished twice: with the sign σ that the unsquared equation
    implies there (σ = sign(A·U_x·C)), and with −σ (needed where A·U_x·C ≈ 0); FK verification decides.
    """
    theta2, real = _wigwag_candidates(carm, p, z)
    forms = _linear_forms(carm, p, z)
    A, _, B, _, C, _ = _forms_at(forms, theta2)
    implied = np.where(A * B * C < 0, -1.0, 1.0)
    qs = []
    for sigma in (implied, -implied):
        polished = _polish(forms, z[:, 2], theta2, sigma)
        qs.append(complete(carm, p[:, None], z[:, None], polished, sigma))
    return np.concatenate(qs, axis=1), np.concatenate((real, real), axis=1)


# --- verification, de-duplication, selection --------------------------------------------------------------

def _drop_duplicates(q: np.ndarray, valid: np.ndarray, tol: float = 1e-7) -> np.ndarray:
    diff = q[:, :, None, :] - q[:, None, :, :]
    diff[..., (1, 3, 4)] = wrap_angle(diff[..., (1, 3, 4)])
    same = np.all(np.abs(diff) <= tol, axis=-1) & valid[:, :, None] & valid[:, None, :]
    earlier = np.triu(np.ones(same.shape[1:], dtype=bool), k=1)  # same[:, i, j] for i < j
    return valid & ~np.any(same & earlier[None], axis=1)


def range_excess(carm: CArmGeometry, q: np.ndarray) -> np.ndarray:
    """Signed excess (..., 5) of C-arm joints outside their ranges (m or rad); 0 inside.

    Revolute joints count as inside if any ``θ + 2πk`` is (the same pose); the excess is that of the nearest
    such representative. The orbital joint is therefore never "wrapped" into range: ±95° spans less than a turn.
    """
    out = np.empty(q.shape)
    for i, (rng, revolute) in enumerate(zip(carm.joint_ranges, (not p for p in PRISMATIC[1:]))):
        value = q[..., i]
        if revolute:
            candidates = value[..., None] + 2.0 * np.pi * np.array([-1.0, 0.0, 1.0])
            excess = rng.excess(candidates)
            out[..., i] = np.take_along_axis(excess, np.argmin(np.abs(excess), axis=-1)[..., None], -1)[..., 0]
        else:
            out[..., i] = rng.excess(value)
    return out


def select(carm: CArmGeometry, q: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Index (N,) of the chosen branch per the module's selection rule; −1 when none is valid."""
    M = carm.arm_length
    lower = np.array([r.lower for r in carm.joint_ranges])
    upper = np.array([r.upper for r in carm.joint_ranges])
    width = np.maximum(upper - lower, 1e-12)
    with np.errstate(invalid="ignore"):
        preferred = (M + q[..., 2] > 0) & (np.cos(q[..., 4]) >= -SINGULAR)
        excess = np.abs(np.nan_to_num(range_excess(carm, q), nan=np.inf)) / width
        centre = np.abs(q - (lower + upper) / 2) / width
    score = np.where(preferred, 0.0, 1e6) + excess.sum(axis=-1) + 1e-3 * np.nan_to_num(centre, nan=1.0).sum(axis=-1)
    score = np.where(valid, score, np.inf)
    chosen = np.argmin(score, axis=-1)
    return np.where(valid.any(axis=-1), chosen, -1)


def _polynomial_chunk(carm: CArmGeometry, p: np.ndarray, z: np.ndarray, tolerance: float):
    """Verified, de-duplicated branches (n, 16, 5), valid (n, 16), residual (n, 16), valid ones first."""
    q, candidate = general_branches(carm, p, z)
    res = residual(carm, q, p[:, None], z[:, None])
    valid = _drop_duplicates(q, candidate & (res <= tolerance))
    order = np.argsort(~valid, axis=1, kind="stable")
    return np.take_along_axis(q, order[..., None], 1), np.take_along_axis(valid, order, 1), \
        np.take_along_axis(res, order, 1)


def solve(carm: CArmGeometry, position, direction, *, method: str = "auto",
          tolerance: float = TOLERANCE) -> FiveDofSolutions:
    """Every 5-DOF solution for source positions (N, 3) (m) and principal axes (N, 3), C-arm base frame.

    ``method``: "closed-form" (isocentric C-arms only), "polynomial" (any a1, a2) or "auto" (closed form
    when a1 = a2 = 0). Each branch is verified by FK (residual ≤ ``tolerance``); see :class:`FiveDofSolutions`.
    The polynomial solver works in chunks of :data:`CHUNK` targets to bound memory.
    """
    p, z = check_targets(position, direction)
    if method == "auto":
        method = "closed-form" if carm.is_isocentric else "polynomial"
    if method == "closed-form":
        q = isocentric_branches(carm, p, z)
        res = residual(carm, q, p[:, None], z[:, None])
        valid = res <= tolerance
    elif method == "polynomial":
        parts = [_polynomial_chunk(carm, p[i:i + CHUNK], z[i:i + CHUNK], tolerance) for i in range(0, len(p), CHUNK)]
        q, valid, res = (np.concatenate(a, axis=0) for a in zip(*parts))
        keep = max(int(valid.sum(axis=1).max(initial=0)), 1)
        q, valid, res = q[:, :keep], valid[:, :keep], res[:, :keep]
    else:
        raise CarmkinError(f"method must be 'auto', 'closed-form' or 'polynomial', got {method!r}")
    q = np.where(valid[..., None], q, np.nan)
    res = np.where(valid, res, np.inf)
    return FiveDofSolutions(q=q, valid=valid, residual=res, chosen=select(carm, q, valid))


def solve_pose(carm: CArmGeometry, T_base_xray, **kwargs) -> FiveDofSolutions:
    """:func:`solve` for source poses (4, 4) or (N, 4, 4) in the C-arm base frame (roll ignored)."""
    return solve(carm, *targets_from_poses(T_base_xray), **kwargs)


__all__ = [
    "FiveDofSolutions",
    "FiveDofTargetError",
    "check_targets",
    "complete",
    "forward",
    "general_branches",
    "isocentric_branches",
    "range_excess",
    "residual",
    "select",
    "solve",
    "solve_pose",
    "targets_from_poses",
]
