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
singular (:mod:`carmkin.analytic.singular`): on or near the singular family of case (b) (cos θ4 = 0, the
orbital axis parallel to the wigwag axis, where only θ2 ± θ5 is fixed) it is solved in closed form, θ2
taken from ``q_current``, every answer checked by the FK; in cases (a) and (c), or when that check fails, it
is solved numerically (damped least squares on Pinocchio's Jacobian, :mod:`carmkin.analytic.dls`) from seeds
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

import numpy as np

from carmkin.analytic import batch
from carmkin.analytic.closed_form import (  # noqa: F401 (the names of this module's contract)
    CASE_TOLERANCE,
    NUMERICAL_TOLERANCE,
    SINGULAR_CASES,
    SINGULAR_TOLERANCE,
    TIE_TOLERANCE,
    ClosedFormIK,
)
from carmkin.analytic.poses import pose_batch
from carmkin.analytic.results import BatchResult, BranchStatus, IKResult  # noqa: F401
from carmkin.analytic.singular import FAMILY_TOLERANCE  # noqa: F401
from carmkin.analytic.solve import solve_pose, solve_rows, solver_for  # noqa: F401 (solver_for: of this module's contract)
from carmkin.errors import (  # noqa: F401 (defined there, raised here)
    AnalyticIKError,
    CarmkinError,
    InvalidConfigurationError,
    SingularPoseError,
    UnsupportedSystemError,
)
from carmkin.model.kinematics import check_configuration
from carmkin.robot.validity import require_system


def solve(system, T, q_current=None) -> IKResult:
    """Both closed-form IK solutions of ``T`` (4x4 pose of ``xray_source`` in the table frame) and the chosen
    one (see the module docstring for the rules). ``q_current`` (6,): current joints (m, rad), default zero.

    Raises :class:`~carmkin.errors.InvalidPoseError` for a non-rigid ``T``,
    :class:`~carmkin.errors.InvalidConfigurationError` for a bad ``q_current``, :class:`SingularPoseError`
    when a singular pose cannot be solved numerically, :class:`UnsupportedSystemError` for a system with
    extra table joints.
    """
    require_system(system, UnsupportedSystemError)
    result = solve_pose(system, T, q_current)
    result._check = (_validity, system)  # a tuple: a partial costs 3x more, on every solve
    return result


def _solve_rows(system, T, rows, q_current=None) -> IKResult:
    """:func:`solve` of a rigid pose ``T`` already checked by :func:`carmkin.analytic.poses.pose_rows` (its
    ``rows``) on a system already checked: what :class:`carmkin.qp.prepared.PreparedIK` calls (the same
    result, without checking the pose and the system a second time)."""
    result = solve_rows(system, T, rows, 0.0, q_current)
    result._check = (_validity, system)
    return result


def _validity(system, q):
    """The validity report of ``q`` at the one default margin (:func:`carmkin.robot.validity.check`)."""
    from carmkin.robot import validity

    return validity.check(system, q)


def solve_batch(system, Ts, q_current=None) -> BatchResult:
    """:func:`solve` for N poses ``Ts`` (N, 4, 4), vectorized; ``q_current`` (6,) or (N, 6), default zero.

    Singular poses: the singular family (case b) in closed form, vectorised; the others (cases a and c) through
    the numerical fallback one by one; an unsolved one gets NaN solutions and ``reached`` False instead of an
    exception.
    """
    require_system(system, UnsupportedSystemError)
    solver = solver_for(system)
    Ts, rows, correction = pose_batch(Ts, "Ts")
    if q_current is None:
        q_ref = np.zeros(6)
    else:
        q_ref = check_configuration(q_current, 6, "q_current")
        if q_ref.shape not in ((6,), (len(Ts), 6)):
            raise InvalidConfigurationError(
                f"q_current must be finite with shape (6,) or ({len(Ts)}, 6), got {q_ref.shape}")
    return dataclasses.replace(batch.solve_batch(solver, Ts, q_ref, rows), pose_correction=correction)
