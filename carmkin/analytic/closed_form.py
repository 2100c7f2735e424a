"""The closed form of the 6-DOF chain for one system: its constants, the two branches of a pose, the choice
between them, for floats (one pose) and arrays (a batch). The derivation is in :mod:`carmkin.analytic_ik`;
singular poses are handled in :mod:`carmkin.analytic.singular`, batches in :mod:`carmkin.analytic.batch`.
Lengths in metres, angles in radians, joint order ``[d0, d1, θ2, d3, θ4, θ5]``.
"""

from __future__ import annotations

import functools
import math
import weakref

import numpy as np

from carmkin.errors import UnsupportedSystemError
from carmkin.model import singular_cases
from carmkin.model.params import JOINT_NAMES, JOINT_RANGE_TOLERANCE, PRISMATIC
from carmkin.transforms import pose_error, wrap_angle

from .results import BranchStatus, IKResult

#: Below this |det J| (eq. 4.7, dimensionless) a pose is treated as singular and solved numerically. The
#: closed form loses about eps/|factor| of accuracy; at 1e-5 that stays ~1e-10 m / rad for poses within a
#: few metres, well inside the 1e-9 round-trip requirement.
SINGULAR_TOLERANCE = 1e-5
#: A singular pose names every case whose factor of det J is below ``SINGULAR_TOLERANCE ** (1/3)`` (at least
#: one factor is, since all three are at most 1 in magnitude).
CASE_TOLERANCE = SINGULAR_TOLERANCE ** (1.0 / 3.0)
#: Residual (m, rad) a numerical solution must reach.
NUMERICAL_TOLERANCE = 1e-9
#: The singular cases of §4.3.2 (:class:`~carmkin.model.singular_cases.SingularCase`): (a) sin γ1 = 0,
#: (b) cos θ4 = 0, (c) sin(θ2 + γ3) = 0; the one vocabulary shared with :mod:`carmkin.singularity`.
SINGULAR_CASES = singular_cases.CASES
#: Movement sums that differ by less than this (rad or m) count as equal in the selection rules.
TIE_TOLERANCE = 1e-12

REVOLUTE = tuple(i for i, p in enumerate(PRISMATIC) if not p)
PRISMATIC_JOINTS = tuple(i for i, p in enumerate(PRISMATIC) if p)
PI = math.pi
TWO_PI = 2.0 * math.pi


class ClosedFormIK:
    """Per-system constants of the closed form (built once per system, see
    :func:`carmkin.analytic_ik.solver_for`)."""

    def __init__(self, system) -> None:
        if system.table.joints or system.mount.joints:
            extra = [("extra table joints", system.table.joints), ("mount joints", system.mount.joints)]
            raise UnsupportedSystemError(
                "the closed-form IK covers the 6-DOF chain of §4.3; this system has "
                + " and ".join(f"{what} ({', '.join(j.name for j in joints)})" for what, joints in extra if joints)
                + ": use carmkin.qp_ik"
            )
        self._system = weakref.ref(system)  # the per-system cache must not keep the system alive
        fk = system.closed_form
        self.R = np.array(fk.R, dtype=float)
        self.p = np.array(fk.p, dtype=float)
        self.K = tuple(tuple(float(v) for v in row) for row in self.R)
        self.pK = tuple(float(v) for v in self.p)
        self.g = tuple(float(v) for v in self.R[2])  # table axis Z0 in the axes of K
        self.L, self.M, self.a1, self.a2 = float(fk.L), float(fk.M), float(fk.a1), float(fk.a2)
        self.sin_gamma1 = math.sin(system.setup.gamma1)
        self.c3, self.s3 = math.cos(system.setup.gamma3), math.sin(system.setup.gamma3)
        # the constants each pose reads, one attribute read each (the scalar path's speed)
        self.frame2_constants = (self.K, self.L, self.a2, self.pK)
        self.scalar_constants = (self.a1, self.M, self.sin_gamma1, self.c3, self.s3, self.g)
        self.lower = tuple(float(v) for v in system.lower)
        self.upper = tuple(float(v) for v in system.upper)
        # the limits widened by the range tolerance: a value on a limit is in range
        self.lower_ok = tuple(v - JOINT_RANGE_TOLERANCE for v in self.lower)
        self.upper_ok = tuple(v + JOINT_RANGE_TOLERANCE for v in self.upper)
        self.names = JOINT_NAMES
        # revolute joints whose range reaches beyond (−π, π]: candidates θ + 2πk, k in wrap_k[j]
        self.wrap = {}
        for j in REVOLUTE:
            lo, hi = self.lower[j], self.upper[j]
            if lo < -math.pi or hi > math.pi:
                # θ + 2πk with θ in (−π, π] can reach [lo, hi] only for these k (0 = the principal value)
                k_min, k_max = math.ceil((lo - math.pi) / TWO_PI), math.floor((hi + math.pi) / TWO_PI)
                # nearest 0 first, as in the batch path, so that ties (equally near to q_current) keep the
                # principal value in both paths
                self.wrap[j] = tuple(sorted(range(k_min, k_max + 1), key=abs))
        # per joint: (index, revolute, wrap candidates or None, widened range), read by settle()
        self.joints = tuple((j, not PRISMATIC[j], self.wrap.get(j), self.lower_ok[j], self.upper_ok[j])
                            for j in range(6))

    @property
    def system(self):
        """The system these constants were built from."""
        return self._system()

    def frame2_terms(self, x0, y0, z0, px, x1, y1, z1, py, x2, y2, z2, pz):
        """The pose entries seen from frame 2, for floats (scalar path) or arrays (batch path).

        Returns ``(Wx, Wy, s4, Yz, Zz, ux, uy, uz)``: X_xray's components (Wx, Wy, s4 = sin θ4), the Z
        components of Y_xray and Z_xray, and ``u = R_K^T (p + L Z_xray + a2 Y_xray − p_K)``.
        """
        ((k00, k01, k02), (k10, k11, k12), (k20, k21, k22)), L, a2, (pK0, pK1, pK2) = self.frame2_constants
        wx = px + L * z0 + a2 * y0 - pK0
        wy = py + L * z1 + a2 * y1 - pK1
        wz = pz + L * z2 + a2 * y2 - pK2
        return (k00 * x0 + k10 * x1 + k20 * x2, k01 * x0 + k11 * x1 + k21 * x2, k02 * x0 + k12 * x1 + k22 * x2,
                k02 * y0 + k12 * y1 + k22 * y2, k02 * z0 + k12 * z1 + k22 * z2,
                k00 * wx + k10 * wy + k20 * wz, k01 * wx + k11 * wy + k21 * wz, k02 * wx + k12 * wy + k22 * wz)

    # --- scalar path --------------------------------------------------------------------------------
    def angles_and_translations(self, T):
        """Both branches from a 4x4 nested sequence (no checks): (q0, q1, det_j, det2) as lists/floats."""
        (x0, y0, z0, px), (x1, y1, z1, py), (x2, y2, z2, pz) = T[0], T[1], T[2]
        Wx, Wy, s4, Yz, Zz, ux, uy, uz = self.frame2_terms(x0, y0, z0, px, x1, y1, z1, py, x2, y2, z2, pz)
        hyp = math.sqrt(Wx * Wx + Wy * Wy)  # as in the batch path (np.hypot is slow)
        t2 = math.atan2(-Wy, -Wx)
        if hyp > 0.0:
            c2, s2 = -Wx / hyp, -Wy / hyp
        else:
            c2, s2 = math.cos(t2), math.sin(t2)
        t4 = math.atan2(s4, hyp)
        t5 = math.atan2(Yz, Zz)
        a1, M, sin_gamma1, c3, s3, (gx, gy, gz) = self.scalar_constants
        det_j = (s2 * c3 + c2 * s3) * sin_gamma1 * hyp
        det2 = gx * c2 + gy * s2
        # branch 0 (σ = +1) and branch 1 (σ = −1: c2, s2, c4 change sign, and so does det2)
        a1s4, a1c4, Ms2, Mc2 = a1 * s4, a1 * hyp, M * s2, M * c2
        rx, ry = ux - a1s4 * c2 + Ms2, uy - a1s4 * s2 - Mc2
        rx1, ry1 = ux + a1s4 * c2 - Ms2, uy + a1s4 * s2 + Mc2
        if det2 != 0.0:
            d0, d3 = (rx * c2 + ry * s2) / det2, (gx * ry - gy * rx) / det2
            d0_1, d3_1 = (rx1 * c2 + ry1 * s2) / det2, (gy * rx1 - gx * ry1) / det2
        else:
            d0 = d3 = d0_1 = d3_1 = math.nan
        # branch 1's angles (θ2 + π, π − θ4, θ5 + π) wrapped into (−π, π]
        q0 = [d0, uz - a1c4 - d0 * gz, t2, d3, t4, t5]
        q1 = [d0_1, uz + a1c4 - d0_1 * gz, t2 - PI if t2 > 0.0 else t2 + PI, d3_1,
              PI - t4 if t4 >= 0.0 else -PI - t4, t5 - PI if t5 > 0.0 else t5 + PI]
        return q0, q1, det_j, det2

    def settle(self, q: list, ref) -> dict:
        """Put branch ``q`` in range, in place, and return its excess.

        Each angle goes to (−π, π], or to its in-range representative θ + 2πk nearest to ``ref`` where the
        joint's range reaches beyond; the result is the signed excess of the joints still out of range
        (name -> m or rad; NaN for a NaN value), empty when ``q`` is within its ranges. One pass over the
        joints: this is the scalar path's inner loop."""
        out = {}
        for j, revolute, ks, lo, hi in self.joints:
            v = q[j]
            if revolute:
                if not -PI < v <= PI:  # the closed form's atan2 angles are, but for −π; DLS results need not be
                    v = wrap_angle(v)
                if ks and not (lo <= v <= hi and abs(v - ref[j]) < PI):  # else no v + 2πk is nearer ref[j]
                    r, best = ref[j], None
                    for k in ks:
                        c = v + k * TWO_PI
                        if lo <= c <= hi and (best is None or abs(c - r) < abs(best - r)):
                            best = c
                    if best is not None:
                        v = best
                q[j] = v
            if not lo <= v <= hi:  # outside, or NaN
                out[self.names[j]] = v - self.lower[j] if v < lo else v - self.upper[j] if v > hi else math.nan
        return out

    @staticmethod
    def choose(q0, q1, within0: bool, within1: bool, ref) -> int:
        """The rules of §4.4.2: within limits, then rotational movement, then translational movement."""
        if within0 != within1:
            return 0 if within0 else 1
        (i, j, k), (l, m, n) = REVOLUTE, PRISMATIC_JOINTS  # written out: the scalar path's speed
        rot0 = abs(q0[i] - ref[i]) + abs(q0[j] - ref[j]) + abs(q0[k] - ref[k])
        rot1 = abs(q1[i] - ref[i]) + abs(q1[j] - ref[j]) + abs(q1[k] - ref[k])
        if rot1 < rot0 - TIE_TOLERANCE:
            return 1
        if rot0 < rot1 - TIE_TOLERANCE:
            return 0
        tr0 = abs(q0[l] - ref[l]) + abs(q0[m] - ref[m]) + abs(q0[n] - ref[n])
        tr1 = abs(q1[l] - ref[l]) + abs(q1[m] - ref[m]) + abs(q1[n] - ref[n])
        return 1 if tr1 < tr0 - TIE_TOLERANCE else 0

    def singular_cases(self, det_j: float, c4: float, f_c: float) -> tuple:
        """The cases (:class:`SingularCase`) whose factor of det J is below :data:`CASE_TOLERANCE`."""
        return singular_cases.cases_below((self.sin_gamma1, c4, f_c), CASE_TOLERANCE)

    def regular(self, T: np.ndarray, q0: list, q1: list, det_j: float, q_ref) -> IKResult:
        """The result of a regular pose from its two closed-form branches (lists, changed in place)."""
        e0, e1 = self.settle(q0, q_ref), self.settle(q1, q_ref)
        chosen = self.choose(q0, q1, not e0, not e1, q_ref)
        return IKResult((q0, q1), chosen, functools.partial(self.statuses, T, q0, q1, e0, e1), det_j)

    def statuses(self, T, q0: list, q1: list, e0: dict, e1: dict) -> tuple:
        """The :class:`BranchStatus` of a regular pose's two branches (excess ``e0``, ``e1``; residual on
        first read)."""
        return (BranchStatus(not e0, e0, _pose_check=lambda: self.residual(q0, T)),
                BranchStatus(not e1, e1, _pose_check=lambda: self.residual(q1, T)))

    def residual(self, q, T) -> float:
        """max(position error m, rotation angle rad) of the closed-form FK of ``q`` against ``T``."""
        with np.errstate(over="ignore", invalid="ignore"):  # a seed with absurd translations: inf, not a warning
            return max(pose_error(self.system.closed_form.pose(q), np.asarray(T, dtype=float)))

    def excess_batch(self, v: np.ndarray, j: int) -> np.ndarray:
        """Vectorized excess (:meth:`settle`) of joint ``j`` for values ``v``: signed excess, 0 within the range
        widened by :data:`JOINT_RANGE_TOLERANCE` (NaN stays NaN)."""
        lo, hi = self.lower[j], self.upper[j]
        out = np.where(v < self.lower_ok[j], v - lo, np.where(v > self.upper_ok[j], v - hi, 0.0))
        return np.where(np.isnan(v), np.nan, out)

    def representatives_batch(self, q: np.ndarray, ref: np.ndarray, zero_ref: bool) -> None:
        """Vectorized representatives (:meth:`settle`) on q (2, 6, N) with ref (6, N) or (6, 1), in place."""
        for j in REVOLUTE:
            t = q[:, j]
            t[t <= -math.pi] += TWO_PI  # atan2 gives [−π, π]: map −π to π
            ks = self.wrap.get(j)
            if ks is None:
                continue
            lo, hi = self.lower_ok[j], self.upper_ok[j]
            inside = (t >= lo) & (t <= hi)
            shift = np.zeros(t.shape)
            best_d = None if zero_ref else np.where(inside, np.abs(t - ref[j]), np.inf)
            for k in sorted(ks, key=abs):  # nearest to 0 first
                if k == 0:
                    continue
                c = t + k * TWO_PI
                take = (c >= lo) & (c <= hi)
                if zero_ref:  # |c| > π ≥ |t|: another representative only when none nearer 0 is in range
                    take &= ~inside
                    inside |= take
                else:
                    d = np.abs(c - ref[j])
                    take &= d < best_d
                    np.copyto(best_d, d, where=take)
                shift[take] = k * TWO_PI
            q[:, j] = t + shift

    @staticmethod
    def choose_batch(q: np.ndarray, within: np.ndarray, ref: np.ndarray) -> np.ndarray:
        """Vectorized :meth:`choose` on q (2, 6, N), within (2, N) and ref (6, N) or (6, 1)."""
        rot = np.abs(q[:, 2] - ref[2]) + np.abs(q[:, 4] - ref[4]) + np.abs(q[:, 5] - ref[5])
        tr = np.abs(q[:, 0] - ref[0]) + np.abs(q[:, 1] - ref[1]) + np.abs(q[:, 3] - ref[3])
        pick1 = np.where(
            within[0] != within[1],
            within[1],
            (rot[1] < rot[0] - TIE_TOLERANCE)
            | ((np.abs(rot[1] - rot[0]) <= TIE_TOLERANCE) & (tr[1] < tr[0] - TIE_TOLERANCE)),
        )
        return pick1.astype(np.intp)
