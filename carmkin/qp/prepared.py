"""Build once, solve many: the one IK of every system with its problem prepared (as pink and mink separate
building the problem from solving it).

:class:`PreparedIK` holds what does not change from one target to the next — the system's Pinocchio model,
the collision world with the obstacles (:class:`carmkin.world.World`; e.g. the patient, a list of
:class:`~carmkin.robot.collision.Obstacle`),
the options, the QP backend and one QP IK per kind of target — and :meth:`PreparedIK.solve` runs the steps
of :func:`carmkin.qp_ik.solve` (closed form where it applies, then the QP from seeds) against them. Every
validity it reports is computed at ``options.safety_margin`` (and says so). :meth:`PreparedIK.clearance`
gives the exact smallest distance of many configurations at the cost of a broad phase plus the coal
distances that decide. Lengths in metres, angles in radians, poses in the table frame 0.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import sys
from typing import Callable, Sequence

import numpy as np
import pinocchio as pin

from carmkin.analytic.poses import pose_rows
from carmkin.errors import CarmkinError, InvalidConfigurationError
from carmkin.robot import validity
from carmkin.world.tolerances import BOUND_SLACK
from carmkin.world import Obstacle, World
from carmkin.validation import JOINT_VALUE_LIMIT, frozen_instance, real_array, real_scalar

from .backends import BACKENDS, make_backend
from .loop import QPIK
from .options import SOURCE_FRAME, QPIKError, QPIKOptions, SearchOptions
from .redundant import Redundancy, joint_weights, locked_indices
from .redundant import random_seeds as draw_seeds
from .results import BranchReport, Failure, Path, QPIKResult, RunStatus, SolveResult
from .targets import AimTarget, AxisTarget, closed_form_pose, make_task
from .tasks import pose_errors

#: Random seeds tried after the deterministic ones when :class:`SearchOptions` names no count: none where the
#: 6-DOF closed form gives every solution, a few on redundant chains (the QP is a local method).
DEFAULT_RANDOM_SEEDS = {True: 0, False: 4}


def obstacle_list(obstacles) -> tuple:
    """``obstacles`` as a tuple of :class:`Obstacle`, or :class:`QPIKError` naming the argument."""
    if obstacles is None or isinstance(obstacles, (str, bytes, dict)) or not hasattr(obstacles, "__iter__"):
        raise QPIKError(f"obstacles must be a list of carmkin.robot.collision.Obstacle, got {obstacles!r}")
    obstacles = tuple(obstacles)
    if not all(isinstance(o, Obstacle) for o in obstacles):
        raise QPIKError(f"obstacles must be a list of carmkin.robot.collision.Obstacle, got {obstacles!r}")
    return obstacles


def _default_accept(report) -> bool:
    """Joints in range and every pair clear of the margin (the table-in-cone condition is not required)."""
    return report.reachable


class PreparedIK:
    """The IK problem of ``system`` built once: see the module docstring and :func:`carmkin.qp_ik.prepare`.

    ``obstacles``: bodies fixed in the table frame (a list of :class:`Obstacle`), or a prebuilt ``world``
    holding them; ``options`` (:class:`QPIKOptions`, the margin included); ``backend``: a QP backend name
    or object; ``accept(report) -> bool`` on the :class:`~carmkin.robot.validity.ValidityReport` at the
    margin (default: joints in range and no pair inside the margin); ``redundancy`` (:class:`Redundancy`:
    joint weights, preference, free joints); ``search`` (:class:`SearchOptions`: closed form, QP, random
    seeds).
    """

    def __init__(self, system, obstacles: Sequence[Obstacle] = (), options: QPIKOptions = QPIKOptions(), *,
                 backend=None, accept: Callable[[object], bool] | None = None,
                 redundancy: Redundancy = Redundancy(), search: SearchOptions = SearchOptions(),
                 world: World | None = None) -> None:
        validity.require_system(system, QPIKError)
        for name, value, kind in (("options", options, QPIKOptions), ("redundancy", redundancy, Redundancy),
                                  ("search", search, SearchOptions)):
            if not isinstance(value, kind):
                raise QPIKError(f"{name} must be a carmkin.qp_ik.{kind.__name__}, got {value!r}")
        if accept is not None and not callable(accept):
            raise QPIKError(f"accept must be a function of the validity report, got {accept!r}")
        if world is not None and not isinstance(world, World):
            raise QPIKError(f"world must be a carmkin.world.World, got {world!r}")
        obstacles = obstacle_list(obstacles)
        if not (backend is None or isinstance(backend, str) or callable(getattr(backend, "solve", None))):
            raise QPIKError(f"backend must be a QP backend name ({', '.join(BACKENDS)}), a backend object or None, "
                            f"got {backend!r}")
        if world is not None and obstacles:
            raise QPIKError("give the obstacles either in the world or as obstacles, not both")
        if world is not None and world.system != system:
            raise QPIKError("world belongs to another system: build it as carmkin.world.World(system, patient)")
        self.options, self.search, self.redundancy = options, search, redundancy
        self.model = model = system.pinocchio()[0]
        self.world = world if world is not None else World(system, obstacles)
        self.accept = _default_accept if accept is None else accept
        self.lower, self.upper = np.array(model.lowerPositionLimit), np.array(model.upperPositionLimit)
        self._bounds = (system.lower.tolist(), system.upper.tolist())
        self.locked = locked_indices(system, redundancy.free)
        self.weights = joint_weights(system, redundancy.weights, redundancy.prefer)
        self.weights_given = redundancy.weights is not None or redundancy.prefer is not None
        self._middle = 0.5 * (self.lower + self.upper)  # the reference without q_current
        self._middle[self.locked] = 0.0
        rows = len(self.world) + 2  # the collision rows and the two distance rows of an AimTask
        self.backend = make_backend(backend, model.nv, rows) if backend is None or isinstance(backend, str) else backend
        self.data = model.createData()
        self._source = model.getFrameId(SOURCE_FRAME)
        self._solvers: dict[type, QPIK] = {}
        self._pairs = len(self.world) > 0
        self._geometry = pin.GeometryData(self.world.geometry_model)  # this solver's own collision data
        self._source_pose = None  # the source pose (4, 4) of the configuration _check last checked
        for request in self._geometry.collisionRequests:
            request.security_margin = options.safety_margin + BOUND_SLACK
            request.enable_contact = False
        for request in self._geometry.distanceRequests:
            request.enable_signed_distance = True
        self.margin = options.safety_margin

    @property
    def system(self):
        """The system this solver was prepared for (its world's)."""
        return self.world.system

    def hold_weakly(self) -> "PreparedIK":
        """Keep only a weak reference to the system (for caches keyed by the system: see
        :mod:`carmkin.model.per_system`; :meth:`carmkin.world.World.hold_weakly`); returns ``self``."""
        self.world.hold_weakly()
        return self

    # --- validity -----------------------------------------------------------------------------------------
    def _configuration(self, q, name: str) -> np.ndarray:
        return real_array(q, name, (self.model.nq,), error=InvalidConfigurationError, limit=JOINT_VALUE_LIMIT,
                          unit="m, rad")

    def check(self, q) -> validity.ValidityReport:
        """The validity report of ``q`` (nq,) at the margin ``options.safety_margin``: joints, every pair
        closer than the margin with its exact distance, the exact smallest distance, table in the cone. One
        forward-kinematics pass; ``self.data`` then holds ``q``'s frames."""
        q = self._configuration(q, "q")
        return self._check(q)

    def _check(self, q: np.ndarray) -> validity.ValidityReport:
        # One C++ pass flags the pairs closer than the margin (coal's collision test with the margin as
        # security margin, plus a slack so that no pair coal's distance puts below the margin goes unflagged);
        # coal's distance decides each flagged pair; the exact smallest distance is computed when read.
        model, data, geometry = self.model, self.data, self._geometry
        if self._pairs and pin.computeCollisions(model, data, self.world.geometry_model, geometry, q, False):
            flagged = [k for k, r in enumerate(geometry.collisionResults) if r.isCollision()]
            distances = [pin.computeDistance(self.world.geometry_model, geometry, k).min_distance for k in flagged]
            close = [(k, d) for k, d in zip(flagged, distances) if d < self.margin]
            pairs, distances = [k for k, _ in close], [d for _, d in close]
        else:
            pin.forwardKinematics(model, data, q)
            pairs, distances = [], []
        pin.updateFramePlacement(model, data, self._source)
        self._source_pose = source = data.oMf[self._source].homogeneous  # q's; read by solve's pose check too
        return validity.report(self.system, q, self.world, pairs, distances, lambda: float(self.world.clearance(q)[0]),
                               source, self.margin, self._bounds)

    def clearance(self, qs, exact_below: float = np.inf) -> np.ndarray:
        """(N,) smallest signed pair distance (m) of each configuration of ``qs`` (N, nq) in this scene.

        Exact (the coal distance of the nearest pair; bounds for every pair at once, coal only for the pairs
        whose bound decides) wherever it is below ``exact_below``; elsewhere a lower bound that is
        itself at least ``exact_below`` (pass the margin to learn "clear of it or not" at the cost of the broad
        phase). See :mod:`carmkin.world.bounds` for why it is exact.
        """
        qs = real_array(qs, "qs", (None, self.model.nq), error=InvalidConfigurationError, limit=JOINT_VALUE_LIMIT,
                        unit="m, rad")
        if not (isinstance(exact_below, float) and exact_below == math.inf):  # inf (the default): exact everywhere
            exact_below = real_scalar(exact_below, "exact_below", error=QPIKError, limit=None, unit="m")
        return self.world.clearance(qs, exact_below)

    def reachable(self, qs) -> np.ndarray:
        """(N,) bool: joints in range and every pair at least the margin apart, for ``qs`` (N, nq): the test of
        :meth:`check` (one C++ collision pass at the margin per configuration, coal's distance for the flagged
        pairs), without building reports."""
        qs = real_array(qs, "qs", (None, self.model.nq), error=InvalidConfigurationError, limit=JOINT_VALUE_LIMIT,
                        unit="m, rad")
        out = validity.within_ranges(self.system, qs)
        if not self._pairs:
            return out
        model, data, geometry, pairs = self.model, self.data, self._geometry, self.world.geometry_model
        for i in np.flatnonzero(out).tolist():
            if pin.computeCollisions(model, data, pairs, geometry, qs[i], False):
                out[i] = all(pin.computeDistance(pairs, geometry, k).min_distance >= self.margin
                              for k, r in enumerate(geometry.collisionResults) if r.isCollision())
        return out

    # --- solving ------------------------------------------------------------------------------------------
    def _qp(self, task_kind: type, target) -> QPIK:
        solver = self._solvers.get(task_kind)
        if solver is None:
            solver = QPIK(self.model, [make_task(self.model, target)], self.world, backend=self.backend,
                          options=self.options, joint_weights=self.weights, locked=self.locked)
            self._solvers[task_kind] = solver
        else:
            task = solver.tasks[0]
            if isinstance(target, AxisTarget):
                task.set_target(target.position, target.direction)
            elif isinstance(target, AimTarget):
                task.set_target(target.point, target.distance_range)
            else:  # a pose already checked (or projected) by pose_target
                task.target = pin.SE3(target)
        return solver

    def _reference(self, q_current) -> tuple[np.ndarray | None, np.ndarray]:
        if q_current is None:
            return None, self._middle.copy()
        q = self._configuration(q_current, "q_current")
        outside = validity.joint_violations(self.system, q, self._bounds)
        if outside:
            raise InvalidConfigurationError(
                "q_current must be within the joint ranges (it is the held value of locked joints and the QP's "
                "first seed): " + "; ".join(map(str, outside)))
        return q, q

    def _closed_forms(self, pose, q_current, q_ref, rows=None):
        """``(path, result, solutions (k, nq), error)`` of the closed form that applies, or ``None``; ``rows``:
        the nested lists of ``pose`` when :func:`~carmkin.analytic.poses.pose_rows` has checked it."""
        system, locked = self.system, self.locked
        if self.model.nq == 6:
            if locked:
                return None
            try:  # looked up at call time, so a stand-in module (tests) is honoured
                facade = sys.modules.get("carmkin.analytic_ik") or importlib.import_module("carmkin.analytic_ik")
                checked = getattr(facade, "_solve_rows", None) if rows is not None else None
                if checked is not None:  # the pose and the system are checked already: not a second time
                    result = checked(system, pose, rows, q_current)
                else:
                    result = facade.solve(system, pose, q_current=q_current)
            except CarmkinError as exc:
                return Path.CLOSED_FORM, None, np.zeros((0, system.nq)), str(exc)
            return Path.CLOSED_FORM, result, np.asarray(result.solutions, dtype=float), None
        from carmkin.analytic.single_axis import solve_single_axis

        if 0 in locked or any(k >= system.nq - 5 for k in locked):
            return None
        if system.mount.joints:  # it would hold the robot and move the C-arm's own (often locked) joints: QP only
            return None
        try:
            result = solve_single_axis(system, pose, "table_translation", q_ref)
        except CarmkinError as exc:
            return Path.SINGLE_AXIS, None, np.zeros((0, system.nq)), str(exc)
        return Path.SINGLE_AXIS, result, np.asarray(result.solutions, dtype=float), None

    def solve(self, target, q_current=None, *, seeds: Sequence = (), record: bool = False) -> SolveResult:
        """Joint values (nq,) that put ``xray_source`` on ``target`` without collision (see
        :func:`carmkin.qp_ik.solve` for the steps and the result). ``target``: a 4x4 pose (a nearly rigid
        one is projected, :attr:`SolveResult.pose_correction`), an :class:`AxisTarget` or an
        :class:`AimTarget`; ``q_current`` (nq,) within the joint ranges; ``seeds`` (k, nq) tried after it;
        ``record``: keep the QP iterates."""
        rows = None
        if isinstance(target, (AxisTarget, AimTarget)):
            kind, correction = type(target), 0.0
        else:
            target, rows, correction = pose_rows(target, "target")
            kind = np.ndarray
        q_current, q_ref = self._reference(q_current)
        if seeds is None or isinstance(seeds, (str, bytes, dict)) or not hasattr(seeds, "__len__"):
            raise QPIKError(f"seeds must be a sequence of configurations ({self.model.nq},), got {seeds!r}")
        if not isinstance(record, (bool, np.bool_)):
            raise QPIKError(f"record must be True or False, got {record!r}")
        if len(seeds):
            seeds = [self._configuration(s, f"seeds[{k}]") for k, s in enumerate(seeds)]
        o, lower, upper = self.options, self.lower, self.upper
        search = self.search

        def reached() -> bool:  # the source pose of the configuration _check has just checked, on the target
            if rows is not None:
                position, angle = pose_errors(self._source_pose.tolist(), rows)
                return position <= o.position_tolerance and angle <= o.angle_tolerance
            return self._qp(kind, target).tasks[0].errors(self.data, o.position_tolerance, o.angle_tolerance).satisfied

        def done(q, branch_reports=(), attempts=(), closed=None, error=None, path=Path.NONE, seed=None,
                 failure=None, report=None):  # SolveResult(q, failure is None, path, ...) without its frozen __init__
            return frozen_instance(SolveResult, {
                "q": q, "success": failure is None, "path": path, "seed": seed, "failure": failure,
                "validity": report, "closed_form": closed, "branch_reports": tuple(branch_reports),
                "attempts": tuple(attempts), "closed_form_error": error, "pose_correction": correction})

        branch_reports: list[BranchReport] = []
        branch_seeds: list[tuple[str, np.ndarray]] = []
        closed, error = None, None
        found = None
        if search.closed_form:
            pose = target if isinstance(target, np.ndarray) else closed_form_pose(target, self.system.fk(q_ref))
            found = self._closed_forms(pose, q_current, q_ref, rows)
        if found is not None:
            path, closed, solutions, error = found
            direct = path is Path.CLOSED_FORM or not (self.weights_given and q_current is not None)
            chosen = int(getattr(closed, "chosen", 0) or 0) if closed is not None else 0
            order = [chosen] + [k for k in range(len(solutions)) if k != chosen] if len(solutions) else []
            for k in order:
                name = f"branch {k}" if path is Path.CLOSED_FORM else f"single-axis branch {k}"
                q_k = solutions[k]
                if not math.isfinite(sum(q_k.tolist())):
                    branch_reports.append(BranchReport(name, path, q_k, None, False, False))
                    continue
                report = self._check(q_k)
                hit = reached()
                ok = direct and hit and self.accept(report)
                branch_reports.append(frozen_instance(BranchReport, {  # BranchReport(name, path, q_k, report, ...)
                    "name": name, "path": path, "q": q_k, "validity": report, "reached": hit, "accepted": ok}))
                if ok:
                    return done(q_k, branch_reports, (), closed, None, path, name, None, report)
                branch_seeds.append((name, np.clip(q_k, lower, upper)))
        if not search.qp:
            return done(np.full(self.model.nq, np.nan), branch_reports, (), closed, error, failure=Failure.QP_NOT_RUN)

        start = [("q_current" if q_current is not None else "mid-range", np.clip(q_ref, lower, upper))]
        given = [(f"seed {k}", s) for k, s in enumerate(seeds)]
        if q_current is None:  # the caller's seeds know more than the middle of the ranges
            ordered = branch_seeds + given + start
        elif self.weights_given:  # least weighted motion from where the joints are
            ordered = start + branch_seeds + given
        else:
            ordered = branch_seeds + start + given
        count = DEFAULT_RANDOM_SEEDS[self.system.nq == 6] if search.random_seeds is None else search.random_seeds
        ordered += [(f"random {k}", s) for k, s in enumerate(draw_seeds(lower, upper, count, search.rng_seed))]

        qp = self._qp(kind, target)
        attempts: list[QPIKResult] = []
        tried: list[np.ndarray] = []
        for name, q0 in ordered:
            q0 = np.where(qp.free, np.clip(q0, lower, upper), q_ref)
            if any(np.array_equal(q0, t) for t in tried):  # q_current often is the chosen branch
                continue
            tried.append(q0)
            run = qp.solve(q0, record=record, seed=name)
            if run.success:
                report = self._check(run.q)
                if self.accept(report):
                    return done(run.q, branch_reports, attempts + [run], closed, error, Path.QP, name, None, report)
                run = dataclasses.replace(run, status=RunStatus.REJECTED, rejection=report)
            attempts.append(run)
        # Never hand back a colliding or out-of-range answer: the closest attempt that is reachable, else NaN.
        safe = [(run, report) for run in attempts for report in [self._check(run.q)] if report.reachable]
        if safe:
            best, report = min(safe, key=lambda item: item[0].position_error + item[0].angle_error)
            q_out, seed = best.q, best.seed
        else:
            q_out, seed, report = np.full(self.model.nq, np.nan), None, None
        return done(q_out, branch_reports, attempts, closed, error, Path.QP if attempts else Path.NONE, seed,
                    Failure.NOT_REACHED, report)


__all__ = ["DEFAULT_RANDOM_SEEDS", "PreparedIK"]
