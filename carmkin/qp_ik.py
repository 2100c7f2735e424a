"""QP inverse kinematics with joint limits and collision avoidance, and the one solve for every system.

:func:`solve` is the front door (the ``carmkin.qp_ik.solve`` contract). It picks the path itself:

1. the closed form where it applies — the 6-DOF closed form of :mod:`carmkin.analytic_ik` on a 6-joint
   system, the single-axis closed form of :mod:`carmkin.analytic.single_axis` (``table_translation``
   active, the other table joints held) on a motorized table; the first branch that reaches the pose and
   passes the acceptance rule is the answer;
2. otherwise the QP IK (:class:`QPIK`) from seeds in turn: the closed-form branches (projected onto the
   joint box), ``q_current`` (or mid-range), the caller's ``seeds``, then ``random_seeds`` uniform draws;
   the first run that converges to an accepted configuration is the answer.

The pieces live in :mod:`carmkin.qp`: backends, limits (constraints as objects), step (one QP step),
loop (the iteration), targets, redundant (joint weights, preference, locked joints), results (enums and
frozen dataclasses; sentences are rendered from them).
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
from typing import Callable, Sequence

import numpy as np

from carmkin.errors import CarmkinError, InvalidConfigurationError
from carmkin.qp.backends import (
    BACKENDS,
    OSQPBackend,
    QpsolversBackend,
    default_backend,
    make_backend,
)
from carmkin.qp.limits import CollisionAvoidance, JointLimits
from carmkin.qp.loop import QPIK
from carmkin.qp.options import MARGIN_TOLERANCE, SOURCE_FRAME, QPIKError, QPIKOptions
from carmkin.qp.redundant import (
    PREFERENCE_RATIO,
    is_table_joint,
    joint_weights,
    locked_indices,
)
from carmkin.qp.redundant import random_seeds as draw_seeds
from carmkin.qp.results import (
    BranchReport,
    Failure,
    Path,
    QPIKResult,
    RunStatus,
    SolveResult,
)
from carmkin.qp.step import StepQP, build_step, solve_step
from carmkin.qp.targets import AimTarget, AxisTarget, closed_form_pose, make_task
from carmkin.robot.collision import CollisionScene, Obstacle
from carmkin.robot.state import KinematicState

__all__ = [
    "BACKENDS", "AimTarget", "AxisTarget", "BranchReport", "CollisionAvoidance", "Failure", "JointLimits",
    "MARGIN_TOLERANCE", "OSQPBackend", "PREFERENCE_RATIO", "Path", "QPIK", "QPIKError", "QPIKOptions",
    "QPIKResult", "QpsolversBackend", "RunStatus", "SOURCE_FRAME", "SolveResult", "StepQP", "build_step",
    "closed_form_pose", "default_backend", "is_table_joint", "joint_weights", "locked_indices", "make_backend",
    "make_task", "solve", "solve_redundant", "solve_step",
]

#: Random seeds tried by :func:`solve` after the deterministic ones when the caller names no count: none
#: where the 6-DOF closed form gives every solution, a few on redundant chains (the QP is a local method).
DEFAULT_RANDOM_SEEDS = {True: 0, False: 4}


@functools.lru_cache(maxsize=8)
def _plain_scene(system) -> CollisionScene:
    """The obstacle-free collision scene of ``system``, built once per (hashable, frozen) system: building
    one costs more than a closed-form solve. Its data is overwritten by every distance query."""
    return CollisionScene.from_system(system)


def _default_accept(report) -> bool:
    """Joints in range and every pair clear of the margin (the table-in-cone condition is not required)."""
    return report.reachable


def _closed_forms(system, target, q_ref, q_current, locked):
    """``(path, result, solutions (k, nq), error)`` of the closed form that applies to ``system``, or
    ``None`` when none does (a locked joint it would move)."""
    pose = closed_form_pose(target, system.fk(q_ref))
    if system.nq == 6:
        if locked:
            return None
        try:  # looked up at call time, so a stand-in module (tests) is honoured
            result = importlib.import_module("carmkin.analytic_ik").solve(system, pose, q_current=q_current)
        except CarmkinError as exc:
            return Path.CLOSED_FORM, None, np.zeros((0, system.nq)), str(exc)
        return Path.CLOSED_FORM, result, np.asarray(result.solutions, dtype=float), None
    from carmkin.analytic.single_axis import solve_single_axis

    if 0 in locked or any(k >= system.nq - 5 for k in locked):
        return None
    try:
        result = solve_single_axis(system, pose, "table_translation", q_ref)
    except CarmkinError as exc:
        return Path.SINGLE_AXIS, None, np.zeros((0, system.nq)), str(exc)
    return Path.SINGLE_AXIS, result, np.asarray(result.solutions, dtype=float), None


def solve(
    system,
    target,
    q_current=None,
    obstacles: Sequence[Obstacle] = (),
    options: QPIKOptions = QPIKOptions(),
    backend=None,
    accept: Callable[[object], bool] | None = None,
    *,
    scene: CollisionScene | None = None,
    weights=None,
    prefer: str | None = None,
    free: Sequence[str] | None = None,
    seeds: Sequence = (),
    random_seeds: int | None = None,
    rng_seed: int = 0,
    closed_form: bool = True,
    qp: bool = True,
    record: bool = False,
) -> SolveResult:
    """Joint values (nq,) of any ``system`` that put ``xray_source`` on ``target`` without collision.

    ``target``: a 4x4 pose in the table frame, an :class:`AxisTarget` (position + principal-axis direction,
    roll free) or an :class:`AimTarget`. ``q_current`` (nq,): current joints; reference of the branch
    choice (and of the roll of axis/aim targets), first QP seed, held value of locked joints (default:
    mid-range, locked joints at 0). ``obstacles``: extra bodies in the table frame (or a prebuilt
    ``scene`` holding them). ``accept(report) -> bool`` on the
    :class:`~carmkin.robot.validity.ValidityReport` (margin ``options.safety_margin``): the acceptance rule
    of closed-form branches and QP answers (default: joints in range and no pair inside the margin).

    Redundant chains: ``weights``/``prefer`` (:func:`joint_weights`), ``free`` (names of the joints that may
    move; the others stay at ``q_current``), ``seeds`` (k, nq) tried after ``q_current`` (before the mid-range default), ``random_seeds``
    uniform draws (numpy seed ``rng_seed``; default :data:`DEFAULT_RANDOM_SEEDS`). When weights or a
    preference are given with ``q_current``, the single-axis closed form only seeds the QP, which starts
    from ``q_current`` (least weighted motion). ``closed_form=False``: QP only; ``qp=False``: closed form
    only. ``backend``: QP backend name (created once per call, shared by every seed).
    """
    from carmkin.robot import validity

    model = system.pinocchio()[0]
    task = make_task(model, target)
    if scene is not None and obstacles:
        raise QPIKError("give the obstacles either in the scene or as obstacles, not both")
    if scene is None:
        scene = CollisionScene.from_system(system, obstacles) if obstacles else _plain_scene(system)
    accept = _default_accept if accept is None else accept
    lower, upper = np.array(model.lowerPositionLimit), np.array(model.upperPositionLimit)
    locked = locked_indices(system, free)
    weights_given = weights is not None or prefer is not None
    w = joint_weights(system, weights, prefer)
    if q_current is not None:
        q_current = np.asarray(q_current, dtype=float)
        if q_current.shape != (model.nq,) or not np.all(np.isfinite(q_current)):
            raise InvalidConfigurationError(
                f"q_current must be a finite vector of shape ({model.nq},), got {q_current.shape}")
        q_ref = q_current
    else:
        q_ref = 0.5 * (lower + upper)
        q_ref[locked] = 0.0
    margin = options.safety_margin

    def check(q, state=None):
        state = state if state is not None else KinematicState(model, q, scene)
        return validity.check(system, q, margin=margin, scene=scene, state=state), state

    branch_reports: list[BranchReport] = []
    branch_seeds: list[tuple[str, np.ndarray]] = []
    closed, error = None, None
    found = _closed_forms(system, target, q_ref, q_current, locked) if closed_form else None
    if found is not None:
        path, closed, solutions, error = found
        direct = path is Path.CLOSED_FORM or not (weights_given and q_current is not None)
        chosen = int(getattr(closed, "chosen", 0) or 0) if closed is not None else 0
        order = [chosen] + [k for k in range(len(solutions)) if k != chosen] if len(solutions) else []
        for k in order:
            name = f"branch {k}" if path is Path.CLOSED_FORM else f"single-axis branch {k}"
            q_k = solutions[k]
            if not np.all(np.isfinite(q_k)):
                branch_reports.append(BranchReport(name, path, q_k, None, False, False))
                continue
            report, state = check(q_k)
            o = options
            reached = task.errors(state.data, o.position_tolerance, o.angle_tolerance).satisfied
            ok = direct and reached and accept(report)
            branch_reports.append(BranchReport(name, path, q_k, report, reached, ok))
            if ok:
                return SolveResult(q_k, True, path, name, None, report, closed, tuple(branch_reports))
            branch_seeds.append((name, np.clip(q_k, lower, upper)))
    if not qp:
        return SolveResult(np.full(model.nq, np.nan), False, Path.NONE, None, Failure.QP_NOT_RUN, None, closed,
                           tuple(branch_reports), (), error)

    start = [("q_current" if q_current is not None else "mid-range", np.clip(q_ref, lower, upper))]
    given = [(f"seed {k}", np.asarray(s, dtype=float)) for k, s in enumerate(seeds)]
    if q_current is None:  # the caller's seeds know more than the middle of the ranges
        ordered = branch_seeds + given + start
    elif weights_given:  # least weighted motion from where the joints are
        ordered = start + branch_seeds + given
    else:
        ordered = branch_seeds + start + given
    count = DEFAULT_RANDOM_SEEDS[system.nq == 6] if random_seeds is None else int(random_seeds)
    ordered += [(f"random {k}", s) for k, s in enumerate(draw_seeds(lower, upper, count, rng_seed))]

    solver = QPIK(model, [task], scene, backend=backend, options=options, joint_weights=w, locked=locked)
    attempts: list[QPIKResult] = []
    tried: list[np.ndarray] = []
    for name, q0 in ordered:
        q0 = np.where(solver.free, np.clip(q0, lower, upper), q_ref)
        if any(np.array_equal(q0, t) for t in tried):  # q_current often is the chosen branch
            continue
        tried.append(q0)
        run = solver.solve(q0, record=record, seed=name)
        if run.success:
            report, _ = check(run.q, solver.last_state)
            if accept(report):
                return SolveResult(run.q, True, Path.QP, name, None, report, closed, tuple(branch_reports),
                                   tuple(attempts) + (run,), error)
            run = dataclasses.replace(run, status=RunStatus.REJECTED, rejection=report)
        attempts.append(run)
    # Never hand back a colliding or out-of-range answer: the closest attempt that is reachable, else NaN.
    safe = [(run, report) for run in attempts for report in [check(run.q)[0]] if report.reachable]
    if safe:
        best, report = min(safe, key=lambda item: item[0].position_error + item[0].angle_error)
        q_out, seed = best.q, best.seed
    else:
        q_out, seed, report = np.full(model.nq, np.nan), None, None
    return SolveResult(q_out, False, Path.QP if attempts else Path.NONE, seed, Failure.NOT_REACHED, report, closed,
                       tuple(branch_reports), tuple(attempts), error)


def solve_redundant(system, target, q_current=None, obstacles: Sequence[Obstacle] = (),
                    options: QPIKOptions = QPIKOptions(), weights=None, prefer: str | None = None,
                    free: Sequence[str] | None = None, extra_seeds: Sequence = (), backend=None,
                    closed_form_seeds: bool = True, random_seeds: int = 0, rng_seed: int = 0) -> SolveResult:
    """Deprecated alias of :func:`solve` (same answers): ``extra_seeds`` → ``seeds``,
    ``closed_form_seeds`` → ``closed_form``."""
    return solve(system, target, q_current, obstacles, options, backend, weights=weights, prefer=prefer, free=free,
                 seeds=extra_seeds, random_seeds=random_seeds, rng_seed=rng_seed, closed_form=closed_form_seeds)
