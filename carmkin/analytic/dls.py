"""Damped-least-squares inverse kinematics on Pinocchio's Jacobian (numerical fallback and baseline).

Used by :mod:`carmkin.analytic_ik` at singular poses (§4.3.3: "numerical solutions should be explored
in these situations"), and as the baseline of ``benchmarks/bench_ik.py``. Frames: the target is the pose of
a model frame (default ``xray_source``) in the root (table) frame 0; lengths in m, angles in rad.

Iteration (Levenberg–Marquardt style damping, full steps):
``e = log6(oMf⁻¹ · oMdes)`` (frame-local twist), ``Jₑ = −Jlog6(e⁻¹) · J_local``,
``Δq = −Jₑᵀ (Jₑ Jₑᵀ + λ I)⁻¹ e`` with ``λ = damping·max(1, tr Jₑ Jₑᵀ) + μ‖e‖²``,
``q ← integrate(q, Δq)``.
Joint limits are not enforced here (callers check ranges and never clip silently).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from carmkin.errors import (
    NumericalIKError,  # noqa: F401 (defined there, raised here)
)
from carmkin.model.per_system import per_system
from carmkin.transforms import check_rigid_transform, pose_error

#: Default convergence threshold on the pose residual (m and rad).
TOLERANCE = 1e-9


@dataclass(frozen=True)
class DLSResult:
    """Outcome of one damped-least-squares run.

    ``q`` (nq,): the best iterate (smallest residual); ``residual``: max(position error (m), rotation angle (rad)) of its pose;
    ``position_error``, ``angle_error``: the two parts; ``iterations``; ``success``: residual ≤ tolerance.
    """

    q: np.ndarray
    residual: float
    position_error: float
    angle_error: float
    iterations: int
    success: bool


class DampedLeastSquares:
    """DLS IK of one frame of a Pinocchio model; build once per model (it holds a ``pin.Data``)."""

    def __init__(self, model: pin.Model, frame: str = "xray_source", damping: float = 1e-12, mu: float = 1e-3,
                 max_iterations: int = 100, tolerance: float = TOLERANCE, polish_steps: int = 2) -> None:
        if not model.existFrame(frame):
            raise NumericalIKError(f"model has no frame named {frame!r}")
        self.model, self.data = model, model.createData()
        self.frame_id = model.getFrameId(frame)
        self.damping, self.mu = damping, mu
        self.max_iterations, self.tolerance, self.polish_steps = max_iterations, tolerance, polish_steps

    def pose(self, q: np.ndarray) -> np.ndarray:
        """4x4 pose of the frame in the root frame for ``q``."""
        pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[self.frame_id].homogeneous

    def solve(self, T_target, q0) -> DLSResult:
        """Run DLS from ``q0`` (nq,) towards ``T_target`` (4x4); never raises on non-convergence."""
        T_target = check_rigid_transform(T_target, "T_target")
        q = np.array(q0, dtype=float)
        if q.shape != (self.model.nq,) or not np.all(np.isfinite(q)):
            raise NumericalIKError(f"q0 must be a finite vector of shape ({self.model.nq},), got {q.shape}")
        target = pin.SE3(T_target[:3, :3].copy(), T_target[:3, 3].copy())
        model, data, fid = self.model, self.data, self.frame_id
        eye = np.eye(6)
        iterations = polish = 0
        best = None
        while True:
            pin.framesForwardKinematics(model, data, q)
            dp, angle = pose_error(data.oMf[fid].homogeneous, T_target)
            residual = max(dp, angle)
            if best is None or residual < best[1]:
                best = (q, residual, dp, angle)
            if residual <= self.tolerance:  # converged: a few more steps polish the round-off
                polish += 1
            if polish > self.polish_steps or residual <= 1e-14 or iterations >= self.max_iterations:
                break
            iMd = data.oMf[fid].actInv(target)
            err = pin.log6(iMd).vector
            J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)
            J = -pin.Jlog6(iMd.inverse()) @ J
            JJt = J @ J.T
            lam = self.damping * max(1.0, float(np.trace(JJt))) + self.mu * float(err @ err)
            try:
                dq = -J.T @ np.linalg.solve(JJt + lam * eye, err)
            except np.linalg.LinAlgError:  # not finite (a seed far out): keep the best iterate
                break
            q = pin.integrate(model, q, dq)
            iterations += 1
        q, residual, dp, angle = best  # the best iterate, not the last one
        return DLSResult(q, residual, dp, angle, iterations, residual <= self.tolerance)


@per_system
def solver_for(system) -> DampedLeastSquares:
    """The :class:`DampedLeastSquares` of ``system``'s ``xray_source``, built once per system object
    (:func:`carmkin.model.per_system.per_system`; nothing is written into the frozen system)."""
    return DampedLeastSquares(system.pinocchio()[0])


def solve(system, T, q0) -> DLSResult:
    """DLS IK of ``xray_source`` of ``system`` from ``q0`` (nq,) to the pose ``T`` (4x4, table frame)."""
    return solver_for(system).solve(T, q0)
