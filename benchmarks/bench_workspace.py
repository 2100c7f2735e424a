"""Workspace study of §4.6.1 (110 565 poses): vectorized 5-DOF IK next to a per-pose loop in the same run.

Run: python benchmarks/bench_workspace.py [--quick]

Rows: the whole study (6-DOF FK of every pose, base-frame change, 5-DOF IK of all branches with FK
verification, statistics), the study with the general polynomial solver forced, and the baseline: the same
closed-form IK called pose by pose from Python, timed on a subset and scaled to all poses.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _timing import row  # noqa: E402

import carmkin  # noqa: E402
from carmkin.analytic import five_dof  # noqa: E402
from carmkin.studies import workspace  # noqa: E402


def best_of(call, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer repetitions and a smaller baseline subset (CI)")
    args = parser.parse_args()
    repeat, subset = (1, 500) if args.quick else (5, 3000)

    system = carmkin.load_preset("siremobile-iso-c3d")
    grid = workspace.PAPER_GRID
    q5 = grid.configurations()
    n = len(q5) * len(grid.translations_mm)

    t_study = best_of(lambda: workspace.run_study(system), repeat)
    p, z = workspace.desired_targets(system, q5, 0.4)
    t_poly = best_of(lambda: five_dof.solve(system.carm, p, z, method="polynomial"), max(1, repeat // 2))
    t_poly *= len(grid.translations_mm)  # one translation timed, scaled to all nine

    start = time.perf_counter()
    for i in range(subset):
        five_dof.solve(system.carm, p[i], z[i])
    t_loop = (time.perf_counter() - start) / subset * n

    print(f"Workspace study of §4.6.1: {n} poses (preset {system.name}), best of {repeat}")
    print(row("per-pose loop of the closed-form IK (baseline)", t_loop, unit="s"))
    print(row("whole study, vectorized closed form (ours)", t_study, t_loop, unit="s"))
    print(row("5-DOF IK alone, general polynomial solver", t_poly, t_loop, unit="s"))
    print(f"speed-up of the vectorized study over the per-pose loop: {t_loop / t_study:.0f}x")
    print(f"acceptance: whole study {t_study:.3f} s {'<=' if t_study <= 2.0 else '>'} 2 s")


if __name__ == "__main__":
    main()
