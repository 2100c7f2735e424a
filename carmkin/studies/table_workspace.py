"""Workspace study of §4.6.1 generalised to multi-DOF tables (issue 9): which table DOFs buy how much reach.

Desired poses. ``n`` configurations drawn uniformly (``numpy`` seed ``seed``) within every range of the full
motorized system (e.g. preset ``siremobile-iso-c3d-motorized-table``: five C-arm joints, the paper's d0 and
five extra table joints), kept only when every collision pair is at least ``safety_margin`` apart; the
desired pose is the ``xray_source`` position and principal axis there, in the table-top frame 0, roll about
the axis free (as in §4.6.1: :class:`carmkin.qp_ik.AxisTarget`).

Reachable by model X (:data:`MODELS`): with only model X's joints free and every other joint held at zero,
some configuration within all ranges, every pair at least the margin apart, puts the source on the pose
(1e-6 m, 1e-6 rad). Solver: :func:`carmkin.qp_ik.solve_redundant`, seeded at mid-range (held joints 0),
then, for the C-arm alone, at every branch of the 5-DOF closed form (:mod:`carmkin.analytic.five_dof`, exact: all
solutions), then at ``random_seeds`` uniform draws. For models with table DOFs the QP is a local method, so
the fractions are lower bounds (a miss may be a local-minimum failure); the generating configuration is
never used as a seed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from carmkin.analytic import five_dof
from carmkin.errors import CarmkinError
from carmkin.model.params import CARM_JOINT_NAMES
from carmkin.model.system import CArmSystem
from carmkin.qp_ik import AxisTarget, QPIKOptions, solve_redundant
from carmkin.robot.collision import CollisionScene
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


class TableWorkspaceError(CarmkinError):
    """Bad request to the generalised workspace study (unknown model, N < 1, system lacks joints)."""


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
    scene = CollisionScene.from_system(system)
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
    """Every 5-DOF closed-form branch for the pose T with all table joints at zero, as full q (nq,)."""
    base = system.carm_base_pose
    sols = five_dof.solve_pose(system.carm, inverse(base) @ T)
    out = []
    for q5, ok in zip(sols.q[0], sols.valid[0]):
        if ok:
            q = np.zeros(system.nq)
            q[-5:] = q5
            out.append(q)
    return out


def reachable(system: CArmSystem, T: np.ndarray, model: str, *, options: QPIKOptions = QPIKOptions(),
              random_seeds: int = 6, rng_seed: int = 0) -> bool:
    """Whether ``model``'s joints alone (others at zero) reach the position and axis of T (4, 4), validly."""
    free = MODELS[model]
    missing = set(free) - set(system.joint_names)
    if missing:
        raise TableWorkspaceError(f"model {model!r} needs joints {sorted(missing)} the system lacks")
    extra = _five_dof_seeds(system, T) if model == "none" else []
    result = solve_redundant(system, axis_target(T), options=options, free=free, extra_seeds=extra,
                             random_seeds=random_seeds, rng_seed=rng_seed)
    return result.success


def run_study(system: CArmSystem, models=tuple(MODELS), n: int = 200, seed: int = 0, *,
              random_seeds: int = 6, options: QPIKOptions = QPIKOptions(),
              progress: Callable[[int], object] | None = None) -> tuple[np.ndarray, list[ModelReach]]:
    """Desired configurations (n, nq) and the reach of each model on their poses (see the module docstring)."""
    import time

    unknown = set(models) - set(MODELS)
    if unknown:
        raise TableWorkspaceError(f"unknown model(s) {sorted(unknown)}; known: {', '.join(MODELS)}")
    qs = desired_configurations(system, n, seed, options.safety_margin)
    poses = system.fk(qs)
    out = []
    for model in models:
        start = time.perf_counter()
        reached = []
        for k, T in enumerate(poses):
            reached.append(reachable(system, T, model, options=options, random_seeds=random_seeds, rng_seed=seed + k))
            if progress is not None:
                progress(1)
        out.append(ModelReach(model, np.array(reached), time.perf_counter() - start))
    return qs, out


def table_rows(results: list[ModelReach]) -> list[str]:
    """Printable rows: model, free joints, reachable fraction, time."""
    rows = [f"{'model':<14}{'free joints':<34}{'reachable':>10}{'s':>8}"]
    for r in results:
        rows.append(f"{r.model:<14}{LABELS[r.model]:<34}{r.fraction:>10.1%}{r.seconds:>8.1f}")
    return rows


def plot(results: list[ModelReach], path=None):
    """Bar chart of the reachable fraction per model (:func:`carmkin.plots.table_reach`); saved to ``path``."""
    from carmkin import plots

    return plots.table_reach(results, LABELS, path)
