"""Workspace study of §4.6.1 (Table 4.5): how often the 5-DOF C-arm fails to reach poses of the 6-DOF model.

Protocol (§4.6.1, Fig. 4.6). For each table translation d0 and each C-arm configuration q5 of a joint grid:

1. desired source pose ``T = system.fk([d0, q5])`` in the table frame (6-DOF model);
2. the same pose in the C-arm base frame with the table back at zero, ``B⁻¹ T`` with ``B`` the base frame in
   the table frame at q = 0 (translating the table only shifts the target by d0 along Z0);
3. the 5-DOF IK (:mod:`carmkin.analytic.five_dof`, table fixed, roll free) and its selected branch;
4. per C-arm joint: K = number of poses whose required value is out of range, and mean, std (population),
   max, min of the excess |value − closest boundary| over those K poses (mm or degrees; all 0 when K = 0).

Excesses ≤ ``tolerance`` (default :data:`~carmkin.model.params.JOINT_RANGE_TOLERANCE`, 1e-9 m or rad) count
as inside: the grid puts joints exactly on their
limits (d1 = 400 mm, θ2 = ±10°, d3 = 0 and 200 mm) and the round trip FK → IK is exact only to ~1e-15.
Revolute values are compared to the range modulo 2π (:func:`carmkin.analytic.five_dof.range_excess`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from carmkin.analytic import five_dof
from carmkin.errors import (
    WorkspaceStudyError,  # noqa: F401 (defined there, raised here)
)
from carmkin.model import singular_cases
from carmkin.model.params import CARM_JOINT_NAMES, JOINT_RANGE_TOLERANCE
from carmkin.model.system import CArmSystem
from carmkin.seed import DISSERTATION_TABLE_4_5_TEXT
from carmkin.transforms import inverse

#: The five C-arm joints, in the order of q5.
JOINTS = CARM_JOINT_NAMES
#: Display unit per joint and the factor from SI to it.
UNITS = {"vertical": ("mm", 1e3), "wigwag": ("deg", 180 / math.pi), "horizontal": ("mm", 1e3),
         "angular": ("deg", 180 / math.pi), "orbital": ("deg", 180 / math.pi)}


@dataclass(frozen=True)
class StudyGrid:
    """Joint values of the study (mm and degrees, as printed in §4.6.1)."""

    vertical_mm: tuple[float, ...] = tuple(50.0 * i for i in range(9))
    wigwag_deg: tuple[float, ...] = (-10.0, 0.0, 10.0)
    horizontal_mm: tuple[float, ...] = tuple(50.0 * i for i in range(5))
    angular_deg: tuple[float, ...] = tuple(30.0 * i for i in range(-3, 4))
    orbital_deg: tuple[float, ...] = tuple(30.0 * i for i in range(-6, 7))
    translations_mm: tuple[float, ...] = tuple(50.0 * i for i in range(9))

    def __post_init__(self) -> None:
        for name in ("vertical_mm", "wigwag_deg", "horizontal_mm", "angular_deg", "orbital_deg", "translations_mm"):
            values = tuple(float(v) for v in getattr(self, name))
            if not values or not all(math.isfinite(v) for v in values):
                raise WorkspaceStudyError(f"StudyGrid.{name} must be a non-empty list of finite numbers")
            object.__setattr__(self, name, values)

    def configurations(self) -> np.ndarray:
        """(n, 5) C-arm configurations [d1, θ2, d3, θ4, θ5] (m, rad), vertical varying slowest."""
        axes = (np.array(self.vertical_mm) * 1e-3, np.radians(self.wigwag_deg), np.array(self.horizontal_mm) * 1e-3,
                np.radians(self.angular_deg), np.radians(self.orbital_deg))
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 5)


#: The grid of §4.6.1: 9 · 3 · 5 · 7 · 13 = 12285 configurations, nine translations 0..400 mm.
PAPER_GRID = StudyGrid()


@dataclass(frozen=True)
class JointExcess:
    """Out-of-range statistics of one joint at one translation (mm or degrees)."""

    K: int
    mean: float
    std: float
    max: float
    min: float

    @classmethod
    def from_excess(cls, excess: np.ndarray) -> "JointExcess":
        """Statistics of the magnitudes of the non-zero excesses (population std)."""
        out = np.abs(excess[excess != 0.0])
        if out.size == 0:
            return cls(0, 0.0, 0.0, 0.0, 0.0)
        return cls(int(out.size), float(out.mean()), float(out.std()), float(out.max()), float(out.min()))

    def as_dict(self) -> dict:
        return {"K": self.K, "mean": self.mean, "std": self.std, "max": self.max, "min": self.min}


@dataclass(frozen=True)
class TranslationResult:
    """Results for one table translation.

    Attributes:
        translation: d0 (m).
        joints: :class:`JointExcess` per joint name.
        poses: number of poses.
        reachable_5dof: poses whose selected 5-DOF solution has all joints in range.
        reachable_6dof: poses the 6-DOF model reaches with all joints (with d0) in range
            (:func:`six_dof_reachable`).
        unsolved: poses with no FK-verified 5-DOF branch.
        max_residual: worst FK residual of the chosen branches (m / unit-vector norm).
    """

    translation: float
    joints: dict[str, JointExcess]
    poses: int
    reachable_5dof: int
    reachable_6dof: int
    unsolved: int
    max_residual: float


@dataclass(frozen=True)
class StudyResult:
    """Results of :func:`run_study`, one entry per translation (in the order given)."""

    system: str
    results: tuple[TranslationResult, ...] = field(default_factory=tuple)

    def as_json(self) -> dict:
        """``{"translations_mm": {"<d0 in mm>": {"<joint>_<unit>": {"K", "mean", "std", "max", "min"}}}}``: the
        unit in each key (joints ``vertical_mm``, ``wigwag_deg``, ...: mean, std, max and min in that unit; K a
        count), as the command line's JSON keys."""
        return {"translations_mm": {translation_key(r.translation): {f"{j}_{UNITS[j][0]}": r.joints[j].as_dict()
                                                                      for j in JOINTS} for r in self.results}}

    @property
    def fraction_5dof(self) -> float:
        """Fraction of all poses the 5-DOF model reaches within all joint ranges."""
        return sum(r.reachable_5dof for r in self.results) / sum(r.poses for r in self.results)

    @property
    def fraction_6dof(self) -> float:
        """Fraction of all poses the 6-DOF model reaches within all joint ranges (:func:`six_dof_reachable`)."""
        return sum(r.reachable_6dof for r in self.results) / sum(r.poses for r in self.results)


def translation_key(translation: float) -> str:
    """JSON/table key of a translation d0 (m): millimetres, e.g. "250"."""
    value = translation * 1e3
    return f"{value:.0f}" if abs(value - round(value)) < 1e-6 else f"{value:g}"


def base_in_table(system: CArmSystem) -> np.ndarray:
    """Pose (4, 4) of the C-arm base frame (5-DOF frame 1) in the table frame with all joints at zero
    (:attr:`CArmSystem.carm_base_pose`)."""
    return system.carm_base_pose


def desired_poses(system: CArmSystem, q5: np.ndarray, translation: float) -> np.ndarray:
    """6-DOF source poses (N, 4, 4) in the table frame, ``fk([translation, 0…, q5])``; extra motorized-table
    joints stay at zero."""
    q = np.zeros((len(q5), system.nq))
    q[:, 0] = translation
    q[:, -5:] = q5
    return system.fk(q)


def desired_targets(system: CArmSystem, q5: np.ndarray, translation: float,
                    poses: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Source positions and principal axes (N, 3) in the C-arm base frame (table at zero) of the 6-DOF poses
    :func:`desired_poses` (pass ``poses`` to reuse them)."""
    T = desired_poses(system, q5, translation) if poses is None else poses
    return five_dof.targets_from_poses(inverse(base_in_table(system)) @ T)


#: Poses with |det J| (eq. 4.7) below this are not sent to the analytic 6-DOF IK (it would fall back to a
#: per-pose numerical solver there); for them only the generating configuration counts.
SIX_DOF_SINGULAR = 1e-3


def six_dof_reachable(system: CArmSystem, q5: np.ndarray, translation: float, poses: np.ndarray,
                      tolerance: float = JOINT_RANGE_TOLERANCE) -> np.ndarray:
    """(N,) True where the 6-DOF model reaches the pose within all ranges: the generating configuration
    [translation, q5] is inside, or (regular poses, when :mod:`carmkin.analytic_ik` is available and the
    system has no extra table joints) one of the two analytic IK branches is."""
    def inside(q6: np.ndarray) -> np.ndarray:
        with np.errstate(invalid="ignore"):
            carm_ok = np.all(np.abs(five_dof.range_excess(system.carm, q6[..., 1:])) <= tolerance, axis=-1)
            return carm_ok & (np.abs(system.table.translation.excess(q6[..., 0])) <= tolerance)

    q6 = np.column_stack((np.full(len(q5), translation), q5))
    reachable = inside(q6)
    try:
        from carmkin import analytic_ik
    except ImportError:  # pragma: no cover - the analytic IK ships with carmkin
        return reachable
    if system.table.joints:
        return reachable
    det_j = singular_cases.det_closed_form(system.setup, q5[:, 1], q5[:, 3])
    regular = np.flatnonzero(np.abs(det_j) >= SIX_DOF_SINGULAR)
    if regular.size:
        result = analytic_ik.solve_batch(system, poses[regular])
        ok = result.reached & inside(result.solutions)
        reachable[regular] |= ok.any(axis=0)
    return reachable


def study_translation(system: CArmSystem, q5: np.ndarray, translation: float, *,
                      tolerance: float = JOINT_RANGE_TOLERANCE) -> TranslationResult:
    """The study at one table translation d0 (m) for C-arm configurations q5 (n, 5) (m, rad)."""
    poses = desired_poses(system, q5, translation)
    p, z = desired_targets(system, q5, translation, poses)
    solutions = five_dof.solve(system.carm, p, z)
    q = solutions.selected
    solved = solutions.chosen >= 0
    excess = five_dof.range_excess(system.carm, q[solved])
    excess = np.where(np.abs(excess) <= tolerance, 0.0, excess)
    joints = {}
    for i, name in enumerate(JOINTS):
        joints[name] = JointExcess.from_excess(excess[:, i] * UNITS[name][1])
    chosen_residual = solutions.residual[np.arange(len(q)), np.maximum(solutions.chosen, 0)][solved]
    return TranslationResult(
        translation=float(translation), joints=joints, poses=len(q5),
        reachable_5dof=int(np.all(excess == 0.0, axis=1).sum()),
        reachable_6dof=int(six_dof_reachable(system, q5, translation, poses, tolerance).sum()),
        unsolved=int((~solved).sum()),
        max_residual=float(chosen_residual.max(initial=0.0)),
    )


def run_study(system: CArmSystem, grid: StudyGrid = PAPER_GRID, *, tolerance: float = JOINT_RANGE_TOLERANCE,
              progress: Callable[[int], object] | None = None) -> StudyResult:
    """The §4.6.1 study of ``system`` over ``grid`` (see the module docstring); ``progress(n)`` after each
    translation with the number of poses done."""
    q5 = grid.configurations()
    results = []
    for d0 in np.array(grid.translations_mm) * 1e-3:
        results.append(study_translation(system, q5, float(d0), tolerance=tolerance))
        if progress is not None:
            progress(len(q5))
    return StudyResult(system=system.name, results=tuple(results))


def _same_precision(value: float, printed: str) -> str:
    decimals = len(printed.split(".")[1]) if "." in printed else (0 if printed == "0" and value == 0 else 2)
    return f"{value:.{decimals}f}"


def comparison_rows(result: StudyResult) -> list[tuple[str, str, str, str]]:
    """Rows (quantity, translation, ours, dissertation) for the wigwag and horizontal joints of Table 4.5,
    ours rounded to the printed precision ("—" where the dissertation has no column)."""
    rows = []
    for joint in ("wigwag", "horizontal"):
        for r in result.results:
            key = translation_key(r.translation)
            ours = r.joints[joint]
            paper = DISSERTATION_TABLE_4_5_TEXT[joint].get(key)
            for stat in ("K", "mean", "std", "max", "min"):
                value = getattr(ours, stat)
                if stat == "K":
                    text = f"{value:d}"
                else:
                    text = _same_precision(value, paper[stat]) if paper else f"{value:.2f}"
                rows.append((f"{joint} {stat}", key, text, paper[stat] if paper else "—"))
    return rows
