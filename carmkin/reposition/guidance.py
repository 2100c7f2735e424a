"""Joint-by-joint guidance back to a reference pose (§4.5, §4.6.2).

From the reference pose (an earlier shot, measured by the camera) the goal joints ``q_goal`` are solved
once on the model by the one IK, :func:`carmkin.qp_ik.solve` (closed form first, QP when no branch is valid;
collision-free with :attr:`GuidanceOptions.goal_margin`). Then, each time the operator has moved, the
current pose is measured again and the current joints are read off it by the closed-form IK of the model
(§4.5: "the joint values for each estimated C-arm pose can be computed by solving the inverse
kinematics"; the extra joints of a motorized table come from its encoders), and the remaining motion
``q_goal − q`` is shown. Because both ends go through the same model, errors of the model cancel when
``q`` reaches ``q_goal``. Guidance stops when every remaining move is below the thresholds (seed: 2 mm for
translational and 0.5° for rotational joints).

A manual C-arm is moved one joint at a time: the next joint is the first in :attr:`GuidanceOptions.order`
with a remaining move whose whole path (that joint alone, from the current to the goal value) stays at
least :attr:`GuidanceOptions.path_clearance` away from every collision pair. The path is checked by
conservative advancement (:func:`sweep`): a point of any body moves at most ``lever_arm`` metres per radian
of a revolute joint (1 m per metre of a prismatic one), so from a sample at distance ``d`` the next sample
may be ``(d − clearance) / speed`` further on without any pair coming closer than ``clearance`` in between
— a guarantee for the continuous path, not only for the samples. Lengths in m, angles in rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from carmkin.errors import (
    CarmkinError,
    GuidanceError,  # noqa: F401 (defined there, raised here)
)

from .model import frozen_table_system

#: The seed's stop thresholds (§4.6.2): remaining moves below 2 mm (translational) and 0.5° (rotational).
SEED_TRANSLATION_THRESHOLD = 0.002
SEED_ROTATION_THRESHOLD = math.radians(0.5)
#: Conservative advancement gives up (path "blocked") after this many samples on one move.
MAX_SWEEP_SAMPLES = 2000
#: Manual move order, first to last; joints not named (e.g. a motorized table's) come after, in q order.
DEFAULT_ORDER = ("table_translation", "vertical", "horizontal", "wigwag", "angular", "orbital")


@dataclass(frozen=True)
class GuidanceOptions:
    """Thresholds and safety settings (m, rad).

    ``translation_threshold`` / ``rotation_threshold``: stop when every remaining prismatic / revolute move
    is below them. ``goal_margin``: clearance of the goal configuration (the IK's safety margin).
    ``path_clearance``: clearance kept along every move (< ``goal_margin``, so the goal's neighbourhood is
    reachable). ``lever_arm``: bound on the distance of any collision body from any rotation axis (m; 2.5 m
    covers the Siremobile preset, see ``tests/reposition/test_guidance.py``). ``order``: joint names in
    the order the operator moves them (default :data:`DEFAULT_ORDER`).
    """

    translation_threshold: float = SEED_TRANSLATION_THRESHOLD
    rotation_threshold: float = SEED_ROTATION_THRESHOLD
    goal_margin: float = 0.01
    path_clearance: float = 0.005
    lever_arm: float = 2.5
    order: tuple[str, ...] = DEFAULT_ORDER

    def __post_init__(self) -> None:
        for name in ("translation_threshold", "rotation_threshold", "goal_margin", "lever_arm"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise GuidanceError(f"GuidanceOptions.{name} must be finite and > 0, got {value}")
        if not (np.isfinite(self.path_clearance) and 0 <= self.path_clearance < self.goal_margin):
            raise GuidanceError(f"GuidanceOptions.path_clearance must be in [0, goal_margin = {self.goal_margin}) m, "
                                f"got {self.path_clearance}")

    def thresholds(self, system) -> np.ndarray:
        """Per-joint thresholds (nq,) for ``system`` (m for prismatic, rad for revolute joints)."""
        return np.where(system.prismatic, self.translation_threshold, self.rotation_threshold)

    def move_order(self, system) -> list[int]:
        """Joint indices in the order the operator moves them."""
        unknown = set(self.order) - set(system.joint_names)
        if unknown:
            raise GuidanceError(f"GuidanceOptions.order names unknown joint(s) {sorted(unknown)}; joints: "
                                f"{', '.join(system.joint_names)}")
        named = [system.joint_names.index(n) for n in self.order]
        return named + [k for k in range(system.nq) if k not in named]


@dataclass(frozen=True)
class Sweep:
    """Result of :func:`sweep`: ``clear`` (the whole path keeps the clearance), ``min_distance`` over the
    samples (m), ``samples`` checked, ``reason`` when not clear."""

    clear: bool
    min_distance: float
    samples: int
    reason: str | None = None


def sweep(system, scene, q_from, q_to, clearance: float, lever_arm: float) -> Sweep:
    """Check the straight joint-space path ``q_from → q_to`` (nq,) by conservative advancement.

    ``clear`` guarantees that every collision pair of ``scene`` stays at least ``clearance`` (m) apart along
    the continuous path and that the joints stay in range. A body point moves at most
    ``Σ_j L_j |Δq_j|`` per unit of the path parameter (``L_j`` = 1 for prismatic joints, ``lever_arm`` for
    revolute ones).
    """
    from carmkin.robot import validity

    q_from, q_to = np.asarray(q_from, float), np.asarray(q_to, float)
    speed = float(np.sum(np.where(system.prismatic, 1.0, lever_arm) * np.abs(q_to - q_from)))
    t, samples, smallest = 0.0, 0, np.inf
    while samples < MAX_SWEEP_SAMPLES:
        q = q_from + t * (q_to - q_from)
        report = validity.check(system, q, scene=scene)
        samples += 1
        smallest = min(smallest, report.min_distance)
        if report.joints:
            return Sweep(False, smallest, samples, "; ".join(report.reasons[:1]))
        if report.min_distance < clearance:
            return Sweep(False, smallest, samples, f"clearance {report.min_distance * 1e3:.1f} mm < "
                         f"{clearance * 1e3:.1f} mm at {100 * t:.0f} % of the move")
        if t >= 1.0 or speed == 0.0:
            return Sweep(True, smallest, samples)
        t = min(1.0, t + max((report.min_distance - clearance) / speed, 1e-12))
    return Sweep(False, smallest, samples, f"unresolved after {MAX_SWEEP_SAMPLES} samples (grazing contact)")


def read_joints(model, T_source, q_previous, q_table=None) -> np.ndarray:
    """Joint values (nq,) of ``model`` at the measured source pose ``T_source`` (table frame).

    ``q_table``: encoder readings of a motorized table's extra joints (default: those of ``q_previous``).
    Table translation and C-arm joints come from the closed-form IK (:func:`carmkin.analytic_ik.solve`) of
    the model with those table joints held; of its two branches the one nearest ``q_previous`` is taken.
    """
    from carmkin import analytic_ik

    q_previous = np.asarray(q_previous, dtype=float)
    q6_prev, q_table_prev = model.split(q_previous)
    q_table = q_table_prev if q_table is None else np.asarray(q_table, dtype=float)
    try:
        result = analytic_ik.solve(frozen_table_system(model, q_table), T_source, q_current=q6_prev)
    except CarmkinError as exc:
        raise GuidanceError(f"cannot read the joints off the measured pose: {exc}") from exc
    solutions = np.asarray(result.solutions, dtype=float)
    finite = np.all(np.isfinite(solutions), axis=1)
    if not finite.any():
        raise GuidanceError("the measured pose has no IK solution on the model")
    distance = [np.max(np.abs(q6 - q6_prev)) if ok else np.inf for q6, ok in zip(solutions, finite)]
    q6 = solutions[int(np.argmin(distance))]
    k = len(q_table)
    return np.concatenate((q6[:1], q_table, q6[1:])) if k else q6


@dataclass(frozen=True)
class GuidanceStep:
    """One guidance update.

    ``q``: joints read off the measured pose (nq,), projected onto the joint ranges; ``remaining``: ``q_goal − q`` (nq,); ``done``: every
    remaining move below its threshold; ``joint``: index of the joint to move next (``None`` when done or
    blocked); ``move``: its signed move (m or rad); ``sweep``: the path check of that move; ``blocked``:
    why no joint can move (``None`` otherwise).
    """

    q: np.ndarray
    remaining: np.ndarray
    done: bool
    joint: int | None = None
    move: float = 0.0
    sweep: Sweep | None = None
    blocked: str | None = None
    skipped: tuple = field(default=())


class Guide:
    """Guidance of ``model`` (the system built from the measured start pose) to ``T_reference``.

    ``q_start`` (nq,): the joint readings where the model was built (the IK's branch reference);
    ``obstacles``: extra bodies (e.g. the patient) as in :func:`carmkin.qp_ik.solve`.
    """

    def __init__(self, model, T_reference, q_start, options: GuidanceOptions = GuidanceOptions(),
                 obstacles=()) -> None:
        from carmkin import qp_ik
        from carmkin.robot.collision import CollisionScene

        self.model, self.options = model, options
        self.thresholds = options.thresholds(model)
        self.order = options.move_order(model)
        self.scene = CollisionScene.from_system(model, obstacles)
        result = qp_ik.solve(model, T_reference, q_current=np.asarray(q_start, dtype=float), obstacles=obstacles,
                             options=qp_ik.QPIKOptions(safety_margin=options.goal_margin))
        if not result.success:
            raise GuidanceError(f"the reference pose has no collision-free solution on the model: {result.reason}")
        self.q_goal = np.asarray(result.q, dtype=float)
        self.q_last = np.asarray(q_start, dtype=float)

    def step(self, T_source, q_table=None) -> GuidanceStep:
        """The next move from the measured source pose ``T_source`` (table frame) and, for a motorized
        table, its encoder readings ``q_table``."""
        # A joint cannot be beyond its stop; measurement noise can put the reading there (e.g. vertical at its
        # lowest, read as −0.02 mm): the reading is projected onto the joint ranges before planning.
        q = np.clip(read_joints(self.model, T_source, self.q_last, q_table), self.model.lower, self.model.upper)
        self.q_last = q
        remaining = self.q_goal - q
        pending = np.abs(remaining) >= self.thresholds
        if not pending.any():
            return GuidanceStep(q, remaining, True)
        skipped = []
        for j in self.order:
            if not pending[j]:
                continue
            target = q.copy()
            target[j] = self.q_goal[j]
            check = sweep(self.model, self.scene, q, target, self.options.path_clearance, self.options.lever_arm)
            if check.clear:
                return GuidanceStep(q, remaining, False, j, float(remaining[j]), check, skipped=tuple(skipped))
            skipped.append((self.model.joint_names[j], check.reason))
        reason = "; ".join(f"{name}: {why}" for name, why in skipped)
        return GuidanceStep(q, remaining, False, blocked=f"no joint can move all the way: {reason}",
                            skipped=tuple(skipped))
