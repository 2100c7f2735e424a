"""Timing helpers shared by the benchmarks: medians of repeated calls, printed side by side with ratios."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable


def median_time(call: Callable[[], object], repeat: int = 2000, inner: int = 1) -> float:
    """Median wall time (s) of ``inner`` consecutive calls divided by ``inner``, over ``repeat`` runs."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        for _ in range(inner):
            call()
        times.append((time.perf_counter() - start) / inner)
    return statistics.median(times)


def row(label: str, seconds: float, baseline: float | None = None, unit: str = "µs") -> str:
    """One aligned line: label, time in ``unit``, and the ratio to ``baseline`` when given."""
    scale = {"s": 1.0, "ms": 1e3, "µs": 1e6}[unit]
    ratio = f"{seconds / baseline:8.2f}x baseline" if baseline else ""
    return f"{label:<48}{seconds * scale:12.3f} {unit:<3}{ratio}"


def per_target_medians(call: Callable[[object], object], targets, inner: int = 20) -> float:
    """Median over targets of the mean time (s) of ``inner`` consecutive calls ``call(target)``."""
    times = []
    for target in targets:
        start = time.perf_counter()
        for _ in range(inner):
            call(target)
        times.append((time.perf_counter() - start) / inner)
    return statistics.median(times)
