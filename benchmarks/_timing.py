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


def paired_ratio(baseline: Callable[[object], object], candidate: Callable[[object], object], targets,
                 inner: int = 20, rounds: int = 5) -> tuple[float, float, float]:
    """``candidate`` against ``baseline`` timed side by side on each target: ``rounds`` alternating runs of
    ``inner`` calls each, the fastest run of each kept (the machine's other load only ever adds time), their
    ratio per target; returns the medians over targets of the baseline's and the candidate's time (s) and of
    the per-target ratio. On a shared machine whose load drifts, timing the two at different moments (two
    :func:`per_target_medians`) moved the ratio by 2x between runs; pairing them cancels the drift."""

    def best(call, target) -> float:
        start = time.perf_counter()
        for _ in range(inner):
            call(target)
        return (time.perf_counter() - start) / inner

    base, cand, ratios = [], [], []
    for target in targets:
        b = c = float("inf")
        for _ in range(rounds):
            b, c = min(b, best(baseline, target)), min(c, best(candidate, target))
        base.append(b)
        cand.append(c)
        ratios.append(c / b)
    return statistics.median(base), statistics.median(cand), statistics.median(ratios)
