"""Singular poses of the 6-DOF closed form (§4.3.2): the singular family in closed form, the rest numerically.

**The singular family (case b, cos θ4 = 0: the orbital axis parallel to the wigwag axis).** With ``W = R_Kᵀ R``
(the source orientation in frame 2's parent axes, :mod:`carmkin.analytic_ik`) the chain gives, checked
entry by entry against the FK::

    W = [[−c2 c4,  s2 c5 + c2 s4 s5,  −s2 s5 + c2 s4 c5],
         [−s2 c4, −c2 c5 + s2 s4 s5,   c2 s5 + s2 s4 c5],
         [  s4,          c4 s5,              c4 c5     ]]

so with ``σ = sign(s4)``: ``W01 + σ W12 = (1 + σ s4) sin(θ2 + σ θ5)`` and ``−W11 + σ W02 = (1 + σ s4)
cos(θ2 + σ θ5)``. Hence ``φ = θ2 + σ θ5 = atan2(W01 + σ W12, −W11 + σ W02)``, well conditioned for every θ4
(``1 + |s4| ≥ 1``), whereas the regular ``θ5 = atan2(c4 s5, c4 c5)`` loses ``eps/|c4|`` near the family.
On the family (``|c4| < FAMILY_TOLERANCE``) only φ is fixed: θ2 is free, and the rules of §4.4.2 (least
rotation from ``q_current``) take ``θ2 = θ2_ref`` (branch 1: ``θ2_ref + π``), ``θ4 = ±π/2``,
``θ5 = σ (φ − θ2)``; near it, θ2 = atan2(−Wy, −Wx) as usual and θ5 from φ. The translations follow from the
linear position equations at the chosen θ2 (determinant ``sin γ1 sin(θ2 + γ3)``, away from cases a and c).
Every answer is checked by the closed-form FK (residual ≤ :data:`NUMERICAL_TOLERANCE`); a pose whose
answer does not pass, and every pose of cases a and c, goes to damped least squares
(:mod:`carmkin.analytic.dls`) from seeds built from the closed form and ``q_current``.
"""

from __future__ import annotations

import math

import numpy as np

from carmkin.analytic import dls as numerical_ik
from carmkin.errors import SingularPoseError
from carmkin.transforms import pose_error
from carmkin.validation import JOINT_VALUE_LIMIT

from .closed_form import (
    CASE_TOLERANCE,
    NUMERICAL_TOLERANCE,
    SINGULAR_CASES,
    SINGULAR_TOLERANCE,
    TWO_PI,
    ClosedFormIK,
)
from .results import BranchStatus, IKResult

#: Below this ``|cos θ4|`` a pose counts as on the singular family itself and θ2 is taken from ``q_current``:
#: forcing θ4 = ±π/2 there moves the source axes by at most ``2 |cos θ4|`` (2e-10), inside
#: :data:`NUMERICAL_TOLERANCE`, and the FK check stands behind it.
FAMILY_TOLERANCE = 1e-10


def family(ik: ClosedFormIK, rows: np.ndarray, ref: np.ndarray):
    """Both branches of poses near or on the singular family, vectorised.

    ``rows`` (16, n): row-major entries of the poses; ``ref`` (6, n) the reference joints. Returns
    ``(q (2, 6, n), det2 (2, n), f_c (n,), hyp (n,))``: the solutions (angles in (−π, π]), the determinant of
    the position equations per branch, the factor ``sin(θ2 + γ3)`` of branch 0 and ``|cos θ4|`` of the pose.
    """
    x0, y0, z0, px, x1, y1, z1, py, x2, y2, z2, pz = rows[:12]
    Wx, Wy, s4, _, _, ux, uy, uz = ik.frame2_terms(x0, y0, z0, px, x1, y1, z1, py, x2, y2, z2, pz)
    (k00, k01, _), (k10, k11, _), (k20, k21, _) = ik.K
    w01, w11 = k00 * y0 + k10 * y1 + k20 * y2, k01 * y0 + k11 * y1 + k21 * y2
    w02, w12 = k00 * z0 + k10 * z1 + k20 * z2, k01 * z0 + k11 * z1 + k21 * z2
    sigma = np.where(s4 >= 0.0, 1.0, -1.0)
    phi = np.arctan2(w01 + sigma * w12, -w11 + sigma * w02)
    hyp = np.sqrt(Wx * Wx + Wy * Wy)
    on = hyp < FAMILY_TOLERANCE
    hyp_used = np.where(on, 0.0, hyp)
    t2 = np.where(on, ref[2], np.arctan2(-Wy, -Wx))
    gx, gy, gz = ik.g
    q = np.empty((2, 6) + t2.shape)
    det2 = np.empty((2,) + t2.shape)
    for b, sign in enumerate((1.0, -1.0)):
        theta2 = t2 if b == 0 else t2 + math.pi
        theta4 = np.arctan2(s4, sign * hyp_used)
        c2, s2, c4, sin4 = np.cos(theta2), np.sin(theta2), np.cos(theta4), np.sin(theta4)
        rx = ux - ik.a1 * c2 * sin4 + ik.M * s2
        ry = uy - ik.a1 * s2 * sin4 - ik.M * c2
        rz = uz - ik.a1 * c4
        det = gx * c2 + gy * s2
        with np.errstate(divide="ignore", invalid="ignore"):
            d0 = (rx * c2 + ry * s2) / det
            q[b, 3] = (gx * ry - gy * rx) / det
        q[b, 0], q[b, 1] = d0, rz - d0 * gz
        q[b, 2], q[b, 4], q[b, 5] = theta2, theta4, sigma * (phi - theta2)
        det2[b] = det
    for j in (2, 4, 5):  # into (−π, π]
        q[:, j] = np.mod(q[:, j] + math.pi, TWO_PI) - math.pi
        q[:, j][q[:, j] <= -math.pi] += TWO_PI
    f_c = np.sin(q[0, 2]) * ik.c3 + np.cos(q[0, 2]) * ik.s3
    return q, det2, f_c, hyp


def family_residuals(ik: ClosedFormIK, q: np.ndarray, T: np.ndarray) -> np.ndarray:
    """(2, n) max(position error m, rotation angle rad) of the closed-form FK of q (2, 6, n) against T (n, 4, 4)."""
    n = q.shape[-1]
    flat = np.ascontiguousarray(q.transpose(0, 2, 1)).reshape(2 * n, 6)
    with np.errstate(invalid="ignore"):  # translations of cases a and c may be infinite or absurd: not checked
        finite = np.all(np.abs(flat) <= JOINT_VALUE_LIMIT, axis=1)
    out = np.full(2 * n, np.inf)
    if np.any(finite):
        with np.errstate(invalid="ignore", over="ignore"):  # absurd translations: an inf residual, refused
            poses = np.broadcast_to(T[None], (2, n, 4, 4)).reshape(2 * n, 4, 4)[finite]
            out[finite] = np.maximum(*pose_error(ik.system.fk(flat[finite], check_units=False), poses))
    return out.reshape(2, n)


def solved_on_family(ik: ClosedFormIK, det2: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """(n,) bool: both branches away from cases a and c and reaching the pose to :data:`NUMERICAL_TOLERANCE`."""
    with np.errstate(invalid="ignore"):
        return np.all((np.abs(det2) >= CASE_TOLERANCE) & (residual <= NUMERICAL_TOLERANCE), axis=0)


def solve(ik: ClosedFormIK, T, rows, q_ref, q0, q1, det_j) -> IKResult:
    """One singular pose: the closed form of the singular family when it applies and reaches the pose, else
    damped least squares (:func:`solve_numerical`)."""
    T = np.asarray(T, dtype=float)
    ref = np.asarray(q_ref, dtype=float)[:, None]
    q, det2, f_c, hyp = family(ik, np.asarray(rows, dtype=float).reshape(16, 1), ref)
    residual = family_residuals(ik, q, T[None])
    if not solved_on_family(ik, det2, residual)[0]:
        return solve_numerical(ik, T, rows, q_ref, q0, q1, det_j)
    cases = ik.singular_cases(det_j, float(hyp[0]), float(f_c[0]))
    solutions, statuses = [], []
    for b in range(2):
        q_b = q[b, :, 0].tolist()
        e = ik.settle(q_b, q_ref)
        solutions.append(q_b)
        statuses.append(BranchStatus(not e, e, cases, False, True, float(residual[b, 0])))
    chosen = ik.choose(solutions[0], solutions[1], statuses[0].within_limits, statuses[1].within_limits, q_ref)
    return IKResult(np.array(solutions), chosen, tuple(statuses), det_j)


def seeds(ik, rows, q_closed: list, q_ref, branch: int, cases: tuple) -> list[np.ndarray]:
    """Starts for damped least squares, best first: the closed-form branch, and variants taking from
    ``q_ref`` what a singular case leaves undetermined — θ2 in case b (θ5 then follows from θ2 ± θ5),
    and (d0, d3, d1) by the least-change solve of the (rank-deficient) position equations in cases a, c.
    Ordered by the closed-form FK residual of the seed (below 1e-10 counts as exact), then by the
    distance to ``q_ref``."""
    T = np.array(rows, dtype=float)
    W = ik.R.T @ T[:3, :3]
    angle_sets = [list(q_closed)]
    if SINGULAR_CASES[1] in cases:
        q = list(q_closed)
        q[2] = q_ref[2] + (0.0 if branch == 0 else math.pi)
        phi = math.atan2(W[0, 1], -W[1, 1])
        q[5] = phi - q[2] if W[2, 0] > 0 else q[2] - phi
        angle_sets.append(q)
    u = ik.R.T @ (T[:3, 3] - ik.p + ik.L * T[:3, 2] + ik.a2 * T[:3, 1])
    x_ref = np.array((q_ref[0], q_ref[3], q_ref[1]))
    out = []
    for angles in angle_sets:
        c2, s2, c4, s4 = math.cos(angles[2]), math.sin(angles[2]), math.cos(angles[4]), math.sin(angles[4])
        r = u - ik.a1 * np.array((c2 * s4, s2 * s4, c4)) - ik.M * np.array((-s2, c2, 0.0))
        A = np.array(((ik.g[0], -s2, 0.0), (ik.g[1], c2, 0.0), (ik.g[2], 0.0, 1.0)))
        translations = [x_ref + np.linalg.pinv(A, rcond=1e-9) @ (r - A @ x_ref)]
        try:
            translations.append(np.linalg.solve(A, r))
        except np.linalg.LinAlgError:  # exactly singular: the least-change solution only
            pass
        for x in translations:
            q = np.array(angles, dtype=float)
            q[[0, 3, 1]] = x
            if np.all(np.isfinite(q)):
                out.append(q)
    ref = np.asarray(q_ref, dtype=float)

    def key(q):
        residual = ik.residual(q, T)
        return (residual if residual > 1e-10 else 0.0, float(np.abs(q - ref).sum()))

    return sorted(out, key=key)

def solve_numerical(ik, T, rows, q_ref, q0, q1, det_j) -> IKResult:
    c4 = math.cos(q0[4])
    f_c = math.sin(q0[2] + ik.system.setup.gamma3)
    cases = ik.singular_cases(det_j, c4, f_c)
    T = np.asarray(T, dtype=float)
    solutions, statuses = [], []
    for branch, q_closed in enumerate((q0, q1)):
        best = None
        for seed in seeds(ik, rows, q_closed, q_ref, branch, cases):
            run = numerical_ik.solve(ik.system, T, seed)
            if best is None or run.residual < best.residual:
                best = run
            if run.success:
                break
        q = [float(v) for v in best.q]
        e = ik.settle(q, q_ref)
        solutions.append(q)
        statuses.append(BranchStatus(not e, e, cases, True, best.success, best.residual))
    if not (statuses[0].reached or statuses[1].reached):
        raise SingularPoseError(
            f"singular pose ({', '.join(cases)}; |det J| = {abs(det_j):.3g} < {SINGULAR_TOLERANCE:g}): "
            f"damped least squares stopped at residuals {statuses[0].residual:.3g}, "
            f"{statuses[1].residual:.3g} > {NUMERICAL_TOLERANCE:g}",
            cases, (statuses[0].residual, statuses[1].residual),
        )
    if statuses[0].reached != statuses[1].reached:
        chosen = 0 if statuses[0].reached else 1
    else:
        chosen = ik.choose(solutions[0], solutions[1], statuses[0].within_limits, statuses[1].within_limits,
                             q_ref)
    return IKResult(np.array(solutions), chosen, tuple(statuses), det_j)
