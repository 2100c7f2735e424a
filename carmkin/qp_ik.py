"""QP-based inverse kinematics with joint limits and collision avoidance, and the hybrid solve.

Each iteration solves, for the step ``dq`` (nv,) of any Pinocchio model with ``nq == nv``,

    minimise    sum_i w_i |r_i + J_i dq|^2 + lambda |dq|^2          (tasks, :mod:`carmkin.qp.tasks`)
    subject to  lower - q <= dq <= upper - q,  |dq|_inf <= max_step     (joint limits, trust region)
                -grad d_k · dq <= gain (d_k - margin)   for pairs k with d_k < influence distance

``lambda = damping + error_damping * E`` with ``E = sum_i w_i |r_i|^2`` (Levenberg–Marquardt: small near the
solution, so convergence is quadratic). The collision rows are the discrete velocity damper of Faverjon &
Tournassoud: a step may close at most the fraction ``gain`` of the gap to the safety margin; a pair already
inside the margin must leave it in one (linearised) step, ``-grad d_k · dq <= d_k - margin``. ``grad d``
comes from coal witness points and normals (:meth:`carmkin.robot.collision.CollisionScene.distance_jacobian`);
pairs farther than ``influence_distance`` are skipped (broad phase). Every step is shortened (halved, up to
12 times) until no pair ends closer than the smaller of the margin and its current distance, which covers
the linearisation error of the rows and the pairs skipped by the broad phase. Iterations stop when every
task is within tolerance and every pair clears the margin (success), when the step vanishes (stalled), when
the QP is infeasible, or after ``max_iterations``.

:func:`solve` is the hybrid of the ``carmkin.qp_ik.solve`` contract: closed-form branches first, the QP
seeded from them and from ``q_current`` when no branch is valid.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import pinocchio as pin
import qpsolvers
import scipy.sparse as sp

from carmkin.errors import CarmkinError, InvalidConfigurationError
from carmkin.qp.tasks import AimTask, AxisTask, FrameTask, PoseTask
from carmkin.robot.collision import CollisionScene, Obstacle
from carmkin.transforms import check_rigid_transform

#: Backends in order of preference, fastest first as measured by ``benchmarks/bench_qp_ik.py`` (all reliable
#: there); ``None`` as backend means the first one installed. osqp is a core dependency, the others come
#: with the ``solvers`` extra.
BACKENDS = ("daqp", "quadprog", "proxqp", "osqp")


def default_backend() -> str:
    """The first installed backend of :data:`BACKENDS`."""
    for name in BACKENDS:
        if name in qpsolvers.available_solvers:
            return name
    raise QPIKError(f"none of the QP backends {BACKENDS} is installed")
#: A run counts as clear of obstacles when every pair is at least ``safety_margin - MARGIN_TOLERANCE`` apart (m).
MARGIN_TOLERANCE = 1e-6
#: Frame of the X-ray source, the end effector of the C-arm chain.
SOURCE_FRAME = "xray_source"


class QPIKError(CarmkinError):
    """Bad input to the QP IK (unsupported model, unknown backend, bad option, bad target)."""


# --- QP backends ------------------------------------------------------------------------------------------
class QpsolversBackend:
    """A QP solver through :func:`qpsolvers.solve_qp` (daqp, quadprog, proxqp, ...)."""

    def __init__(self, name: str, nv: int, max_rows: int) -> None:
        if name not in qpsolvers.available_solvers:
            raise QPIKError(f"QP backend {name!r} is not installed; available: {sorted(qpsolvers.available_solvers)}")
        self.name = name
        self.options = {"eps_abs": 1e-12, "eps_rel": 0.0} if name == "proxqp" else {}

    def solve(self, H, g, G, h, lb, ub) -> np.ndarray | None:
        if G is not None and G.shape[0] == 0:
            G = h = None
        return qpsolvers.solve_qp(H, g, G, h, lb=lb, ub=ub, solver=self.name, **self.options)


class OSQPBackend:
    """OSQP with one persistent workspace: fixed sparsity, ``update()`` + ``solve()`` with warm start.

    Constraint matrix ``[I; G_pad]`` with ``max_rows`` dense rows of which unused ones get infinite bounds.
    Tolerances 1e-10 and solution polishing give steps exact enough for 1e-6 convergence; a step may leave
    the bounds by the solver tolerance only, and is projected back (a larger violation is a failure).
    """

    name = "osqp"
    SETTINGS = dict(eps_abs=1e-10, eps_rel=1e-10, polishing=False, max_iter=20000, verbose=False, warm_starting=True)

    def __init__(self, name: str, nv: int, max_rows: int) -> None:
        import osqp

        self.nv, self.max_rows = nv, max_rows
        P = sp.csc_matrix(np.triu(np.ones((nv, nv))))
        self._p_rows = P.indices.copy()
        self._p_cols = np.repeat(np.arange(nv), np.diff(P.indptr))
        A = sp.csc_matrix(np.ones((nv + max_rows, nv)))
        self._G = np.zeros((max_rows, nv))
        self._l = np.full(nv + max_rows, -np.inf)
        self._u = np.full(nv + max_rows, np.inf)
        A.data[:] = self._a_data()
        self.solver = osqp.OSQP()
        self.solver.setup(sp.csc_matrix((np.ones(P.nnz), P.indices, P.indptr), shape=(nv, nv)), np.zeros(nv), A,
                          self._l, self._u, **self.SETTINGS)

    def _a_data(self) -> np.ndarray:
        return np.vstack((np.eye(self.nv), self._G)).ravel(order="F")

    def solve(self, H, g, G, h, lb, ub) -> np.ndarray | None:
        m = 0 if G is None else G.shape[0]
        if m > self.max_rows:
            raise QPIKError(f"OSQP workspace holds {self.max_rows} inequality rows, got {m}")
        self._G[:] = 0.0
        self._l[:] = -np.inf
        self._u[:] = np.inf
        self._l[: self.nv], self._u[: self.nv] = lb, ub
        if m:
            self._G[:m] = G
            self._u[self.nv : self.nv + m] = h
        self.solver.update(q=g, l=self._l, u=self._u, Px=H[self._p_rows, self._p_cols], Ax=self._a_data())
        result = self.solver.solve(raise_error=False)
        if result.info.status_val != 1 or result.x is None or not np.all(np.isfinite(result.x)):
            return None
        x = result.x
        if np.any(x < lb - 1e-7) or np.any(x > ub + 1e-7):
            return None
        return np.clip(x, lb, ub)


def make_backend(name: str | None, nv: int, max_rows: int):
    """The backend ``name`` (``None`` = :func:`default_backend`) for ``nv`` variables."""
    name = default_backend() if name is None else name
    if name == "osqp":
        return OSQPBackend(name, nv, max_rows)
    return QpsolversBackend(name, nv, max_rows)


# --- options and results ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class QPIKOptions:
    """Settings of the QP IK (SI units).

    position_tolerance (m), angle_tolerance (rad): convergence test on every task. max_iterations.
    damping, error_damping: ``lambda = damping + error_damping * E``. max_step: bound on each |dq_i|
    (m or rad) per iteration. safety_margin (m): minimum distance kept between collision pairs.
    influence_distance (m): pairs farther than this add no constraint (broad phase). collision_gain in
    (0, 1]: fraction of the gap to the margin one step may close. stall_step: a step below this
    (inf-norm) without convergence stops the iteration as stalled.
    """

    position_tolerance: float = 1e-6
    angle_tolerance: float = 1e-6
    max_iterations: int = 100
    damping: float = 1e-10
    error_damping: float = 1e-3
    max_step: float = 0.3
    safety_margin: float = 0.01
    influence_distance: float = 0.1
    collision_gain: float = 0.5
    stall_step: float = 1e-12

    def __post_init__(self) -> None:
        positive = ("position_tolerance", "angle_tolerance", "max_step", "influence_distance", "collision_gain",
                    "stall_step", "error_damping", "damping")
        for name in positive:
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise QPIKError(f"QPIKOptions.{name} must be finite and > 0, got {value}")
        if not (np.isfinite(self.safety_margin) and self.safety_margin >= 0):
            raise QPIKError(f"QPIKOptions.safety_margin must be finite and >= 0 (m), got {self.safety_margin}")
        if self.collision_gain > 1:
            raise QPIKError(f"QPIKOptions.collision_gain must be in (0, 1], got {self.collision_gain}")
        if self.influence_distance <= self.safety_margin:
            raise QPIKError("QPIKOptions.influence_distance must exceed safety_margin")
        if int(self.max_iterations) < 1:
            raise QPIKError(f"QPIKOptions.max_iterations must be >= 1, got {self.max_iterations}")


@dataclass
class QPIKResult:
    """Outcome of one QP IK run from one seed.

    ``q`` (nq,) last iterate; ``success``; ``reason`` (why it failed, ``None`` on success); ``iterations``;
    ``position_error`` (m) and ``angle_error`` (rad), the largest over the tasks; ``min_distance``: the
    smallest pair distance seen over all iterates including the seed (m, ``inf`` without pairs);
    ``history`` (iterations+1, nq) when recorded; ``seed`` names the start.
    """

    q: np.ndarray
    success: bool
    reason: str | None
    iterations: int
    position_error: float
    angle_error: float
    min_distance: float
    history: np.ndarray | None = None
    seed: str = "q0"


class QPIK:
    """Reusable QP IK for ``model`` with ``tasks``, an optional :class:`CollisionScene` and a QP backend.

    Keeps one ``pin.Data`` and the scene's ``GeometryData``; change targets through the tasks'
    ``set_target`` and call :meth:`solve` again. Bounds are the model's position limits.

    ``joint_weights`` (nv,), positive: the regularisation becomes ``lambda · dq^T diag(w) dq``; on a
    redundant chain (more joints than task rows) each step then tends, as ``lambda -> 0``, to the
    least-norm step in the weighted norm ``sqrt(dq^T W dq)``, so joints with large weights move less.
    ``locked``: indices of joints held at their seed value (their step is bounded to 0).
    """

    def __init__(
        self,
        model: pin.Model,
        tasks: Sequence[FrameTask],
        scene: CollisionScene | None = None,
        backend: str | None = None,
        options: QPIKOptions = QPIKOptions(),
        joint_weights=None,
        locked: Sequence[int] = (),
    ) -> None:
        if model.nq != model.nv:
            raise QPIKError(f"the QP IK needs a model with nq == nv (vector joints); got nq={model.nq}, nv={model.nv}")
        if not tasks:
            raise QPIKError("at least one task is needed")
        self.model, self.tasks, self.scene, self.options = model, list(tasks), scene, options
        self.data = model.createData()
        self.lower = np.array(model.lowerPositionLimit, dtype=float)
        self.upper = np.array(model.upperPositionLimit, dtype=float)
        self.weights = np.ones(model.nv) if joint_weights is None else _check_weights(joint_weights, model.nv)
        self.free = np.ones(model.nv, dtype=bool)
        for index in locked:
            if not 0 <= int(index) < model.nv:
                raise QPIKError(f"locked joint index {index} outside 0..{model.nv - 1}")
            self.free[int(index)] = False
        extra_rows = sum(2 for t in self.tasks if isinstance(t, AimTask))
        self.backend = make_backend(backend, model.nv, (len(scene) if scene else 0) + extra_rows)

    def _evaluate(self, q: np.ndarray):
        """Forward kinematics, Jacobians and distances at q; returns (distances or None)."""
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        if self.scene is None or not len(self.scene):
            return None
        return self.scene.distances(self.data)

    def _errors(self):
        o = self.options
        errors = [t.errors(self.data, o.position_tolerance, o.angle_tolerance) for t in self.tasks]
        return (max(e.position for e in errors), max(e.angle for e in errors), all(e.satisfied for e in errors))

    def solve(self, q0, record: bool = False, seed: str = "q0") -> QPIKResult:
        """Iterate from ``q0`` (nq,) until the tasks converge; see the module docstring."""
        o, model = self.options, self.model
        q = np.array(q0, dtype=float)
        if q.shape != (model.nq,) or not np.all(np.isfinite(q)):
            raise InvalidConfigurationError(f"q0 must be a finite vector of shape ({model.nq},), got {q.shape}")
        history = [q.copy()] if record else None
        min_distance = np.inf
        reason = None
        iteration = 0
        q_last = q
        nv = model.nv
        distances = self._evaluate(q)
        while True:
            if distances is not None and distances.size:  # the seed, then every accepted iterate
                min_distance = min(min_distance, float(distances.min()))
            position_error, angle_error, done = self._errors()
            if done and self._clear(distances):
                break
            if iteration >= o.max_iterations:
                reason = (f"not converged after {iteration} iterations "
                          f"(errors {position_error:.3g} m, {angle_error:.3g} rad)")
                break
            H = np.zeros((nv, nv))
            g = np.zeros(nv)
            energy = 0.0
            G_rows, h_rows = [], []
            for task in self.tasks:
                J, r = task.residual(model, self.data)
                H += task.weight * (J.T @ J)
                g += task.weight * (J.T @ r)
                energy += task.weight * float(r @ r)
                rows = task.inequalities(model, self.data)
                if rows is not None:
                    G_rows.append(rows[0])
                    h_rows.append(rows[1])
            H += (o.damping + o.error_damping * energy) * np.diag(self.weights)
            if distances is not None:
                near = self.scene.proximity(distances, o.influence_distance)
                if near.index.size:
                    G_rows.append(-self.scene.distance_jacobian(near, self.data.J))
                    gap = near.distance - o.safety_margin
                    h_rows.append(np.where(gap >= 0, o.collision_gain * gap, gap))  # inside the margin: get out
            G = np.vstack(G_rows) if G_rows else None
            h = np.concatenate(h_rows) if h_rows else None
            lb = np.maximum(self.lower - q, -o.max_step)
            ub = np.minimum(self.upper - q, o.max_step)
            lb[~self.free] = ub[~self.free] = 0.0  # locked joints stay where the seed put them
            if np.any(lb > ub):
                reason = "start configuration lies outside the joint limits by more than max_step"
                break
            dq = self.backend.solve(H, g, G, h, lb, ub)
            if dq is None and h is not None and np.any(h < 0):
                # Getting out of the margin in one step is infeasible: ask for a fraction of the way out, down
                # to "not closer" (dq = 0 is then feasible); the following iterations keep pushing out.
                for fraction in (0.5, 0.2, 0.05, 0.0):
                    dq = self.backend.solve(H, g, G, np.where(h < 0, fraction * h, h), lb, ub)
                    if dq is not None:
                        break
            if dq is None:
                reason = self._infeasible_reason(iteration, distances)
                break
            dq[~self.free] = 0.0  # a solver may return ~1e-17 for a variable bounded to [0, 0]
            iteration += 1
            q, dq, distances = self._accept(q, dq, distances)
            if q is None:
                reason = (f"step blocked at iteration {iteration}: every shortened step breaks the safety margin "
                          f"({', '.join(self._near_pairs(distances, 1e-4))})")
                q = q_last
                break
            q_last = q
            if record:
                history.append(q.copy())
            if np.max(np.abs(dq)) < o.stall_step:
                if distances is not None and distances.size:
                    min_distance = min(min_distance, float(distances.min()))
                position_error, angle_error, done = self._errors()
                if not (done and self._clear(distances)):
                    reason = self._stall_reason(q, position_error, angle_error, done)
                break
        return QPIKResult(
            q=q,
            success=reason is None,
            reason=reason,
            iterations=iteration,
            position_error=position_error,
            angle_error=angle_error,
            min_distance=min_distance,
            history=np.array(history) if record else None,
            seed=seed,
        )

    def _clear(self, distances) -> bool:
        """Every pair at least the safety margin apart (up to :data:`MARGIN_TOLERANCE`)."""
        if distances is None or not distances.size:
            return True
        return distances.min() >= self.options.safety_margin - MARGIN_TOLERANCE

    def _accept(self, q, dq, distances):
        """Backtracking on the linearisation error of the collision rows: halve ``dq`` until no pair ends
        closer than ``min(margin, its current distance)``. Returns ``(q_new, dq, distances at q_new)``, the
        new point's kinematics left in ``self.data``; ``q_new`` is None when 12 halvings do not suffice."""
        floor = None if distances is None else np.minimum(distances, self.options.safety_margin) - 1e-9
        for _ in range(12):
            q_new = np.clip(q + dq, self.lower, self.upper)  # removes floating-point residue only
            new = self._evaluate(q_new)
            if floor is None or np.all(new >= floor):
                return q_new, dq, new
            dq = 0.5 * dq
        self._evaluate(q)
        return None, dq, distances

    def _near_pairs(self, distances, slack: float) -> list[str]:
        if distances is None:
            return []
        limit = self.options.safety_margin + slack
        return [f"{a}/{b}" for k, (a, b) in enumerate(self.scene.pairs) if distances[k] < limit]

    def _infeasible_reason(self, iteration: int, distances) -> str:
        blocked = self._near_pairs(distances, 1e-6)
        where = f" (pairs inside the margin: {', '.join(blocked)})" if blocked else ""
        return f"QP infeasible at iteration {iteration}{where}"

    def _stall_reason(self, q, position_error, angle_error, task_done: bool = False) -> str:
        at_limit = [self.model.names[j] for j in range(1, self.model.njoints)
                    if self.model.joints[j].nq == 1
                    and (abs(q[self.model.joints[j].idx_q] - self.lower[self.model.joints[j].idx_q]) < 1e-9
                         or abs(q[self.model.joints[j].idx_q] - self.upper[self.model.joints[j].idx_q]) < 1e-9)]
        distances = self.scene.distances(self.data) if self.scene is not None and len(self.scene) else None
        blocked = self._near_pairs(distances, 1e-4)
        why = []
        if at_limit:
            why.append("joints at limits: " + ", ".join(at_limit))
        if blocked:
            why.append("collision pairs at or inside the safety margin: " + ", ".join(blocked))
        if task_done:
            return ("target reached only inside the safety margin, no way out found ("
                    + "; ".join(why or ["pairs inside the margin"]) + ")")
        return (f"stalled with errors {position_error:.3g} m, {angle_error:.3g} rad"
                + (f" ({'; '.join(why)})" if why else " (local minimum)"))


# --- targets of the C-arm ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class AxisTarget:
    """Source position (m) and principal-axis direction in the table frame; roll about the axis free."""

    position: tuple[float, float, float]
    direction: tuple[float, float, float]


@dataclass(frozen=True)
class AimTarget:
    """The principal axis passes through ``point`` (m, table frame) at a source distance in ``distance_range``."""

    point: tuple[float, float, float]
    distance_range: tuple[float, float]


def make_task(model: pin.Model, target, frame: str = SOURCE_FRAME) -> FrameTask:
    """The task of a target: a 4x4 pose → :class:`PoseTask`, :class:`AxisTarget`, :class:`AimTarget`."""
    if isinstance(target, AxisTarget):
        return AxisTask(model, frame, target.position, target.direction)
    if isinstance(target, AimTarget):
        return AimTask(model, frame, target.point, target.distance_range)
    try:
        return PoseTask(model, frame, target)
    except CarmkinError as exc:
        raise QPIKError(f"target must be a 4x4 pose, an AxisTarget or an AimTarget: {exc}") from exc


def _closed_form_pose(system, target, q_ref: np.ndarray) -> np.ndarray:
    """A full pose for the closed form: the target itself, or for 5-DOF/aim targets the pose reached from
    the reference configuration's source pose with the least rotation (roll kept)."""
    if not isinstance(target, (AxisTarget, AimTarget)):
        return check_rigid_transform(target, "target")
    T_ref = system.fk(q_ref)
    if isinstance(target, AxisTarget):
        position, direction = np.asarray(target.position, float), np.asarray(target.direction, float)
        direction = direction / np.linalg.norm(direction)
    else:
        point = np.asarray(target.point, float)
        w = point - T_ref[:3, 3]
        direction = w / np.linalg.norm(w) if np.linalg.norm(w) > 1e-12 else T_ref[:3, 2]
        lo, hi = target.distance_range
        distance = float(np.clip(np.linalg.norm(w), lo, hi))  # a seed pose only: the QP enforces the range
        position = point - distance * direction
    z = T_ref[:3, 2]
    axis = np.cross(z, direction)
    s, c = np.linalg.norm(axis), float(z @ direction)
    if s > 1e-12:
        R_align = pin.exp3(axis / s * np.arctan2(s, c))
    else:  # parallel: nothing to do, or a half turn about the source's X axis
        R_align = np.eye(3) if c > 0 else pin.exp3(np.pi * T_ref[:3, 0])
    T = np.eye(4)
    T[:3, :3] = R_align @ T_ref[:3, :3]
    T[:3, 3] = position
    return T


@dataclass
class SolveResult:
    """Outcome of the hybrid :func:`solve`.

    ``q`` (nq,): the answer; when ``success`` is False, the QP attempt closest to the target among those in
    range and collision-free (never a colliding one), or NaN when there is none; ``success``; ``path``:
    ``"closed_form"`` or ``"qp"`` (the path of ``q``); ``seed``: the closed-form branch or ``"q_current"``
    the QP started from; ``reason``: why it failed (``None`` on success); ``validity``: the
    :class:`~carmkin.robot.validity.ValidityReport` of ``q`` (``None`` for NaN); ``closed_form``: the analytic
    result (or ``None``);
    ``branch_reports``: validity of each closed-form branch; ``attempts``: the QP runs.
    """

    q: np.ndarray
    success: bool
    path: str
    seed: str | None
    reason: str | None
    validity: object
    closed_form: object = None
    branch_reports: list = field(default_factory=list)
    attempts: list[QPIKResult] = field(default_factory=list)


def solve(
    system,
    target,
    q_current=None,
    obstacles: Sequence[Obstacle] = (),
    options: QPIKOptions = QPIKOptions(),
    backend: str | None = None,
    record: bool = False,
) -> SolveResult:
    """Joint values (nq,) of ``system`` that put ``xray_source`` on ``target`` without collision.

    ``target``: a 4x4 pose in the table frame, an :class:`AxisTarget` (position + principal-axis
    direction, roll free) or an :class:`AimTarget`. ``q_current`` (nq,): current joints, used to choose
    among branches (and, for 5-DOF/aim targets, the roll of the closed-form pose) and as a QP seed.
    ``obstacles``: extra bodies in the table frame (e.g. the patient). First the closed-form branches of
    :mod:`carmkin.analytic_ik` are checked (joints in range, every pair at least ``safety_margin`` apart,
    pose residual within tolerance); the first valid one is returned with ``path="closed_form"``. When none
    is valid, the QP starts from each branch (projected onto the joint box) and from ``q_current``, and
    the first converged, collision-free run is returned with ``path="qp"``.
    """
    from carmkin.robot import validity

    model = system.pinocchio()[0]
    task = make_task(model, target)
    scene = CollisionScene.from_system(system, obstacles)
    lower, upper = np.array(model.lowerPositionLimit), np.array(model.upperPositionLimit)
    if q_current is not None:
        q_current = np.asarray(q_current, dtype=float)
        if q_current.shape != (model.nq,) or not np.all(np.isfinite(q_current)):
            raise InvalidConfigurationError(
                f"q_current must be a finite vector of shape ({model.nq},), got {q_current.shape}"
            )
    q_ref = q_current if q_current is not None else 0.5 * (lower + upper)
    margin = options.safety_margin

    def check(q):
        return validity.check(system, q, margin=margin, scene=scene)

    seeds: list[tuple[str, np.ndarray]] = []
    reasons: list[str] = []
    branch_reports = []
    closed = None
    try:
        from . import analytic_ik
    except ImportError:
        analytic_ik = None
        reasons.append("closed form unavailable (carmkin.analytic_ik missing)")
    if analytic_ik is not None:
        try:
            closed = analytic_ik.solve(system, _closed_form_pose(system, target, q_ref), q_current=q_current)
        except CarmkinError as exc:
            reasons.append(f"closed form failed: {exc}")
    if closed is not None:
        chosen = int(closed.chosen) if getattr(closed, "chosen", None) is not None else 0
        order = [chosen] + [k for k in range(len(closed.solutions)) if k != chosen]
        for k in order:
            q_k = np.asarray(closed.solutions[k], dtype=float)
            name = f"branch {k}"
            if not np.all(np.isfinite(q_k)):
                reasons.append(f"{name}: no finite solution")
                continue
            report = check(q_k)
            branch_reports.append((k, report))
            problems = [r for r in report.reasons if not r.startswith("table not in")]
            task_ok = _task_satisfied(model, task, q_k, options)
            if not problems and task_ok:
                return SolveResult(q_k, True, "closed_form", name, None, report, closed, branch_reports)
            if not task_ok:
                problems.append("closed-form residual above tolerance")
            reasons.append(f"{name}: " + "; ".join(problems))
            seeds.append((name, np.clip(q_k, lower, upper)))
    q_start = np.clip(q_ref, lower, upper)
    if not any(np.array_equal(q_start, q0) for _, q0 in seeds):  # q_current often is the chosen branch
        seeds.append(("q_current" if q_current is not None else "mid-range", q_start))

    qp = QPIK(model, [task], scene, backend=backend, options=options)
    attempts = []
    for name, q0 in seeds:
        run = qp.solve(q0, record=record, seed=name)
        attempts.append(run)
        if run.success:
            report = check(run.q)
            if report.reachable:
                return SolveResult(run.q, True, "qp", name, None, report, closed, branch_reports, attempts)
            run.success = False
            run.reason = "converged to an invalid configuration: " + "; ".join(report.reasons)
        reasons.append(f"QP from {name}: {run.reason}")
    # Never hand back a colliding or out-of-range answer: the closest attempt that is reachable, else NaN.
    safe = [(r, rep) for r in attempts for rep in [check(r.q)] if rep.reachable]
    if safe:
        best, report = min(safe, key=lambda item: item[0].position_error + item[0].angle_error)
        q_out, seed = best.q, best.seed
    else:
        q_out, seed, report = np.full(model.nq, np.nan), None, None
    return SolveResult(q_out, False, "qp", seed, " | ".join(reasons), report, closed, branch_reports, attempts)


def _task_satisfied(model: pin.Model, task: FrameTask, q: np.ndarray, options: QPIKOptions) -> bool:
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return task.errors(data, options.position_tolerance, options.angle_tolerance).satisfied


# --- redundant chains: weighted minimal motion (multi-DOF tables, issue 9) ---------------------------------
#: Weight ratio of :func:`joint_weights` ``prefer``: the non-preferred group's joints cost this much more.
PREFERENCE_RATIO = 100.0


def _check_weights(weights, nv: int) -> np.ndarray:
    w = np.asarray(weights, dtype=float)
    if w.shape != (nv,) or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise QPIKError(f"joint_weights must be {nv} finite positive numbers, got {weights!r}")
    return w


def is_table_joint(name: str) -> bool:
    """True for the table's joints (``table_translation`` and the extra ones), False for the C-arm's."""
    return name.startswith("table_")


def joint_weights(system, weights=None, prefer: str | None = None) -> np.ndarray:
    """Per-joint weights (nq,) of the regularisation ``dq^T diag(w) dq`` (m⁻² or rad⁻²; 1 m ~ 1 rad).

    ``weights``: ``None`` (all 1), a sequence (nq,) in the order of ``system.joint_names``, or a dict by
    joint name (unnamed joints keep 1). ``prefer``: ``"table"`` multiplies the C-arm joints' weights by
    :data:`PREFERENCE_RATIO` (the table does the moving), ``"carm"`` the table joints' weights; ``None``
    leaves them.
    """
    names = system.joint_names
    if weights is None:
        w = np.ones(len(names))
    elif isinstance(weights, dict):
        unknown = set(weights) - set(names)
        if unknown:
            raise QPIKError(f"joint_weights names unknown joint(s) {sorted(unknown)}; joints: {', '.join(names)}")
        w = np.array([float(weights.get(n, 1.0)) for n in names])
    else:
        w = np.asarray(weights, dtype=float)
    w = _check_weights(w, len(names))
    if prefer is None:
        return w
    if prefer not in ("table", "carm"):
        raise QPIKError(f"prefer must be 'table', 'carm' or None, got {prefer!r}")
    penalised = np.array([is_table_joint(n) == (prefer == "carm") for n in names])
    return np.where(penalised, PREFERENCE_RATIO * w, w)


def locked_indices(system, free: Sequence[str] | None) -> list[int]:
    """Indices of the joints not named in ``free`` (``None``: every joint free)."""
    if free is None:
        return []
    unknown = set(free) - set(system.joint_names)
    if unknown:
        raise QPIKError(f"free names unknown joint(s) {sorted(unknown)}; joints: {', '.join(system.joint_names)}")
    return [k for k, n in enumerate(system.joint_names) if n not in free]


def solve_redundant(
    system,
    target,
    q_current=None,
    obstacles: Sequence[Obstacle] = (),
    options: QPIKOptions = QPIKOptions(),
    weights=None,
    prefer: str | None = None,
    free: Sequence[str] | None = None,
    extra_seeds: Sequence = (),
    backend: str | None = None,
    closed_form_seeds: bool = True,
    random_seeds: int = 0,
    rng_seed: int = 0,
) -> SolveResult:
    """IK of a system with any number of joints (e.g. the 11 of a motorized table) by the QP alone.

    ``target`` as in :func:`solve`. Among the infinitely many solutions of a redundant chain the QP, seeded
    at ``q_current`` (default: mid-range of the free joints, the locked ones at 0), moves little in the
    weighted norm of :func:`joint_weights` (``weights``, ``prefer``). ``free``: names of the joints that may
    move; the others are held at their value in ``q_current`` (0 by default). When the run from ``q_current``
    fails, further seeds are tried in order: ``extra_seeds`` (k, nq); with ``closed_form_seeds`` both
    branches of the single-axis closed form (:func:`carmkin.analytic.single_axis.solve_single_axis`, ``table_translation``
    active, the other table joints held at ``q_current``, when ``table_translation`` is free; for axis and aim
    targets on the pose of :func:`_closed_form_pose`); then ``random_seeds`` uniform draws over the free joints' ranges (``numpy`` seed ``rng_seed``). Limits and collisions as in :class:`QPIK`; the answer is
    checked by :func:`carmkin.robot.validity.check` (joints in range, every pair at least the safety margin
    apart; the table-in-cone condition is reported in ``validity`` but not required).
    """
    from carmkin.robot import validity

    model = system.pinocchio()[0]
    lower, upper = np.array(model.lowerPositionLimit), np.array(model.upperPositionLimit)
    locked = locked_indices(system, free)
    if q_current is None:
        q_current = 0.5 * (lower + upper)
        q_current[locked] = 0.0
    q_current = np.asarray(q_current, dtype=float)
    if q_current.shape != (model.nq,) or not np.all(np.isfinite(q_current)):
        raise InvalidConfigurationError(f"q_current must be a finite vector of shape ({model.nq},), got {q_current.shape}")
    scene = CollisionScene.from_system(system, obstacles)
    qp = QPIK(model, [make_task(model, target)], scene, backend=backend, options=options,
              joint_weights=joint_weights(system, weights, prefer), locked=locked)
    seeds = [("q_current", q_current)]
    for k, s in enumerate(extra_seeds):
        seeds.append((f"seed {k}", np.array(s, dtype=float)))
    if closed_form_seeds and 0 not in locked:
        try:
            from carmkin.analytic.single_axis import solve_single_axis

            pose = _closed_form_pose(system, target, q_current)  # roll of a 5-DOF target: least rotation
            single = solve_single_axis(system, pose, "table_translation", q_current)
            seeds += [(f"closed-form branch {k}", q) for k, q in enumerate(single.solutions) if np.all(np.isfinite(q))]
        except CarmkinError:
            pass
    rng = np.random.default_rng(rng_seed)
    seeds += [(f"random {k}", rng.uniform(lower, upper)) for k in range(random_seeds)]
    attempts, reasons = [], []
    for name, q0 in seeds:
        q0 = np.where(qp.free, q0, q_current)
        q0 = np.where(qp.free, np.clip(q0, lower, upper), q0)
        run = qp.solve(q0, seed=name)
        attempts.append(run)
        if run.success:
            report = validity.check(system, run.q, margin=options.safety_margin, scene=scene)
            if report.reachable:
                return SolveResult(run.q, True, "qp", name, None, report, None, [], attempts)
            run.success = False
            run.reason = "converged to an invalid configuration: " + "; ".join(report.reasons)
        reasons.append(f"QP from {name}: {run.reason}")
    return SolveResult(np.full(model.nq, np.nan), False, "qp", None, " | ".join(reasons), None, None, [], attempts)
