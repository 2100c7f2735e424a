"""The QP IK iteration: build a step (:mod:`carmkin.qp.step`), solve it, shorten it, repeat.

Every step is shortened (halved, up to :data:`MAX_HALVINGS` times) until no pair ends closer than the
smaller of the margin and its current distance, which covers the linearisation error of the collision rows
and the pairs skipped by the broad phase. Iterations stop when every task is within tolerance and every
pair clears the margin (converged), when the step vanishes (stalled), when the QP is infeasible, or after
``max_iterations``. One :class:`~carmkin.robot.state.KinematicState` per iterate: forward kinematics,
Jacobians and distances once per configuration.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import pinocchio as pin

from carmkin.errors import InvalidConfigurationError
from carmkin.world import World
from carmkin.robot.state import KinematicState

from .backends import make_backend
from .limits import CollisionAvoidance, JointLimits
from .options import AT_LIMIT_TOLERANCE, QPIKError, QPIKOptions
from .redundant import check_weights
from .results import QPIKResult, RunStatus
from .step import build_step, solve_step
from .tasks import AimTask, FrameTask

#: Backtracking: a step is halved at most this many times before the run counts as blocked.
MAX_HALVINGS = 12
#: A shortened step may end this much (m) closer than ``min(margin, current distance)`` (round-off).
BACKTRACK_SLACK = 1e-9
#: Pairs reported as blocking: those within the margin plus this slack (m) when infeasible / stalled.
INFEASIBLE_SLACK, STALL_SLACK = 1e-6, 1e-4


class QPIK:
    """Reusable QP IK for ``model`` with ``tasks``, an optional :class:`carmkin.world.World` and a QP backend.

    Keeps one ``pin.Data``; change targets through the tasks' ``set_target`` and call :meth:`solve` again.
    Bounds are the model's position limits. ``backend``: a name (``None`` = the fastest installed) or a
    backend object of :mod:`carmkin.qp.backends` shared with other solves.

    ``joint_weights`` (nv,), positive: the regularisation becomes ``lambda · dq^T diag(w) dq``; on a
    redundant chain (more joints than task rows) each step then tends, as ``lambda -> 0``, to the
    least-norm step in the weighted norm ``sqrt(dq^T W dq)``, so joints with large weights move less.
    ``locked``: indices of joints held at their seed value (their step is bounded to 0).
    """

    def __init__(
        self,
        model: pin.Model,
        tasks: Sequence[FrameTask],
        world: World | None = None,
        backend=None,
        options: QPIKOptions = QPIKOptions(),
        joint_weights=None,
        locked: Sequence[int] = (),
    ) -> None:
        if model.nq != model.nv:
            raise QPIKError(f"the QP IK needs a model with nq == nv (vector joints); got nq={model.nq}, nv={model.nv}")
        if not tasks:
            raise QPIKError("at least one task is needed")
        self.model, self.tasks, self.world, self.options = model, list(tasks), world, options
        self.data = model.createData()
        self.limits = JointLimits(model.lowerPositionLimit, model.upperPositionLimit, options.max_step, locked)
        self.lower, self.upper, self.free = self.limits.lower, self.limits.upper, self.limits.free
        self.weights = np.ones(model.nv) if joint_weights is None else check_weights(joint_weights, model.nv)
        self.avoidance = (CollisionAvoidance(world, options.safety_margin, options.collision_gain,
                                             options.influence_distance) if world is not None and len(world) else None)
        rows = (len(world) if world else 0) + sum(2 for t in self.tasks if isinstance(t, AimTask))
        if backend is None or isinstance(backend, str):
            backend = make_backend(backend, model.nv, rows)
        elif getattr(backend, "max_rows", rows) < rows:
            raise QPIKError(f"the shared QP backend holds {backend.max_rows} inequality rows, {rows} needed")
        self.backend = backend
        self._joint_of_q = [""] * model.nq  # name of the joint each coordinate of q belongs to
        for j in range(1, model.njoints):
            for k in range(model.joints[j].idx_q, model.joints[j].idx_q + model.joints[j].nq):
                self._joint_of_q[k] = model.names[j]
        self.last_state: KinematicState | None = None

    def state(self, q: np.ndarray) -> KinematicState:
        """The kinematic state at ``q`` with Jacobians and this solver's world (reuses one ``pin.Data``)."""
        return KinematicState(self.model, q, self.world, jacobians=True, data=self.data)

    def errors(self, state: KinematicState) -> tuple[float, float, bool]:
        """(largest position error m, largest angle error rad, every task within tolerance) at ``state``."""
        o = self.options
        errors = [t.errors(state.data, o.position_tolerance, o.angle_tolerance) for t in self.tasks]
        return max(e.position for e in errors), max(e.angle for e in errors), all(e.satisfied for e in errors)

    def converged(self, state: KinematicState) -> bool:
        """The stop test: every task within tolerance and every pair clear of the margin."""
        return self.errors(state)[2] and self._clear(state)

    def _clear(self, state: KinematicState) -> bool:
        return self.avoidance is None or self.avoidance.clear(state)

    def _pairs(self, state: KinematicState, slack: float) -> tuple[str, ...]:
        return () if self.avoidance is None else self.avoidance.near_pairs(state.distances, slack)

    def solve(self, q0, record: bool = False, seed: str = "q0") -> QPIKResult:
        """Iterate from ``q0`` (nq,) until the tasks converge; see the module docstring."""
        o, model = self.options, self.model
        q = np.array(q0, dtype=float)
        if q.shape != (model.nq,) or not np.all(np.isfinite(q)):
            raise InvalidConfigurationError(f"q0 must be a finite vector of shape ({model.nq},), got {q.shape}")
        history = [q.copy()] if record else None
        min_distance = np.inf
        status, details = RunStatus.CONVERGED, {}
        iteration = 0
        state = self.state(q)
        energies = []  # task energy E at each iterate, for the progress test
        while True:
            min_distance = min(min_distance, state.min_distance)  # the seed, then every accepted iterate
            position_error, angle_error, done = self.errors(state)
            if done and self._clear(state):
                break
            if iteration >= o.max_iterations:
                status = RunStatus.MAX_ITERATIONS
                break
            step = build_step(state, self.tasks, self.limits, self.avoidance, self.weights, o)
            energies.append(step.energy)
            window = int(o.progress_window)
            if len(energies) > window and step.energy > o.progress_ratio * energies[-1 - window]:
                status = RunStatus.STALLED
                limits = self.limits.at_limits(state.q, AT_LIMIT_TOLERANCE)
                details = {"pairs": self._pairs(state, STALL_SLACK), "no_progress": True,
                           "joints_at_limits": tuple(dict.fromkeys(self._joint_of_q[int(j)] for j in limits))}
                break
            if not step.bounds_consistent:
                status = RunStatus.OUTSIDE_LIMITS
                break
            dq = solve_step(self.backend, step)
            if dq is None:
                status, details = RunStatus.INFEASIBLE, {"pairs": self._pairs(state, INFEASIBLE_SLACK)}
                break
            dq[~self.free] = 0.0  # a solver may return ~1e-17 for a variable bounded to [0, 0]
            iteration += 1
            new = self._backtrack(state, dq)
            if new is None:
                status, details = RunStatus.BLOCKED, {"pairs": self._pairs(state, STALL_SLACK)}
                state = self.state(state.q)  # data back to the last iterate
                break
            state, dq = new
            if record:
                history.append(state.q.copy())
            if np.max(np.abs(dq)) < o.stall_step:
                min_distance = min(min_distance, state.min_distance)
                position_error, angle_error, done = self.errors(state)
                if not (done and self._clear(state)):
                    status = RunStatus.INSIDE_MARGIN if done else RunStatus.STALLED
                    limits = self.limits.at_limits(state.q, AT_LIMIT_TOLERANCE)
                    details = {"pairs": self._pairs(state, STALL_SLACK),
                               "joints_at_limits": tuple(dict.fromkeys(self._joint_of_q[int(j)] for j in limits))}
                break
        self.last_state = state
        return QPIKResult(q=state.q, status=status, iterations=iteration, position_error=position_error,
                          angle_error=angle_error, min_distance=min_distance,
                          history=np.array(history) if record else None, seed=seed, **details)

    def _backtrack(self, state: KinematicState, dq: np.ndarray):
        """Halve ``dq`` until no pair ends closer than ``min(margin, its current distance)``. Returns
        ``(new state, dq)``, or ``None`` when :data:`MAX_HALVINGS` halvings do not suffice."""
        floor = None
        if self.avoidance is not None:
            floor = np.minimum(state.distances, self.options.safety_margin) - BACKTRACK_SLACK
        for _ in range(MAX_HALVINGS):
            new = self.state(self.limits.project(state.q + dq))
            if floor is None or np.all(new.distances >= floor):
                return new, dq
            dq = 0.5 * dq
        return None
