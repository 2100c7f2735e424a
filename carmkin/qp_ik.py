"""QP inverse kinematics with joint limits and collision avoidance, and the one solve for every system.

:func:`solve` is the front door (the ``carmkin.qp_ik.solve`` contract); :func:`prepare` builds the problem
once (system, collision world with the obstacles, options, backend) for many solves, and :func:`solve` is a
thin wrapper of it. It picks the path itself:

1. the closed form where it applies — the 6-DOF closed form of :mod:`carmkin.analytic_ik` on a 6-joint
   system, the single-axis closed form of :mod:`carmkin.analytic.single_axis` (``table_translation``
   active, the other table joints held) on a motorized table; the first branch that reaches the pose and
   passes the acceptance rule is the answer;
2. otherwise the QP IK (:class:`QPIK`) from seeds in turn: the closed-form branches (projected onto the
   joint box), ``q_current`` (or mid-range), the caller's ``seeds``, then ``random_seeds`` uniform draws;
   the first run that converges to an accepted configuration is the answer.

The pieces live in :mod:`carmkin.qp`: backends, limits (constraints as objects), step (one QP step),
loop (the iteration), targets, redundant (joint weights, preference, locked joints), results (enums and
frozen dataclasses; sentences are rendered from them), prepared (the problem built once).
"""

from __future__ import annotations

from typing import Callable, Sequence

from carmkin.model.per_system import per_system
from carmkin.qp.backends import (
    BACKENDS,
    OSQPBackend,
    QpsolversBackend,
    default_backend,
    make_backend,
)
from carmkin.qp.limits import CollisionAvoidance, JointLimits
from carmkin.qp.loop import QPIK
from carmkin.qp.options import MARGIN_TOLERANCE, SOURCE_FRAME, QPIKError, QPIKOptions, SearchOptions
from carmkin.qp.prepared import DEFAULT_RANDOM_SEEDS, PreparedIK, obstacle_list
from carmkin.qp.redundant import (
    PREFERENCE_RATIO,
    Redundancy,
    is_table_joint,
    joint_weights,
    locked_indices,
)
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
from carmkin.robot import validity
from carmkin.world import Obstacle, World

__all__ = [
    "BACKENDS", "DEFAULT_RANDOM_SEEDS", "AimTarget", "AxisTarget", "BranchReport", "CollisionAvoidance",
    "Failure", "JointLimits", "MARGIN_TOLERANCE", "OSQPBackend", "PREFERENCE_RATIO", "Path", "PreparedIK",
    "QPIK", "QPIKError", "QPIKOptions", "QPIKResult", "QpsolversBackend", "Redundancy", "RunStatus",
    "SOURCE_FRAME", "SearchOptions", "SolveResult", "StepQP", "build_step", "closed_form_pose",
    "default_backend", "is_table_joint", "joint_weights", "locked_indices", "make_backend", "make_task",
    "prepare", "solve", "solve_redundant", "solve_step",
]

def prepare(system, obstacles: Sequence[Obstacle] = (), options: QPIKOptions = QPIKOptions(), *, backend=None,
            accept: Callable[[object], bool] | None = None, redundancy: Redundancy = Redundancy(),
            search: SearchOptions = SearchOptions(), world: World | None = None) -> PreparedIK:
    """The IK of ``system`` built once and solved many times: ``prepare(system, obstacles=patient)
    .solve(T, q_current=q)`` gives what :func:`solve` gives, without rebuilding the collision world, the
    backend and the tasks at each call; ``.check(q)`` is the validity at the margin, ``.clearance(qs)`` the
    exact smallest distance of many configurations (:class:`~carmkin.qp.prepared.PreparedIK`).

    ``obstacles``: a list of :class:`~carmkin.robot.collision.Obstacle` fixed in the table frame (or a
    prebuilt ``world``); ``options`` (:class:`QPIKOptions`: tolerances, iterations, the safety margin);
    ``backend``: QP backend name or object; ``accept``: acceptance rule on the validity report;
    ``redundancy`` (:class:`Redundancy`: weights, prefer, free); ``search`` (:class:`SearchOptions`).
    """
    return PreparedIK(system, obstacles, options, backend=backend, accept=accept, redundancy=redundancy,
                      search=search, world=world)


#: Prepared solvers :func:`solve` keeps per system (the most recently used option sets).
PREPARED_PER_SYSTEM = 8


@per_system
def _prepared(system) -> dict:
    """Prepared solvers of ``system`` without obstacles, by their (hashable) options: what :func:`solve`
    reuses from one call to the next."""
    return {}


def solve(
    system,
    target,
    q_current=None,
    obstacles: Sequence[Obstacle] = (),
    options: QPIKOptions = QPIKOptions(),
    backend=None,
    accept: Callable[[object], bool] | None = None,
    *,
    world: World | None = None,
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

    ``target``: a 4x4 pose in the table frame (a nearly rigid one, within
    :data:`carmkin.transforms.NEARLY_RIGID_TOLERANCE`, is projected onto the nearest rigid transform and the
    correction reported as ``pose_correction``), an :class:`AxisTarget` (position + principal-axis
    direction, roll free) or an :class:`AimTarget`. ``q_current`` (nq,), within the joint ranges: current
    joints; reference of the branch choice (and of the roll of axis/aim targets), first QP seed, held value
    of locked joints (default: mid-range, locked joints at 0). ``obstacles``: extra bodies in the table frame
    (or a prebuilt ``world`` holding them). ``accept(report) -> bool`` on the
    :class:`~carmkin.robot.validity.ValidityReport` (margin ``options.safety_margin``, the margin of every
    report of the result): the acceptance rule of closed-form branches and QP answers (default: joints in
    range and no pair inside the margin).

    A thin wrapper of :func:`prepare` + :meth:`PreparedIK.solve`; the keywords are those of the option
    objects. Redundant chains (:class:`Redundancy`): ``weights``/``prefer`` (:func:`joint_weights`), ``free``
    (names of the joints that may move; the others stay at ``q_current``). Search (:class:`SearchOptions`):
    ``closed_form=False``: QP only; ``qp=False``: closed form only; ``random_seeds`` uniform draws (numpy seed
    ``rng_seed``; default :data:`DEFAULT_RANDOM_SEEDS`). Per call: ``seeds`` (k, nq) tried after
    ``q_current`` (before the mid-range default), ``record`` the QP iterates. When weights or a preference are
    given with ``q_current``, the single-axis closed form only seeds the QP, which starts from ``q_current``
    (least weighted motion). ``backend``: QP backend name (created once per prepared solver).
    """
    validity.require_system(system, QPIKError)
    obstacles = obstacle_list(obstacles)
    redundancy = Redundancy(weights, prefer, free)
    search = SearchOptions(closed_form, qp, random_seeds, rng_seed)
    reusable = not obstacles and world is None and (backend is None or isinstance(backend, str))
    if reusable:
        try:
            key = (options, backend, accept, redundancy, search)
            hash(key)
        except TypeError:  # options holding unhashable values: prepared for this call only
            reusable = False
    if reusable:
        cache = _prepared(system)
        solver = cache.pop(key, None)
        if solver is None:
            solver = prepare(system, options=options, backend=backend, accept=accept, redundancy=redundancy,
                             search=search).hold_weakly()
        cache[key] = solver  # most recently used last
        while len(cache) > PREPARED_PER_SYSTEM:  # e.g. a new accept function at every call
            cache.pop(next(iter(cache)))
    else:
        solver = prepare(system, obstacles, options, backend=backend, accept=accept, redundancy=redundancy,
                         search=search, world=world)
    return solver.solve(target, q_current, seeds=seeds, record=record)


def solve_redundant(system, target, q_current=None, obstacles: Sequence[Obstacle] = (),
                    options: QPIKOptions = QPIKOptions(), weights=None, prefer: str | None = None,
                    free: Sequence[str] | None = None, extra_seeds: Sequence = (), backend=None,
                    closed_form_seeds: bool = True, random_seeds: int = 0, rng_seed: int = 0) -> SolveResult:
    """Deprecated alias of :func:`solve` (same answers): ``extra_seeds`` → ``seeds``,
    ``closed_form_seeds`` → ``closed_form``."""
    return solve(system, target, q_current, obstacles, options, backend, weights=weights, prefer=prefer, free=free,
                 seeds=extra_seeds, random_seeds=random_seeds, rng_seed=rng_seed, closed_form=closed_form_seeds)
