"""One QP step of the IK, built and solved on its own (testable without the iteration).

For the step ``dq`` (nv,) at a kinematic state:

    minimise    sum_i w_i |r_i + J_i dq|^2 + lambda dq^T diag(joint_weights) dq
    subject to  lb <= dq <= ub                                (:class:`~carmkin.qp.limits.JointLimits`)
                G dq <= h      (task inequalities, :class:`~carmkin.qp.limits.CollisionAvoidance` rows)

with ``lambda = damping + error_damping * E`` and ``E = sum_i w_i |r_i|^2`` (Levenberg–Marquardt: small near
the solution, so convergence is quadratic). Handed to the backend as ``½ dq^T H dq + g^T dq`` (half the
objective, less its constant): ``H = sum_i w_i J_i^T J_i + lambda diag(joint_weights)``, ``g = sum_i w_i J_i^T r_i``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from carmkin.robot.state import KinematicState

from .limits import CollisionAvoidance, JointLimits
from .options import QPIKOptions

#: When leaving the margin in one step is infeasible, the fractions of the way out asked for instead (the
#: last, 0, asks for "not closer", for which dq = 0 is feasible).
ESCAPE_FRACTIONS = (0.5, 0.2, 0.05, 0.0)


@dataclass(frozen=True)
class StepQP:
    """The QP of one step: ``H`` (nv, nv), ``g`` (nv,), ``G`` (m, nv) and ``h`` (m,) or ``None``, bounds
    ``lb``/``ub`` (nv,), and the weighted task energy ``E`` at the state."""

    H: np.ndarray
    g: np.ndarray
    G: np.ndarray | None
    h: np.ndarray | None
    lb: np.ndarray
    ub: np.ndarray
    energy: float

    @property
    def bounds_consistent(self) -> bool:
        """False when the state lies farther outside the joint box than one step can repair."""
        return bool(np.all(self.lb <= self.ub))


def build_step(state: KinematicState, tasks: Sequence, limits: JointLimits,
               avoidance: CollisionAvoidance | None, joint_weights: np.ndarray, options: QPIKOptions) -> StepQP:
    """The step QP at ``state`` (Jacobians computed) for ``tasks``, ``limits`` and ``avoidance``."""
    model, data = state.model, state.data
    nv = model.nv
    H = np.zeros((nv, nv))
    g = np.zeros(nv)
    energy = 0.0
    G_rows, h_rows = [], []
    for task in tasks:
        J, r = task.residual(model, data)
        H += task.weight * (J.T @ J)
        g += task.weight * (J.T @ r)
        energy += task.weight * float(r @ r)
        rows = task.inequalities(model, data)
        if rows is not None:
            G_rows.append(rows[0])
            h_rows.append(rows[1])
    H.flat[:: nv + 1] += (options.damping + options.error_damping * energy) * joint_weights  # the diagonal
    if avoidance is not None:
        rows = avoidance.inequalities(state)
        if rows is not None:
            G_rows.append(rows[0])
            h_rows.append(rows[1])
    # one block (the usual case) as it is: stacking copies cost as much as building the rows
    G = (G_rows[0] if len(G_rows) == 1 else np.vstack(G_rows)) if G_rows else None
    h = (h_rows[0] if len(h_rows) == 1 else np.concatenate(h_rows)) if h_rows else None
    lb, ub = limits.bounds(state.q)
    return StepQP(H, g, G, h, lb, ub, energy)


def solve_step(backend, step: StepQP) -> np.ndarray | None:
    """The step ``dq`` (nv,) of ``step`` by ``backend``, or ``None`` when infeasible.

    When the rows that ask to leave the margin (``h < 0``) make it infeasible, asks for the fractions
    :data:`ESCAPE_FRACTIONS` of the way out instead; the following iterations keep pushing out.
    """
    dq = backend.solve(step.H, step.g, step.G, step.h, step.lb, step.ub)
    if dq is None and step.h is not None and np.any(step.h < 0):
        for fraction in ESCAPE_FRACTIONS:
            dq = backend.solve(step.H, step.g, step.G, np.where(step.h < 0, fraction * step.h, step.h), step.lb, step.ub)
            if dq is not None:
                break
    return dq
