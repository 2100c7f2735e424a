"""Settings, errors and named tolerances of the QP IK (SI units)."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from carmkin.errors import (
    QPIKError,  # noqa: F401 (defined there, raised here)
)
from carmkin.validation import MAGNITUDE_LIMIT, integer
from carmkin.world.tolerances import DEFAULT_MARGIN

#: A run counts as clear of obstacles when every pair is at least ``safety_margin - MARGIN_TOLERANCE`` apart (m).
MARGIN_TOLERANCE = 1e-6
#: A joint within this of a bound (m or rad) is reported as "at its limit" in a stalled run.
AT_LIMIT_TOLERANCE = 1e-9
#: Largest count of QPIKOptions (max_iterations, progress_window): a guard against a float such as 1e300 read
#: as a count, far above any run (the default is 100 iterations).
MAX_ITERATIONS = 10_000_000
#: Frame of the X-ray source, the end effector of the C-arm chain.
SOURCE_FRAME = "xray_source"


@dataclass(frozen=True)
class QPIKOptions:
    """Settings of the QP IK (SI units).

    position_tolerance (m), angle_tolerance (rad): convergence test on every task. max_iterations.
    damping, error_damping: ``lambda = damping + error_damping * E``. max_step: bound on each |dq_i|
    (m or rad) per iteration. safety_margin (m): minimum distance kept between collision pairs (default :data:`carmkin.world.DEFAULT_MARGIN`).
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
    safety_margin: float = DEFAULT_MARGIN
    influence_distance: float = 0.1
    collision_gain: float = 0.5
    stall_step: float = 1e-12
    progress_window: int = 10
    progress_ratio: float = 0.9

    def __post_init__(self) -> None:
        for f in fields(self):  # numbers only: a bool, a string or a complex is refused, naming the field
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
                raise QPIKError(f"QPIKOptions.{f.name} must be a real number, got {value!r}")
            if abs(value) > MAGNITUDE_LIMIT:  # finite but absurd (1e300): no tolerance, step or gain is that large
                raise QPIKError(f"QPIKOptions.{f.name} must be within ±{MAGNITUDE_LIMIT:g}, got {value!r}")
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
        for name in ("max_iterations", "progress_window"):  # counts: an int, never a float truncated
            integer(getattr(self, name), f"QPIKOptions.{name}", low=1, high=MAX_ITERATIONS, error=QPIKError)
        if not (0 < self.progress_ratio <= 1):
            raise QPIKError(f"QPIKOptions.progress_ratio must be in (0, 1], got {self.progress_ratio}")


@dataclass(frozen=True)
class SearchOptions:
    """Which steps :func:`carmkin.qp_ik.solve` runs and which seeds it tries.

    ``closed_form``: try the closed form first (6-DOF, or single axis on a motorized table); ``qp``: run the
    QP when no branch is accepted; ``random_seeds``: uniform draws over the joint box tried last (``None``:
    :data:`carmkin.qp.prepared.DEFAULT_RANDOM_SEEDS`), drawn with numpy seed ``rng_seed``.
    """

    closed_form: bool = True
    qp: bool = True
    random_seeds: int | None = None
    rng_seed: int = 0

    def __post_init__(self) -> None:
        for name in ("closed_form", "qp"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise QPIKError(f"SearchOptions.{name} must be True or False, got {getattr(self, name)!r}")
        for name, low in (("random_seeds", 0), ("rng_seed", 0)):
            value = getattr(self, name)
            if value is None and name == "random_seeds":
                continue
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < low:
                raise QPIKError(f"SearchOptions.{name} must be an integer >= {low}, got {value!r}")
        object.__setattr__(self, "closed_form", bool(self.closed_form))
        object.__setattr__(self, "qp", bool(self.qp))
