"""Closed-form inverse kinematics of the 6-DOF C-arm + table chain (§4.3.3, Table 4.2; selection §4.4.2).

Given ``T`` = pose of ``xray_source`` in the table frame 0 (what :meth:`CArmSystem.fk` returns; m, rad),
:func:`solve` returns both solutions of the chain and picks one; :func:`solve_batch` does the same for N
poses with numpy. Derivation (from the DH rows of :mod:`carmkin.model.kinematics`, not from the printed Table 4.2,
see ``docs/errata/analytic_ik.md``): the FK is ``0T_xray = Tz(d0) · K · Tz(d1) · 2T_xray(θ2, d3, θ4, θ5)``
with the constant ``K = A0(0) A1(0)``. With ``W = R_Kᵀ R`` (the source orientation in frame 2's parent
axes), the X axis of the source is ``W e_x = (−c2 c4, −s2 c4, s4)``, the Z components of its Y and Z axes
are ``c4 s5`` and ``c4 c5``. Hence, with ``σ = ±1`` (branch 0: cos θ4 > 0)::

    θ4 = atan2(s4, σ·hypot(Wx, Wy)),  θ2 = atan2(−σ Wy, −σ Wx),  θ5 = atan2(σ W[2,1], σ W[2,2])

The position is linear in the prismatic joints once the angles are known:
``R_Kᵀ(p − p_K + L·z + a2·y) − a1·(c2 s4, s2 s4, c4) − M·(−s2, c2, 0)
= d0·g + d3·(−s2, c2, 0) + d1·e_z``
with ``g = R_Kᵀ e_z`` (the table axis), ``L = l2 + a1`` and ``M = l1 − a2``; its determinant
``gx c2 + gy s2 = sin γ1 · sin(θ2 + γ3)`` vanishes in singular cases (a) and (c). Exact for any a1, a2 and
any table setup.

Singularities (§4.3.2): ``det J = sin(θ2+γ3) · sin γ1 · cos θ4`` (eq. 4.7, checked against Pinocchio's
Jacobian in the tests; the same value for both branches). When ``|det J| < SINGULAR_TOLERANCE`` the pose is
solved numerically (damped least squares on Pinocchio's Jacobian, :mod:`carmkin.analytic.dls`) from a seed
built from the closed form and ``q_current``, and flagged ``numerical``.

Selection (§4.4.2, in order): within the joint ranges; then the smaller sum of rotational joint movements
from ``q_current`` (zero configuration when none is given); then the smaller sum of translational ones;
ties keep branch 0. Angles are in (−π, π], except where a joint's range reaches beyond ±π (the angular
joint spans ±190°): the representative ``θ + 2πk`` inside the range nearest to ``q_current`` is returned.
Nothing is clipped: out-of-range joints are reported in :attr:`BranchStatus.excess`; a value within
:data:`~carmkin.model.params.JOINT_RANGE_TOLERANCE` of a limit (1e-9 m or rad) is in range.
"""

from __future__ import annotations

import dataclasses
import math
import weakref
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from carmkin.errors import (  # noqa: F401 (defined there, raised here)
    AnalyticIKError,
    CarmkinError,
    InvalidConfigurationError,
    SingularPoseError,
    UnsupportedSystemError,
)
from carmkin.model import singular_cases
from carmkin.model.kinematics import check_configuration
from carmkin.model.params import JOINT_NAMES, JOINT_RANGE_TOLERANCE, PRISMATIC
from carmkin.model.per_system import per_system
from carmkin.analytic.poses import pose_batch, pose_rows
from carmkin.transforms import pose_error, wrap_angle
from carmkin.validation import JOINT_VALUE_LIMIT

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

_REVOLUTE = tuple(i for i, p in enumerate(PRISMATIC) if not p)
_PRISMATIC = tuple(i for i, p in enumerate(PRISMATIC) if p)
_TWO_PI = 2.0 * math.pi


@dataclass(eq=False)
class BranchStatus:
    """Status of one IK branch.

    ``within_limits``: every joint inside its range; ``excess``: joint name -> signed excess (m or rad;
    < 0 below the lower limit, > 0 above the upper) for the out-of-range joints only; ``singular``: names of
    the singular cases (:data:`SINGULAR_CASES`) of the pose, empty when regular; ``numerical``: solved by
    damped least squares; ``reached``: the solution meets the pose (always for the closed form; for a
    numerical one, residual ≤ 1e-9); ``residual``: max(position error m, rotation angle rad) of FK of the
    solution against the target — measured by the numerical solver, computed on first access otherwise.
    """

    within_limits: bool
    excess: dict
    singular: tuple = ()
    numerical: bool = False
    reached: bool = True
    _residual: float | None = field(default=None, repr=False, compare=False)
    _pose_check: object = field(default=None, repr=False, compare=False)

    @cached_property
    def residual(self) -> float:
        if self._residual is not None:
            return self._residual
        return float(self._pose_check())

    @property
    def status(self) -> str:
        """``"ok"``, ``"out of range"``, ``"singular"`` or ``"singular, out of range"`` (unreached:
        ``"singular, unsolved"``)."""
        if not self.reached:
            return "singular, unsolved"
        parts = (["singular"] if self.singular else []) + ([] if self.within_limits else ["out of range"])
        return ", ".join(parts) or "ok"


@dataclass(eq=False)
class IKResult:
    """Both IK solutions of one pose and the chosen one.

    ``solutions`` (2, 6): branch 0 (cos θ4 > 0) and branch 1, joint order ``[d0, d1, θ2, d3, θ4, θ5]``
    (m, rad); ``chosen``: index of the branch picked by the rules of §4.4.2; ``branches``: the two
    :class:`BranchStatus`; ``det_j``: det J of eq. 4.7 at the pose (same for both branches);
    ``pose_correction``: ``‖T_rigid − T‖_F`` by which a nearly rigid ``T`` was projected onto the nearest
    rigid transform (:mod:`carmkin.analytic.poses`; 0 for a rigid one).
    """

    solutions: np.ndarray
    chosen: int
    branches: tuple
    det_j: float
    pose_correction: float = 0.0

    @property
    def q(self) -> np.ndarray:
        """The chosen solution (6,)."""
        return self.solutions[self.chosen]

    @property
    def valid(self) -> bool:
        """The chosen branch is within the joint ranges (and reaches the pose)."""
        status = self.branches[self.chosen]
        return status.within_limits and status.reached

    @property
    def singular(self) -> tuple:
        """Names of the singular cases of the pose (empty when regular)."""
        return self.branches[0].singular

    @property
    def numerical(self) -> bool:
        """True when the solutions come from the numerical fallback."""
        return self.branches[0].numerical


@dataclass(frozen=True)
class BatchResult:
    """IK of N poses: ``solutions`` (2, N, 6); ``chosen`` (N,) int; ``within_limits`` (2, N) bool;
    ``excess`` (2, N, 6) signed excess (0 inside the range); ``singular`` (N, 3) bool, one column per case
    of :data:`SINGULAR_CASES`; ``numerical`` (N,) bool; ``reached`` (2, N) bool; ``det_j`` (N,).
    ``residual`` (2, N) is computed on first access (batch FK); ``pose_correction`` (N,): as
    :attr:`IKResult.pose_correction`, per pose."""

    solutions: np.ndarray
    chosen: np.ndarray
    within_limits: np.ndarray
    excess: np.ndarray
    singular: np.ndarray
    numerical: np.ndarray
    reached: np.ndarray
    det_j: np.ndarray
    _system: object = field(repr=False, compare=False)
    _poses: np.ndarray = field(repr=False, compare=False)
    pose_correction: np.ndarray | None = None

    @property
    def q(self) -> np.ndarray:
        """Chosen solutions (N, 6)."""
        return self.solutions[self.chosen, np.arange(self.solutions.shape[1])]

    @property
    def valid(self) -> np.ndarray:
        """(N,) bool: the chosen branch is within the joint ranges and reaches the pose."""
        index = np.arange(len(self.chosen))
        return self.within_limits[self.chosen, index] & self.reached[self.chosen, index]

    @cached_property
    def residual(self) -> np.ndarray:
        """(2, N): max(position error m, rotation angle rad) of FK of each solution against its pose."""
        n = self.solutions.shape[1]
        fk = self._system.fk(self.solutions.reshape(2 * n, 6)).reshape(2, n, 4, 4)
        return np.maximum(*pose_error(fk, self._poses[None]))


class ClosedFormIK:
    """Per-system constants of the closed form (built once per system, see :func:`solver_for`)."""

    def __init__(self, system) -> None:
        if system.table.joints:
            raise UnsupportedSystemError(
                "the closed-form IK covers the 6-DOF chain of §4.3; this system has extra table joints "
                f"({', '.join(j.name for j in system.table.joints)}): use carmkin.qp_ik"
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
        self.lower = tuple(float(v) for v in system.lower)
        self.upper = tuple(float(v) for v in system.upper)
        # the limits widened by the range tolerance: a value on a limit is in range
        self.lower_ok = tuple(v - JOINT_RANGE_TOLERANCE for v in self.lower)
        self.upper_ok = tuple(v + JOINT_RANGE_TOLERANCE for v in self.upper)
        self.names = JOINT_NAMES
        # revolute joints whose range reaches beyond (−π, π]: candidates θ + 2πk, k in wrap_k[j]
        self.wrap = {}
        for j in _REVOLUTE:
            lo, hi = self.lower[j], self.upper[j]
            if lo < -math.pi or hi > math.pi:
                # θ + 2πk with θ in (−π, π] can reach [lo, hi] only for these k (0 = the principal value)
                k_min, k_max = math.ceil((lo - math.pi) / _TWO_PI), math.floor((hi + math.pi) / _TWO_PI)
                # nearest 0 first, as in the batch path, so that ties (equally near to q_current) keep the
                # principal value in both paths
                self.wrap[j] = tuple(sorted(range(k_min, k_max + 1), key=abs))

    @property
    def system(self):
        """The system these constants were built from."""
        return self._system()

    def frame2_terms(self, x0, y0, z0, px, x1, y1, z1, py, x2, y2, z2, pz):
        """The pose entries seen from frame 2, for floats (scalar path) or arrays (batch path).

        Returns ``(Wx, Wy, s4, Yz, Zz, ux, uy, uz)``: X_xray's components (Wx, Wy, s4 = sin θ4), the Z
        components of Y_xray and Z_xray, and ``u = R_K^T (p + L Z_xray + a2 Y_xray − p_K)``.
        """
        (k00, k01, k02), (k10, k11, k12), (k20, k21, k22) = self.K
        L, a2 = self.L, self.a2
        wx = px + L * z0 + a2 * y0 - self.pK[0]
        wy = py + L * z1 + a2 * y1 - self.pK[1]
        wz = pz + L * z2 + a2 * y2 - self.pK[2]
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
        f_c = s2 * self.c3 + c2 * self.s3
        det_j = f_c * self.sin_gamma1 * hyp
        gx, gy, gz = self.g
        det2 = gx * c2 + gy * s2
        a1, M = self.a1, self.M
        out = []
        for sigma in (1.0, -1.0):
            c2s, s2s, c4 = sigma * c2, sigma * s2, sigma * hyp
            rx = ux - a1 * c2s * s4 + M * s2s
            ry = uy - a1 * s2s * s4 - M * c2s
            rz = uz - a1 * c4
            det = sigma * det2
            if det != 0.0:
                d0 = (rx * c2s + ry * s2s) / det
                d3 = (gx * ry - gy * rx) / det
            else:
                d0 = d3 = math.nan
            d1 = rz - d0 * gz
            if sigma > 0:
                out.append([d0, d1, t2, d3, t4, t5])
            else:  # (θ2 + π, π − θ4, θ5 + π), wrapped into (−π, π]
                out.append([d0, d1, t2 - math.pi if t2 > 0.0 else t2 + math.pi, d3,
                            math.pi - t4 if t4 >= 0.0 else -math.pi - t4, t5 - math.pi if t5 > 0.0 else t5 + math.pi])
        return out[0], out[1], det_j, det2

    def representatives(self, q: list, ref) -> list:
        """Angles of ``q`` in (−π, π], or the in-range representative nearest to ``ref`` (in place)."""
        for j in _REVOLUTE:
            t = wrap_angle(q[j])
            ks = self.wrap.get(j)
            if ks is not None:
                lo, hi, r = self.lower_ok[j], self.upper_ok[j], ref[j]
                best = None
                for k in ks:
                    c = t + k * _TWO_PI
                    if lo <= c <= hi and (best is None or abs(c - r) < abs(best - r)):
                        best = c
                if best is not None:
                    t = best
            q[j] = t
        return q

    def excess(self, q) -> dict:
        """Signed excess of the out-of-range joints of ``q`` (name -> m or rad)."""
        out = {}
        for j in range(6):
            v = q[j]
            if v < self.lower_ok[j]:
                out[self.names[j]] = v - self.lower[j]
            elif v > self.upper_ok[j]:
                out[self.names[j]] = v - self.upper[j]
            elif v != v:  # NaN
                out[self.names[j]] = math.nan
        return out

    @staticmethod
    def choose(q0, q1, within0: bool, within1: bool, ref) -> int:
        """The rules of §4.4.2: within limits, then rotational movement, then translational movement."""
        if within0 != within1:
            return 0 if within0 else 1
        rot0 = sum(abs(q0[j] - ref[j]) for j in _REVOLUTE)
        rot1 = sum(abs(q1[j] - ref[j]) for j in _REVOLUTE)
        if rot1 < rot0 - TIE_TOLERANCE:
            return 1
        if rot0 < rot1 - TIE_TOLERANCE:
            return 0
        tr0 = sum(abs(q0[j] - ref[j]) for j in _PRISMATIC)
        tr1 = sum(abs(q1[j] - ref[j]) for j in _PRISMATIC)
        return 1 if tr1 < tr0 - TIE_TOLERANCE else 0

    def singular_cases(self, det_j: float, c4: float, f_c: float) -> tuple:
        """The cases (:class:`SingularCase`) whose factor of det J is below :data:`CASE_TOLERANCE`."""
        return singular_cases.cases_below((self.sin_gamma1, c4, f_c), CASE_TOLERANCE)

    def solve(self, T: np.ndarray, rows, q_ref) -> IKResult:
        q0, q1, det_j, det2 = self.angles_and_translations(rows)
        if not abs(det_j) >= SINGULAR_TOLERANCE or not math.isfinite(q0[0] + q1[0] + q0[3] + q1[3]):
            return self.solve_singular(T, rows, q_ref, q0, q1, det_j)
        self.representatives(q0, q_ref)
        self.representatives(q1, q_ref)
        e0, e1 = self.excess(q0), self.excess(q1)
        chosen = self.choose(q0, q1, not e0, not e1, q_ref)
        b0 = BranchStatus(not e0, e0, _pose_check=lambda: self.residual(q0, T))
        b1 = BranchStatus(not e1, e1, _pose_check=lambda: self.residual(q1, T))
        return IKResult(np.array((q0, q1)), chosen, (b0, b1), det_j)

    def residual(self, q, T) -> float:
        """max(position error m, rotation angle rad) of the closed-form FK of ``q`` against ``T``."""
        return max(pose_error(self.system.closed_form.pose(q), np.asarray(T, dtype=float)))

    # --- singular path -------------------------------------------------------------------------------
    def seeds(self, rows, q_closed: list, q_ref, branch: int, cases: tuple) -> list[np.ndarray]:
        """Starts for damped least squares, best first: the closed-form branch, and variants taking from
        ``q_ref`` what a singular case leaves undetermined — θ2 in case b (θ5 then follows from θ2 ± θ5),
        and (d0, d3, d1) by the least-change solve of the (rank-deficient) position equations in cases a, c.
        Ordered by the closed-form FK residual of the seed (below 1e-10 counts as exact), then by the
        distance to ``q_ref``."""
        T = np.array(rows, dtype=float)
        W = self.R.T @ T[:3, :3]
        angle_sets = [list(q_closed)]
        if SINGULAR_CASES[1] in cases:
            q = list(q_closed)
            q[2] = q_ref[2] + (0.0 if branch == 0 else math.pi)
            phi = math.atan2(W[0, 1], -W[1, 1])
            q[5] = phi - q[2] if W[2, 0] > 0 else q[2] - phi
            angle_sets.append(q)
        u = self.R.T @ (T[:3, 3] - self.p + self.L * T[:3, 2] + self.a2 * T[:3, 1])
        x_ref = np.array((q_ref[0], q_ref[3], q_ref[1]))
        out = []
        for angles in angle_sets:
            c2, s2, c4, s4 = math.cos(angles[2]), math.sin(angles[2]), math.cos(angles[4]), math.sin(angles[4])
            r = u - self.a1 * np.array((c2 * s4, s2 * s4, c4)) - self.M * np.array((-s2, c2, 0.0))
            A = np.array(((self.g[0], -s2, 0.0), (self.g[1], c2, 0.0), (self.g[2], 0.0, 1.0)))
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
            residual = self.residual(q, T)
            return (residual if residual > 1e-10 else 0.0, float(np.abs(q - ref).sum()))

        return sorted(out, key=key)

    def solve_singular(self, T, rows, q_ref, q0, q1, det_j) -> IKResult:
        from carmkin.analytic import dls as numerical_ik

        c4 = math.cos(q0[4])
        f_c = math.sin(q0[2] + self.system.setup.gamma3)
        cases = self.singular_cases(det_j, c4, f_c)
        T = np.asarray(T, dtype=float)
        solutions, statuses = [], []
        for branch, q_closed in enumerate((q0, q1)):
            best = None
            for seed in self.seeds(rows, q_closed, q_ref, branch, cases):
                run = numerical_ik.solve(self.system, T, seed)
                if best is None or run.residual < best.residual:
                    best = run
                if run.success:
                    break
            q = self.representatives([float(v) for v in best.q], q_ref)
            e = self.excess(q)
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
            chosen = self.choose(solutions[0], solutions[1], statuses[0].within_limits, statuses[1].within_limits,
                                 q_ref)
        return IKResult(np.array(solutions), chosen, tuple(statuses), det_j)

    # --- batch path ----------------------------------------------------------------------------------
    def solve_batch(self, T: np.ndarray, q_ref: np.ndarray, rows: np.ndarray | None = None) -> BatchResult:
        """Both branches for poses T (N, 4, 4) (already checked); q_ref (6,) or (N, 6); ``rows``: the (16, N)
        row-major entries of T when the caller has them."""
        n = T.shape[0]
        if rows is None:
            rows = np.ascontiguousarray(T.reshape(n, 16).T)
        Wx, Wy, s4, Yz, Zz, ux, uy, uz = self.frame2_terms(*rows[:12])
        hyp = np.sqrt(Wx * Wx + Wy * Wy)
        t2 = np.arctan2(-Wy, -Wx)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv_hyp = -1.0 / hyp
        c2, s2 = Wx * inv_hyp, Wy * inv_hyp
        if not np.all(hyp > 0.0):  # exactly singular case b: fall back to the angle
            zero = hyp == 0.0
            c2[zero], s2[zero] = np.cos(t2[zero]), np.sin(t2[zero])
        f_c = s2 * self.c3 + c2 * self.s3
        det_j = f_c * (self.sin_gamma1 * hyp)
        gx, gy, gz = self.g
        det2 = gx * c2 + gy * s2
        a1s4 = self.a1 * s4
        dx = self.M * s2 - a1s4 * c2  # branch 0; branch 1 flips the sign of the a1 and M terms
        dy = -(self.M * c2 + a1s4 * s2)
        dz = self.a1 * hyp
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
        self._representatives_batch(q, ref, not np.any(q_ref))
        excess = np.zeros((2, 6, n))
        for j in range(6):
            excess[:, j] = self._excess_batch(q[:, j], j)
        within = np.all(excess == 0.0, axis=1)
        chosen = self._choose_batch(q, within, ref)
        q = np.ascontiguousarray(q.transpose(0, 2, 1))
        excess = np.ascontiguousarray(excess.transpose(0, 2, 1))
        with np.errstate(invalid="ignore"):  # inf − inf of an unsolvable pose: NaN, caught here
            singular_pose = ~(np.abs(det_j) >= SINGULAR_TOLERANCE) | ~np.isfinite(q[..., (0, 1, 3)].sum(axis=(0, 2)))
        singular = np.zeros((n, 3), dtype=bool)
        reached = np.ones((2, n), dtype=bool)
        for i in np.flatnonzero(singular_pose):  # rare: the numerical fallback, pose by pose
            q_i = q_ref[i] if q_ref.ndim == 2 else q_ref
            closed = self.angles_and_translations(T[i].tolist())
            try:
                result = self.solve_singular(T[i], T[i].tolist(), tuple(q_i.tolist()), closed[0], closed[1],
                                             closed[2])
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
                excess[:, i, j] = self._excess_batch(q[:, i, j], j)
            chosen[i] = result.chosen
        return BatchResult(q, chosen, within, excess, singular, singular_pose, reached, det_j, self.system, T)

    def _excess_batch(self, v: np.ndarray, j: int) -> np.ndarray:
        """Vectorized :meth:`excess` of joint ``j`` for values ``v``: signed excess, 0 within the range
        widened by :data:`JOINT_RANGE_TOLERANCE` (NaN stays NaN)."""
        lo, hi = self.lower[j], self.upper[j]
        out = np.where(v < self.lower_ok[j], v - lo, np.where(v > self.upper_ok[j], v - hi, 0.0))
        return np.where(np.isnan(v), np.nan, out)

    def _representatives_batch(self, q: np.ndarray, ref: np.ndarray, zero_ref: bool) -> None:
        """Vectorized :meth:`representatives` on q (2, 6, N) with ref (6, N) or (6, 1), in place."""
        for j in _REVOLUTE:
            t = q[:, j]
            t[t <= -math.pi] += _TWO_PI  # atan2 gives [−π, π]: map −π to π
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
                c = t + k * _TWO_PI
                take = (c >= lo) & (c <= hi)
                if zero_ref:  # |c| > π ≥ |t|: another representative only when none nearer 0 is in range
                    take &= ~inside
                    inside |= take
                else:
                    d = np.abs(c - ref[j])
                    take &= d < best_d
                    np.copyto(best_d, d, where=take)
                shift[take] = k * _TWO_PI
            q[:, j] = t + shift

    @staticmethod
    def _choose_batch(q: np.ndarray, within: np.ndarray, ref: np.ndarray) -> np.ndarray:
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


@per_system
def solver_for(system) -> ClosedFormIK:
    """The :class:`ClosedFormIK` of ``system``, built on first use and kept while the system lives
    (:func:`carmkin.model.per_system.per_system`; nothing is written into the frozen system)."""
    return ClosedFormIK(system)


def _reference(q_current, n_joints: int = 6):
    if q_current is None:
        return (0.0,) * n_joints
    if type(q_current) is np.ndarray and q_current.shape == (n_joints,) and q_current.dtype == np.float64:
        ref = q_current.tolist()
        if math.isfinite(sum(ref)) and max(map(abs, ref)) <= JOINT_VALUE_LIMIT:
            return ref
    ref = check_configuration(q_current, n_joints, "q_current")
    if ref.ndim != 1:
        raise InvalidConfigurationError(f"q_current must be a finite vector of shape ({n_joints},), got {ref.shape}")
    return tuple(ref.tolist())


def solve(system, T, q_current=None) -> IKResult:
    """Both closed-form IK solutions of ``T`` (4x4 pose of ``xray_source`` in the table frame) and the chosen
    one (see the module docstring for the rules). ``q_current`` (6,): current joints (m, rad), default zero.

    Raises :class:`~carmkin.errors.InvalidPoseError` for a non-rigid ``T``,
    :class:`~carmkin.errors.InvalidConfigurationError` for a bad ``q_current``, :class:`SingularPoseError`
    when a singular pose cannot be solved numerically, :class:`UnsupportedSystemError` for a system with
    extra table joints.
    """
    solver = solver_for(system)
    T, rows, correction = pose_rows(T, "T")
    result = solver.solve(T, rows, _reference(q_current))
    result.pose_correction = correction
    return result


def solve_batch(system, Ts, q_current=None) -> BatchResult:
    """:func:`solve` for N poses ``Ts`` (N, 4, 4), vectorized; ``q_current`` (6,) or (N, 6), default zero.

    Singular poses (rare) go through the numerical fallback one by one; an unsolved one gets NaN solutions
    and ``reached`` False instead of an exception.
    """
    solver = solver_for(system)
    Ts, rows, correction = pose_batch(Ts, "Ts")
    if q_current is None:
        q_ref = np.zeros(6)
    else:
        q_ref = check_configuration(q_current, 6, "q_current")
        if q_ref.shape not in ((6,), (len(Ts), 6)):
            raise InvalidConfigurationError(
                f"q_current must be finite with shape (6,) or ({len(Ts)}, 6), got {q_ref.shape}")
    return dataclasses.replace(solver.solve_batch(Ts, q_ref, rows), pose_correction=correction)
