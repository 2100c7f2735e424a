"""Inverse kinematics: closed-form `analytic_ik.solve` (both branches + selection, from a 4x4 numpy pose) next
to Pinocchio damped least squares on the same targets, and `solve_batch` throughput, in the same run.

Targets: FK of random configurations inside the joint ranges of the preset. The DLS baseline
(`carmkin.analytic.dls`, Pinocchio frame Jacobian, tolerance 1e-9, at most 100 iterations) starts from the
middle of the joint ranges; its success rate is printed. Run: python benchmarks/bench_ik.py [--quick]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _timing import row  # noqa: E402

import carmkin  # noqa: E402
from carmkin import analytic_ik  # noqa: E402
from carmkin.analytic import dls as numerical_ik  # noqa: E402
from carmkin.model.sampling import random_configurations, random_system  # noqa: E402


def per_target_medians(call, targets, inner: int) -> float:
    """Median over targets of the mean time of ``inner`` calls on that target (s)."""
    times = []
    for T in targets:
        start = time.perf_counter()
        for _ in range(inner):
            call(T)
        times.append((time.perf_counter() - start) / inner)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer targets and repetitions (CI)")
    args = parser.parse_args()
    n_targets, n_dls, n_batch = (300, 50, 100_000) if args.quick else (3000, 300, 200_000)

    system = carmkin.load_preset("siremobile-iso-c3d")
    rng = np.random.default_rng(0)
    lower, upper = system.lower, system.upper
    q_targets = rng.uniform(lower, upper, size=(n_targets, 6))
    targets = list(system.fk(q_targets))
    analytic_ik.solve(system, targets[0])  # build the per-system solver once

    t_cf = per_target_medians(lambda T: analytic_ik.solve(system, T), targets, inner=20)
    q_current = 0.5 * (lower + upper)
    t_cf_current = per_target_medians(lambda T: analytic_ik.solve(system, T, q_current), targets, inner=20)

    dls = numerical_ik.solver_for(system)
    runs, dls_times = [], []
    for T in targets[:n_dls]:
        start = time.perf_counter()
        runs.append(dls.solve(T, q_current))
        dls_times.append(time.perf_counter() - start)
    t_dls = statistics.median(dls_times)
    success = np.mean([r.success for r in runs])
    iterations = statistics.median(r.iterations for r in runs)

    print(f"Inverse kinematics of xray_source (preset {system.name}), {n_targets} targets in the joint ranges")
    print(row("Pinocchio DLS from mid-range (baseline)", t_dls))
    print(row("analytic_ik.solve, both branches + selection", t_cf, t_dls))
    print(row("analytic_ik.solve with q_current", t_cf_current, t_dls))
    print(f"DLS success rate (residual <= 1e-9 within 100 iterations): {success:.1%} of {n_dls}, "
          f"median {iterations:.0f} iterations; closed form: speed-up {t_dls / t_cf:.0f}x")

    # batch throughput: one random non-isocentric system with a random table setup, and the preset
    for label, sys_b in (("preset", system), ("random non-isocentric system", random_system(rng, system))):
        Ts = sys_b.fk(random_configurations(rng, sys_b, n_batch))
        analytic_ik.solve_batch(sys_b, Ts[:10])
        times = []
        for _ in range(3 if args.quick else 7):
            start = time.perf_counter()
            result = analytic_ik.solve_batch(sys_b, Ts)
            times.append(time.perf_counter() - start)
        t = statistics.median(times)
        print(f"solve_batch, N = {n_batch} ({label}): {n_batch / t / 1e6:.2f} M poses/s "
              f"(both branches + selection; {int(result.numerical.sum())} singular poses solved numerically), "
              f"{t / n_batch * 1e9:.0f} ns/pose; {t_cf / (t / n_batch):.0f}x the scalar path")

    # accuracy: FK(IK(T)) = T over many random systems (closed-form FK of the returned solutions)
    n_systems = 20 if args.quick else 100
    worst, total, numerical = 0.0, 0, 0
    for _ in range(n_systems):
        sys_r = random_system(rng, system)
        Ts = sys_r.fk(random_configurations(rng, sys_r, 1000))
        result = analytic_ik.solve_batch(sys_r, Ts)
        ok = result.reached
        for k in range(2):
            worst = max(worst, float(np.abs(sys_r.fk(result.solutions[k, ok[k]]) - Ts[ok[k]]).max(initial=0.0)))
        total += len(Ts)
        numerical += int(result.numerical.sum())
    print(f"round trip FK(IK(T)) over {total} poses on {n_systems} random non-isocentric systems and table setups: "
          f"worst matrix-entry error {worst:.2e} (both branches; {numerical} singular poses solved numerically)")


if __name__ == "__main__":
    main()
