"""The closed-form IK of N poses at once (numpy): both branches, the choice, and singular poses — the singular
family (case b) in closed form, vectorised (:mod:`carmkin.analytic.singular`), the rest (cases a and c, and
any family answer the FK check refuses) by damped least squares pose by pose. Same rules and results as the
scalar path of :mod:`carmkin.analytic_ik` (tested pose by pose)."""

from __future__ import annotations

import math

import numpy as np

from carmkin.errors import SingularPoseError

from . import singular as family_closed_form
from .closed_form import CASE_TOLERANCE, SINGULAR_CASES, SINGULAR_TOLERANCE, ClosedFormIK
from .results import BatchResult


def solve_batch(ik: ClosedFormIK, T: np.ndarray, q_ref: np.ndarray, rows: np.ndarray | None = None) -> BatchResult:
    """Both branches for poses T (N, 4, 4) (already checked); q_ref (6,) or (N, 6); ``rows``: the (16, N)
    row-major entries of T when the caller has them."""
    n = T.shape[0]
    if rows is None:
        rows = np.ascontiguousarray(T.reshape(n, 16).T)
    Wx, Wy, s4, Yz, Zz, ux, uy, uz = ik.frame2_terms(*rows[:12])
    hyp = np.sqrt(Wx * Wx + Wy * Wy)
    t2 = np.arctan2(-Wy, -Wx)
    with np.errstate(divide="ignore", invalid="ignore"):  # hyp = 0 on the singular family: replaced below
        inv_hyp = -1.0 / hyp
        c2, s2 = Wx * inv_hyp, Wy * inv_hyp
    if not np.all(hyp > 0.0):  # exactly singular case b: fall back to the angle
        zero = hyp == 0.0
        c2[zero], s2[zero] = np.cos(t2[zero]), np.sin(t2[zero])
    f_c = s2 * ik.c3 + c2 * ik.s3
    det_j = f_c * (ik.sin_gamma1 * hyp)
    gx, gy, gz = ik.g
    det2 = gx * c2 + gy * s2
    a1s4 = ik.a1 * s4
    dx = ik.M * s2 - a1s4 * c2  # branch 0; branch 1 flips the sign of the a1 and M terms
    dy = -(ik.M * c2 + a1s4 * s2)
    dz = ik.a1 * hyp
    q = np.empty((2, 6, n))  # joints first while computing: contiguous rows
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det2
        for b, sigma in enumerate((1.0, -1.0)):
            rx, ry = (ux + dx, uy + dy) if b == 0 else (ux - dx, uy - dy)
            d0 = (rx * c2 + ry * s2) * inv
            q[b, 0] = d0
            q[b, 3] = (gx * ry - gy * rx) * (sigma * inv)
            q[b, 1] = (uz - dz if b == 0 else uz + dz) - d0 * gz
    t4 = np.arctan2(s4, hyp)
    t5 = np.arctan2(Yz, Zz)
    q[0, 2], q[0, 4], q[0, 5] = t2, t4, t5
    # branch 1 = (θ2 + π, π − θ4, θ5 + π), wrapped as in the scalar path (a −π that copysign gives
    # for a zero angle becomes π in _representatives_batch)
    q[1, 2] = t2 + np.copysign(math.pi, -t2)
    q[1, 4] = np.copysign(math.pi, t4) - t4
    q[1, 5] = t5 + np.copysign(math.pi, -t5)
    ref = q_ref.T[:, None] if q_ref.ndim == 2 else q_ref[:, None]  # (6, N) or (6, 1)
    ik.representatives_batch(q, ref, not np.any(q_ref))
    excess = np.zeros((2, 6, n))
    for j in range(6):
        excess[:, j] = ik.excess_batch(q[:, j], j)
    within = np.all(excess == 0.0, axis=1)
    chosen = ik.choose_batch(q, within, ref)
    q = np.ascontiguousarray(q.transpose(0, 2, 1))
    excess = np.ascontiguousarray(excess.transpose(0, 2, 1))
    with np.errstate(invalid="ignore"):  # inf − inf of an unsolvable pose: NaN, caught here
        singular_pose = ~(np.abs(det_j) >= SINGULAR_TOLERANCE) | ~np.isfinite(q[..., (0, 1, 3)].sum(axis=(0, 2)))
    singular = np.zeros((n, 3), dtype=bool)
    reached = np.ones((2, n), dtype=bool)
    numerical = singular_pose.copy()
    if np.any(singular_pose):  # the singular family in closed form, vectorised (module carmkin.analytic.singular)
        s = np.flatnonzero(singular_pose)
        ref_s = q_ref[s].T if q_ref.ndim == 2 else q_ref[:, None]  # (6, k) or (6, 1)
        qf, det2_s, f_c_s, hyp_s = family_closed_form.family(ik, rows[:, s], ref_s)
        ok = family_closed_form.solved_on_family(ik, det2_s, family_closed_form.family_residuals(ik, qf, T[s]))
        if np.any(ok):
            idx, qf = s[ok], qf[..., ok]
            ref_ok = ref_s[:, None, ok] if q_ref.ndim == 2 else ref  # as ref: (6, 1, k) or (6, 1)
            ik.representatives_batch(qf, ref_ok, not np.any(q_ref))
            ex = np.zeros(qf.shape)
            for j in range(6):
                ex[:, j] = ik.excess_batch(qf[:, j], j)
            within[:, idx] = np.all(ex == 0.0, axis=1)
            chosen[idx] = ik.choose_batch(qf, within[:, idx], ref_ok)
            q[:, idx], excess[:, idx] = qf.transpose(0, 2, 1), ex.transpose(0, 2, 1)
            singular[idx] = np.stack((np.full(len(idx), abs(ik.sin_gamma1) < CASE_TOLERANCE),
                                      hyp_s[ok] < CASE_TOLERANCE, np.abs(f_c_s[ok]) < CASE_TOLERANCE), axis=1)
            numerical[idx] = False
    for i in np.flatnonzero(numerical):  # rare: the numerical fallback, pose by pose
        q_i = q_ref[i] if q_ref.ndim == 2 else q_ref
        closed = ik.angles_and_translations(T[i].tolist())
        try:
            result = family_closed_form.solve_numerical(ik, T[i], T[i].tolist(), tuple(q_i.tolist()), closed[0],
                                                        closed[1], closed[2])
        except SingularPoseError as exc:
            singular[i] = [c in exc.cases for c in SINGULAR_CASES]
            reached[:, i] = False
            q[:, i] = excess[:, i] = np.nan
            within[:, i] = False
            continue
        q[:, i] = result.solutions
        singular[i] = [c in result.singular for c in SINGULAR_CASES]
        reached[:, i] = [b.reached for b in result.branches]
        within[:, i] = [b.within_limits for b in result.branches]
        for j in range(6):
            excess[:, i, j] = ik.excess_batch(q[:, i, j], j)
        chosen[i] = result.chosen
    return BatchResult(q, chosen, within, excess, singular, numerical, reached, det_j, ik.system, T)
