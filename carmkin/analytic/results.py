"""Results of the closed-form IK (:mod:`carmkin.analytic_ik`): the status of each branch, the result of one
pose and of a batch. Joint order ``[d0, d1, θ2, d3, θ4, θ5]`` (m, rad); residuals are
max(position error m, rotation angle rad) of FK against the target."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from carmkin.transforms import pose_error

FLOAT = np.float64


@dataclass(eq=False)
class BranchStatus:
    """Status of one IK branch.

    ``within_limits``: every joint inside its range; ``excess``: joint name -> signed excess (m or rad;
    < 0 below the lower limit, > 0 above the upper) for the out-of-range joints only; ``singular``: names of
    the singular cases (:data:`~carmkin.analytic.closed_form.SINGULAR_CASES`) of the pose, empty when regular; ``numerical``: solved by
    damped least squares; ``reached``: the solution meets the pose (always for the closed form; for a
    numerical one, residual ≤ 1e-9); ``residual``: max(position error m, rotation angle rad) of FK of the
    solution against the target — measured by the numerical solver, computed on first access otherwise.
    """

    within_limits: bool
    excess: dict
    singular: tuple = ()
    numerical: bool = False
    reached: bool = True
    _residual: float | None = field(default=None, repr=False, compare=False)
    _pose_check: object = field(default=None, repr=False, compare=False)

    @cached_property
    def residual(self) -> float:
        if self._residual is not None:
            return self._residual
        return float(self._pose_check())

    @property
    def status(self) -> str:
        """``"ok"``, ``"out of range"``, ``"singular"`` or ``"singular, out of range"`` (unreached:
        ``"singular, unsolved"``)."""
        if not self.reached:
            return "singular, unsolved"
        parts = (["singular"] if self.singular else []) + ([] if self.within_limits else ["out of range"])
        return ", ".join(parts) or "ok"


class IKResult:
    """Both IK solutions of one pose and the chosen one.

    ``solutions`` (2, 6): branch 0 (cos θ4 > 0) and branch 1, joint order ``[d0, d1, θ2, d3, θ4, θ5]``
    (m, rad); ``chosen``: index of the branch picked by the rules of §4.4.2; ``branches``: the two
    :class:`BranchStatus`; ``det_j``: det J of eq. 4.7 at the pose (same for both branches);
    ``pose_correction``: ``‖T_rigid − T‖_F`` by which a nearly rigid ``T`` was projected onto the nearest
    rigid transform (:mod:`carmkin.analytic.poses`; 0 for a rigid one); :attr:`validity`: the §4.4.3
    validity report of the chosen solution at the one default margin (computed on first read).

    The solver computes every value; the scalar path hands over the two branches as lists and the branch
    statuses as a callable, and the array and the status objects are built on first read (packaging them
    cost a third of a scalar solve). ``solutions`` may be given as an array or as two sequences of six floats,
    ``branches`` as a tuple or as a callable returning it.
    """

    __slots__ = ("_solutions", "chosen", "_branches", "det_j", "pose_correction", "_check", "_q", "_validity")

    def __init__(self, solutions, chosen: int, branches, det_j: float, pose_correction: float = 0.0) -> None:
        self._solutions = solutions
        self.chosen = chosen
        self._branches = branches
        self.det_j = det_j
        self.pose_correction = pose_correction
        self._check = self._q = self._validity = None

    def __repr__(self) -> str:
        return (f"IKResult(solutions={self.solutions!r}, chosen={self.chosen}, branches={self.branches!r}, "
                f"det_j={self.det_j!r}, pose_correction={self.pose_correction!r})")

    # solutions, branches, q and validity cache by hand: functools.cached_property takes a lock on Python 3.11 and
    # costs more than the closed form's arithmetic

    @property
    def solutions(self) -> np.ndarray:
        """(2, 6): both branches (m, rad)."""
        if type(self._solutions) is not np.ndarray:
            self._solutions = np.array(self._solutions, dtype=float)
        return self._solutions

    @property
    def branches(self) -> tuple:
        """The two :class:`BranchStatus`."""
        if callable(self._branches):
            self._branches = self._branches()
        return self._branches

    @property
    def validity(self):
        """The :class:`~carmkin.robot.validity.ValidityReport` of the chosen solution at
        :data:`carmkin.world.DEFAULT_MARGIN` (joints, clearance to table and floor, table in the cone): the
        verdict :func:`carmkin.robot.validity.check` and :func:`carmkin.qp_ik.solve` give the same configuration;
        ``None`` for an unsolved pose. :attr:`valid` is the joint-range part of it."""
        if self._validity is None and self._check is not None and np.all(np.isfinite(self.q)):
            check, system = self._check  # set by carmkin.analytic_ik.solve: (check(system, q), system)
            self._validity = check(system, self.q)
        return self._validity

    @property
    def q(self) -> np.ndarray:
        """The chosen solution (6,): a copy of row :attr:`chosen` of :attr:`solutions`."""
        if self._q is None:
            self._q = np.array(self._solutions[self.chosen], FLOAT)
        return self._q

    @property
    def valid(self) -> bool:
        """The chosen branch is within the joint ranges (and reaches the pose): the kinematic part of
        :attr:`validity` (which adds the clearance at the default margin and the table in the cone)."""
        status = self.branches[self.chosen]
        return status.within_limits and status.reached

    @property
    def singular(self) -> tuple:
        """Names of the singular cases of the pose (empty when regular)."""
        return self.branches[0].singular

    @property
    def numerical(self) -> bool:
        """True when the solutions come from the numerical fallback."""
        return self.branches[0].numerical


@dataclass(frozen=True)
class BatchResult:
    """IK of N poses: ``solutions`` (2, N, 6); ``chosen`` (N,) int; ``within_limits`` (2, N) bool;
    ``excess`` (2, N, 6) signed excess (0 inside the range); ``singular`` (N, 3) bool, one column per case
    of :data:`~carmkin.analytic.closed_form.SINGULAR_CASES`; ``numerical`` (N,) bool; ``reached`` (2, N) bool; ``det_j`` (N,).
    ``residual`` (2, N) is computed on first access (batch FK); ``pose_correction`` (N,): as
    :attr:`IKResult.pose_correction`, per pose."""

    solutions: np.ndarray
    chosen: np.ndarray
    within_limits: np.ndarray
    excess: np.ndarray
    singular: np.ndarray
    numerical: np.ndarray
    reached: np.ndarray
    det_j: np.ndarray
    _system: object = field(repr=False, compare=False)
    _poses: np.ndarray = field(repr=False, compare=False)
    pose_correction: np.ndarray | None = None

    @property
    def q(self) -> np.ndarray:
        """Chosen solutions (N, 6)."""
        return self.solutions[self.chosen, np.arange(self.solutions.shape[1])]

    @property
    def valid(self) -> np.ndarray:
        """(N,) bool: the chosen branch is within the joint ranges and reaches the pose."""
        index = np.arange(len(self.chosen))
        return self.within_limits[self.chosen, index] & self.reached[self.chosen, index]

    @cached_property
    def residual(self) -> np.ndarray:
        """(2, N): max(position error m, rotation angle rad) of FK of each solution against its pose (NaN for
        an unsolved pose)."""
        n = self.solutions.shape[1]
        flat = self.solutions.reshape(2 * n, 6)
        finite = np.all(np.isfinite(flat), axis=1)  # an unsolved pose has NaN solutions: NaN residual
        out = np.full(2 * n, np.nan)
        if np.any(finite):
            poses = np.broadcast_to(self._poses[None], (2, n, 4, 4)).reshape(2 * n, 4, 4)
            out[finite] = np.maximum(*pose_error(self._system.fk(flat[finite], check_units=False), poses[finite]))
        return out.reshape(2, n)

