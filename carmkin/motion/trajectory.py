"""A planned motion: the joint path, its time law and its certificate (SI units, the system's joint order)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from carmkin.errors import MotionPlanError
from carmkin.validation import real_array


@dataclass(frozen=True)
class Trajectory:
    """A motion from ``waypoints[0]`` to ``waypoints[-1]``.

    ``success``: a certified path was found (``reason`` says why not otherwise; a search that ran out of time
    says "not found within N s", never that no path exists). ``waypoints`` (k+1, nq) m and rad: the polyline
    executed (straight segments, each from rest to rest); ``times`` (k+1,) s: when each is reached;
    ``duration`` (s); ``min_clearance`` (m): a certified lower bound of every pair's distance along the
    executed path (within :data:`carmkin.world.DEFAULT_TOLERANCE` of the true minimum), ``pair``
    the (link, link) that holds it; ``margin`` (m) the clearance the path was planned to keep; ``method``:
    ``"straight"`` (the direct segment was certified) or the OMPL planner that found the path;
    ``planning_s``: seconds spent planning; ``joint_names``."""

    success: bool
    reason: str | None
    waypoints: np.ndarray
    times: np.ndarray
    min_clearance: float
    pair: tuple[str, str] | None
    margin: float
    method: str
    planning_s: float
    joint_names: tuple[str, ...]
    law: object = field(default=None, repr=False, compare=False)  # the TimeLaw (None when not found)

    @property
    def duration(self) -> float:
        """Seconds from start to goal (0 for a failed plan)."""
        return float(self.times[-1]) if self.success else 0.0

    def sample(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q, q̇, q̈)`` each (len(t), nq) at times ``t`` (s) in [0, duration] (m, m/s, m/s² and rad,
        rad/s, rad/s²)."""
        if not self.success:
            raise MotionPlanError(f"this trajectory has no time law: {self.reason}")
        t = real_array(t, "t", (None,) if np.ndim(t) else (), error=MotionPlanError, unit="s").reshape(-1)
        bad = (t < 0.0) | (t > self.duration)
        if bad.any():
            raise MotionPlanError(f"t must lie in [0, {self.duration:.6g}] s (the trajectory's duration), got "
                                  f"{t[bad][0]:.6g} s")
        return self.law.sample(t)

    def __str__(self) -> str:
        if not self.success:
            return f"no motion: {self.reason}"
        a, b = self.pair if self.pair else ("-", "-")
        return (f"{self.method}, {len(self.waypoints) - 1} segment(s), {self.duration:.2f} s, clearance ≥ "
                f"{self.min_clearance * 1e3:.1f} mm ({a} – {b}), planned in {self.planning_s * 1e3:.0f} ms")
