"""Structured results of the QP IK: statuses and failures are enums with detail fields; the sentences for
people (``reason``) are rendered from them and never parsed. Results are frozen: a verdict is made once."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np


class RunStatus(str, Enum):
    """How one QP run from one seed ended."""

    CONVERGED = "converged"
    MAX_ITERATIONS = "not converged within max_iterations"
    OUTSIDE_LIMITS = "start configuration lies outside the joint limits by more than max_step"
    INFEASIBLE = "QP infeasible"
    BLOCKED = "step blocked: every shortened step breaks the safety margin"
    STALLED = "stalled"
    INSIDE_MARGIN = "target reached only inside the safety margin, no way out found"
    REJECTED = "converged to a configuration the acceptance rule rejects"


@dataclass(frozen=True)
class QPIKResult:
    """Outcome of one QP IK run from one seed.

    ``q`` (nq,) last iterate; ``status`` (:class:`RunStatus`); ``iterations``; ``position_error`` (m) and
    ``angle_error`` (rad), the largest over the tasks; ``min_distance``: the smallest pair distance seen
    over all iterates including the seed (m, ``inf`` without pairs); ``history`` (iterations+1, nq) when
    recorded; ``seed`` names the start. Details of a failure: ``joints_at_limits`` (names), ``pairs``
    (``"first/second"`` names of the pairs at or inside the margin), ``rejection`` (the
    :class:`~carmkin.robot.validity.ValidityReport` a ``REJECTED`` run failed).
    """

    q: np.ndarray
    status: RunStatus
    iterations: int
    position_error: float
    angle_error: float
    min_distance: float
    history: np.ndarray | None = None
    seed: str = "q0"
    joints_at_limits: tuple[str, ...] = ()
    pairs: tuple[str, ...] = ()
    rejection: object = None
    no_progress: bool = False

    @property
    def success(self) -> bool:
        return self.status is RunStatus.CONVERGED

    @property
    def reason(self) -> str | None:
        """Why the run failed, for people (``None`` on success)."""
        s = self.status
        errors = f"errors {self.position_error:.3g} m, {np.degrees(self.angle_error):.3g}°"
        pairs = ", ".join(self.pairs)
        if s is RunStatus.CONVERGED:
            return None
        if s is RunStatus.MAX_ITERATIONS:
            return f"not converged after {self.iterations} iterations ({errors})"
        if s is RunStatus.INFEASIBLE:
            return f"QP infeasible at iteration {self.iterations}" + (f" (pairs inside the margin: {pairs})" if pairs else "")
        if s is RunStatus.BLOCKED:
            return f"step blocked at iteration {self.iterations}: every shortened step breaks the safety margin ({pairs})"
        if s in (RunStatus.STALLED, RunStatus.INSIDE_MARGIN):
            why = []
            if self.joints_at_limits:
                why.append("joints at limits: " + ", ".join(self.joints_at_limits))
            if self.pairs:
                why.append("collision pairs at or inside the safety margin: " + pairs)
            if s is RunStatus.INSIDE_MARGIN:
                return f"{s.value} ({'; '.join(why or ['pairs inside the margin'])})"
            stalled = f"no progress in {self.iterations} iterations" if self.no_progress else "stalled"
            return f"{stalled} with {errors}" + (f" ({'; '.join(why)})" if why else " (local minimum)")
        if s is RunStatus.REJECTED:
            why = "; ".join(self.rejection.reasons)
            return ("converged to an invalid configuration: " + why) if why else "converged, rejected by the acceptance rule"
        return s.value


class Path(str, Enum):
    """Which method produced the answer of :func:`carmkin.qp_ik.solve` (compares equal to its value)."""

    CLOSED_FORM = "closed_form"        #: the 6-DOF closed form of carmkin.analytic_ik
    SINGLE_AXIS = "single_axis"        #: the single-axis closed form of a motorized table
    QP = "qp"                          #: the QP IK from one of the seeds
    NONE = "none"                      #: nothing was accepted and no attempt is safe to hand back


class Failure(str, Enum):
    """Why :func:`carmkin.qp_ik.solve` failed; the detail is in the result's branch reports and attempts."""

    NOT_REACHED = "no closed-form branch accepted and no QP run converged to an accepted configuration"
    QP_NOT_RUN = "no closed-form branch accepted (QP fallback off)"


@dataclass(frozen=True)
class BranchReport:
    """One closed-form branch: ``name`` (e.g. ``"branch 0"``), ``path`` (closed form or single axis),
    ``q`` (nq,), ``validity`` (``None`` when not finite), ``reached`` (pose within tolerance), ``accepted``."""

    name: str
    path: Path
    q: np.ndarray
    validity: object
    reached: bool
    accepted: bool

    @property
    def reason(self) -> str | None:
        """Why the branch was not taken (``None`` when accepted)."""
        if self.accepted:
            return None
        if self.validity is None:
            return f"{self.name}: no finite solution"
        problems = list(self.validity.reasons)
        if not self.reached:
            problems.append("closed-form residual above tolerance")
        return f"{self.name}: " + ("; ".join(problems) or "rejected by the acceptance rule")


@dataclass(frozen=True)
class SolveResult:
    """Outcome of :func:`carmkin.qp_ik.solve`.

    ``q`` (nq,): the answer; when ``success`` is False, the QP attempt closest to the target among those the
    validity check calls reachable (never a colliding one), or NaN when there is none; ``path``
    (:class:`Path`); ``seed``: the branch or seed name of ``q``; ``failure`` (:class:`Failure`, ``None`` on
    success) with ``closed_form_error`` (message of a closed form that refused the pose); ``validity``: the
    :class:`~carmkin.robot.validity.ValidityReport` of ``q`` (``None`` for NaN); ``closed_form``: the
    analytic result (or ``None``); ``branch_reports`` (:class:`BranchReport`); ``attempts``: the QP runs;
    ``pose_correction``: ``‖T_rigid − T‖_F`` by which a nearly rigid 4x4 target was projected onto the
    nearest rigid transform before solving (0 for a rigid target or an axis/aim target).
    """

    q: np.ndarray
    success: bool
    path: Path
    seed: str | None
    failure: Failure | None
    validity: object
    closed_form: object = None
    branch_reports: tuple[BranchReport, ...] = ()
    attempts: tuple[QPIKResult, ...] = ()
    closed_form_error: str | None = None
    pose_correction: float = 0.0

    @property
    def reasons(self) -> tuple[str, ...]:
        """Why it failed, one line per closed form, branch and QP run, for people (empty on success)."""
        if self.success:
            return ()
        lines = [f"closed form failed: {self.closed_form_error}"] if self.closed_form_error else []
        lines += [b.reason for b in self.branch_reports if b.reason]
        lines += [f"QP from {run.seed}: {run.reason}" for run in self.attempts if run.reason]
        return tuple(lines) or (self.failure.value,)

    @property
    def reason(self) -> str | None:
        """:attr:`reasons` joined by ``" | "`` (``None`` on success)."""
        return None if self.success else " | ".join(self.reasons)
