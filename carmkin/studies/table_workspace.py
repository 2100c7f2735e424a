"""Workspace study of §4.6.1 generalised to multi-DOF tables (issue 9): which table DOFs buy how much reach.

Desired poses. ``n`` configurations drawn uniformly (``numpy`` seed ``seed``) within every range of the full
motorized system (e.g. preset ``siremobile-iso-c3d-motorized-table``: five C-arm joints, the paper's d0 and
five extra table joints), kept only when every collision pair is at least ``safety_margin`` apart; the
desired pose is the ``xray_source`` position and principal axis there, in the table-top frame 0, roll about
the axis free (as in §4.6.1: :class:`carmkin.qp_ik.AxisTarget`).

Reachable by model X (:data:`MODELS`): with only model X's joints free and every other joint held at zero,
some configuration within all ranges, every pair at least the margin apart, puts the source on the pose
(1e-6 m, 1e-6 rad). The C-arm alone: every branch of the 5-DOF closed form (:mod:`carmkin.analytic.five_dof`,
exact: all solutions) is checked, no QP needed. Models with table DOFs: :func:`carmkin.qp_ik.solve` with
only the model's joints free (the single-axis closed form where d0 is free, then the QP from its branches,
from mid-range with held joints 0 and from ``random_seeds`` uniform draws). For models with table DOFs the QP is a local method, so
the fractions are lower bounds (a miss may be a local-minimum failure); the generating configuration is
never used as a seed.

Speed (:func:`run_study`, same answers): a necessary condition (:mod:`carmkin.studies.reach_bound`) proves
most misses of the models without tilts out of reach before any solve; the models are nested (:func:`nested_in`), so a pose a smaller model
reached is reached by every larger one without a solve; the remaining poses of a row are solved in worker
processes (2 on this 2-core machine). What time is left goes mostly into the misses the condition cannot
prove, where every seed runs until it stalls.
"""

from __future__ import annotations

import functools
import os
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from carmkin.analytic import five_dof
from carmkin.errors import (
    TableWorkspaceError,  # noqa: F401 (defined there, raised here)
)
from carmkin.model.params import CARM_JOINT_NAMES
from carmkin.model.system import CArmSystem
from carmkin.qp_ik import AxisTarget, QPIKOptions, make_task, solve
from carmkin.robot import validity
from carmkin.world import World
from carmkin.robot.state import KinematicState
from carmkin.studies.reach_bound import cannot_reach
from carmkin.transforms import inverse

CARM = CARM_JOINT_NAMES
#: Free joints of each model: the C-arm alone, + the paper's translation d0, + the three table translations,
#: + all table joints (tilts and rotation included).
MODELS: dict[str, tuple[str, ...]] = {
    "none": CARM,
    "paper": ("table_translation",) + CARM,
    "translations": ("table_translation", "table_lateral", "table_height") + CARM,
    "all": ("table_translation", "table_tilt", "table_trendelenburg", "table_lateral", "table_height",
            "table_rotation") + CARM,
}
LABELS = {"none": "5-DOF C-arm alone", "paper": "+ table translation d0 (paper)",
          "translations": "+ translation, lateral, height", "all": "+ tilts and rotation (all)"}


@dataclass(frozen=True)
class ModelReach:
    """Reach of one model: ``reached`` (n,) bool per desired pose, ``seconds`` spent on it."""

    model: str
    reached: np.ndarray
    seconds: float

    @property
    def fraction(self) -> float:
        return float(np.mean(self.reached))


def desired_configurations(system: CArmSystem, n: int, seed: int = 0, margin: float = 0.01) -> np.ndarray:
    """(n, nq) uniform in-range configurations with every collision pair at least ``margin`` (m) apart."""
    if int(n) < 1:
        raise TableWorkspaceError(f"n must be >= 1, got {n}")
    rng = np.random.default_rng(seed)
    scene = World(system)
    out = []
    while len(out) < n:
        q = rng.uniform(system.lower, system.upper)
        if scene.distances(q=q).min() >= margin:
            out.append(q)
    return np.array(out)


def axis_target(T: np.ndarray) -> AxisTarget:
    """Source position and principal axis (Z of ``xray_source``) of a pose (4, 4), roll dropped."""
    return AxisTarget(tuple(T[:3, 3]), tuple(T[:3, 2]))


def _five_dof_seeds(system: CArmSystem, T: np.ndarray) -> list[np.ndarray]:
    """Every 5-DOF closed-form branch for the pose T with all table joints at zero, as full q (nq,), each
    revolute joint moved by a whole turn into its range where that is possible (same pose)."""
    base = system.carm_base_pose
    sols = five_dof.solve_pose(system.carm, inverse(base) @ T)
    out = []
    turns = 2 * np.pi * np.array([0.0, -1.0, 1.0])  # the closed form wraps angles to (-π, π]
    for q5, ok in zip(sols.q[0], sols.valid[0]):
        if ok:
            q = np.zeros(system.nq)
            q[-5:] = q5
            for i in range(system.nq - 5, system.nq):  # a revolute joint's whole-turn twin inside its range
                if not system.prismatic[i]:
                    candidates = q[i] + turns
                    q[i] = candidates[np.argmin(np.abs(system.joint_ranges[i].excess(candidates)))]
            # a branch on a limit comes out of the closed form up to round-off beyond it: back onto the limit
            near = np.abs(np.clip(q, system.lower, system.upper) - q) <= five_dof.TOLERANCE
            out.append(np.where(near, np.clip(q, system.lower, system.upper), q))
    return out


def reachable(system: CArmSystem, T: np.ndarray, model: str, *, options: QPIKOptions = QPIKOptions(),
              random_seeds: int = 6, rng_seed: int = 0, bound: bool = True) -> bool:
    """Whether ``model``'s joints alone (others at zero) reach the position and axis of T (4, 4), validly.

    ``bound``: first the necessary condition :func:`carmkin.studies.reach_bound.cannot_reach` (no solve where
    it proves the target out of reach: the same answer, found in well under a millisecond)."""
    free = free_joints(system, model)
    if bound and cannot_reach(system, T, free):
        return False
    target = axis_target(T)
    if model == "none":  # the 5-DOF closed form gives every solution: reachable iff one branch is valid
        return any(_branch_reaches(system, target, q, options) for q in _five_dof_seeds(system, T))
    result = solve(system, target, options=options, free=free, random_seeds=random_seeds, rng_seed=rng_seed)
    return result.success


def free_joints(system: CArmSystem, model: str) -> tuple[str, ...]:
    """The joints ``model`` frees on ``system``: :data:`MODELS`'s, except that ``"all"`` is every table joint
    the system has (an angiography table has no rotation); a model whose joints the system lacks is refused."""
    free = MODELS[model]
    if model == "all":
        free = tuple(name for name in free if name in system.joint_names)
    missing = set(free) - set(system.joint_names)
    if missing:
        raise TableWorkspaceError(f"model {model!r} needs joints {sorted(missing)} the system lacks")
    return free


def _branch_reaches(system: CArmSystem, target: AxisTarget, q: np.ndarray, options: QPIKOptions) -> bool:
    """A closed-form configuration on the target within tolerance, joints in range, pairs clear of the margin
    (one forward-kinematics pass for the pose and the collisions)."""
    model = system.pinocchio()[0]
    state = KinematicState(model, q, _scene(system))
    if not make_task(model, target).errors(state.data, options.position_tolerance, options.angle_tolerance).satisfied:
        return False
    return validity.check(system, q, margin=options.safety_margin, world=state.world, state=state).reachable


@functools.lru_cache(maxsize=4)
def _scene(system: CArmSystem) -> World:
    return World(system)


def nested_in(model: str) -> tuple[str, ...]:
    """The models of :data:`MODELS` whose free joints are a proper subset of ``model``'s (e.g. ``paper`` for
    ``translations``): a configuration valid for one of them, the extra joints at zero, is valid for ``model``."""
    return tuple(m for m in MODELS if set(MODELS[m]) < set(MODELS[model]))


#: Worker-process state of :func:`run_study` (set once per process by :func:`_init_worker`).
_WORKER: dict = {}


def _init_worker(system, poses, options, random_seeds, seed, bound) -> None:
    _WORKER.update(system=system, poses=poses, options=options, random_seeds=random_seeds, seed=seed, bound=bound)


def _reach_pose(job: tuple[str, int]) -> bool:
    """``reachable`` of pose ``k`` for ``model`` (``job = (model, k)``) with the arguments of :func:`_init_worker`."""
    model, k = job
    w = _WORKER
    return reachable(w["system"], w["poses"][k], model, options=w["options"], random_seeds=w["random_seeds"],
                     rng_seed=w["seed"] + k, bound=w["bound"])


def default_workers() -> int:
    """Worker processes of :func:`run_study` by default: one per available core, at most 2 (the machine's)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, min(2, cores))


def run_study(system: CArmSystem, models=tuple(MODELS), n: int = 200, seed: int = 0, *,
              random_seeds: int = 6, options: QPIKOptions = QPIKOptions(),
              progress: Callable[[int], object] | None = None, workers: int | None = None,
              nested: bool = True, bound: bool = True) -> tuple[np.ndarray, list[ModelReach]]:
    """Desired configurations (n, nq) and the reach of each model on their poses (see the module docstring).

    Speed without changing a single answer: ``bound`` (default) skips the solve of a target that
    :func:`carmkin.studies.reach_bound.cannot_reach` proves out of reach. ``nested`` (default) marks a pose
    reached by a model without solving it when a model nested in it (:func:`nested_in`), run earlier in
    ``models``, reached it: that configuration, the extra joints held at zero, is valid for the larger model
    too (same system, same acceptance rule). ``workers`` > 1 solves the poses of a row in that many
    processes (default :func:`default_workers`); every pose's solve depends only on the pose and its own
    ``rng_seed`` (seed + k), so the answers are those of one process. ``ModelReach.seconds`` is wall time.
    """
    unknown = set(models) - set(MODELS)
    if unknown:
        raise TableWorkspaceError(f"unknown model(s) {sorted(unknown)}; known: {', '.join(MODELS)}")
    for model in models:  # refuse a model the system cannot run before any solve
        free_joints(system, model)
    qs = desired_configurations(system, n, seed, options.safety_margin)
    poses = system.fk(qs)
    workers = default_workers() if workers is None else int(workers)
    if workers < 1:
        raise TableWorkspaceError(f"workers must be >= 1, got {workers}")
    init = (system, poses, options, random_seeds, seed, bound)
    pool = _pool(workers, init) if workers > 1 and len(qs) > 1 else None
    out: list[ModelReach] = []
    try:
        if pool is None:
            _init_worker(*init)
        for model in models:
            start = time.perf_counter()
            reached = np.zeros(len(qs), dtype=bool)
            if nested:
                for earlier in out:
                    if earlier.model in nested_in(model):
                        reached |= earlier.reached
            if progress is not None and reached.any():
                progress(int(reached.sum()))
            todo = [(model, k) for k in np.flatnonzero(~reached).tolist()]
            answers = pool.imap(_reach_pose, todo, chunksize=4) if pool is not None else map(_reach_pose, todo)
            for (_, k), answer in zip(todo, answers):
                reached[k] = answer
                if progress is not None:
                    progress(1)
            out.append(ModelReach(model, reached, time.perf_counter() - start))
    finally:
        if pool is None:
            _WORKER.clear()
        else:
            pool.close()
            pool.join()
    return qs, out


def _pool(workers: int, init: tuple):
    """A process pool whose workers hold the study's arguments; forked where the platform allows it, so the
    built Pinocchio models and collision scene are inherited instead of rebuilt."""
    import multiprocessing

    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else None
    return multiprocessing.get_context(method).Pool(workers, initializer=_init_worker, initargs=init)


def table_rows(results: list[ModelReach]) -> list[str]:
    """Printable rows: model, free joints, reachable fraction, time."""
    rows = [f"{'model':<14}{'free joints':<34}{'reachable':>10}{'time (s)':>10}"]
    for r in results:
        rows.append(f"{r.model:<14}{LABELS[r.model]:<34}{r.fraction:>10.1%}{r.seconds:>10.1f}")
    return rows


def plot(results: list[ModelReach], path=None):
    """Bar chart of the reachable fraction per model (:func:`carmkin.studies.figures.table_reach`); saved to
    ``path``."""
    from carmkin.studies import figures

    return figures.table_reach(results, LABELS, path)
