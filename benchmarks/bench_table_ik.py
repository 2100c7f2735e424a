"""The one solve on both presets, and the multi-DOF table workspace study (issue 12 acceptance).

1. ``carmkin.qp_ik.solve(system, T)`` WITHOUT q_current or seeds, on ``siremobile-iso-c3d-motorized-table``
   (11 joints) and ``siremobile-iso-c3d`` (6): targets are the ``xray_source`` poses of uniform random
   in-range configurations whose collision pairs are all at least the safety margin (10 mm) apart
   (:func:`carmkin.studies.table_workspace.desired_configurations`). Success: the solve says so and the
   answer is re-checked here, independently of it: joints in range, every pair >= margin - 1e-6 m (fresh
   scene), pose within 1e-6 m / 1e-6 rad by the closed-form FK. Median time per target. Baselines in the same
   run: on the motorized preset the QP alone from mid-range (``closed_form=False, random_seeds=0``, the old
   ``carmkin.qp_ik.solve`` path there); on the plain preset the 6-DOF closed form alone
   (``carmkin.analytic_ik.solve``, no validity check).
2. ``carmkin workspace --table-dofs compare`` (:func:`carmkin.studies.table_workspace.run_study`, all four
   models, 300 poses, seed 0): wall and CPU time (all processes) and the reachable fractions, as run now
   (misses proved by the reach bound and nested rows skipped, worker processes) and, in the same run, as
   before (one process, every pose of every row solved: the previous algorithm, on today's faster collision
   queries, so the ratio understates the gain over the 150-170 s of issue 12 / ~29 s CPU before this change);
   the fractions must be equal.

    python benchmarks/bench_table_ik.py            # 500 targets per preset + the 300-pose study
    python benchmarks/bench_table_ik.py --quick    # 100 targets + a 30-pose study
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pinocchio as pin

import carmkin
from carmkin import analytic_ik, qp_ik
from carmkin.world import World
from carmkin.studies import table_workspace
from carmkin.studies.table_workspace import desired_configurations

MOTORIZED, PLAIN = "siremobile-iso-c3d-motorized-table", "siremobile-iso-c3d"
#: Independent re-check of an answer: pose (m, rad) and margin slack (m).
POSE_TOLERANCE, MARGIN_SLACK = 1e-6, 1e-6


def correct(system, scene, q, T, margin) -> bool:
    if not np.all(np.isfinite(q)) or np.any(q < system.lower) or np.any(q > system.upper):
        return False
    F = system.fk(q)
    if np.linalg.norm(F[:3, 3] - T[:3, 3]) > POSE_TOLERANCE or np.linalg.norm(pin.log3(T[:3, :3].T @ F[:3, :3])) > POSE_TOLERANCE:
        return False
    return scene.distances(q=q).min() >= margin - MARGIN_SLACK


def run(system, poses, solve) -> tuple[float, float, dict]:
    """(success fraction, median seconds per target, count per path) of ``solve(T) -> result``."""
    scene = World(system)
    margin = qp_ik.QPIKOptions().safety_margin
    ok, times, paths = 0, [], {}
    for T in poses:
        start = time.perf_counter()
        result = solve(T)
        times.append(time.perf_counter() - start)
        q = getattr(result, "q", None)
        if q is None:  # the closed-form baseline: the chosen branch, unchecked
            q = result.solutions[result.chosen]
        good = getattr(result, "success", True) and correct(system, scene, q, T, margin)
        ok += good
        path = getattr(getattr(result, "path", None), "value", "closed form only")
        paths[path] = paths.get(path, 0) + 1
    return ok / len(poses), float(np.median(times)), paths


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100 targets and a 30-pose study")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    n = 100 if args.quick else 500
    for name in (MOTORIZED, PLAIN):
        system = carmkin.load_preset(name)
        poses = system.fk(desired_configurations(system, n, seed=args.seed))
        qp_ik.solve(system, poses[0])  # build the cached scene and models outside the timing
        rate, median, paths = run(system, poses, lambda T: qp_ik.solve(system, T))
        if system.nq == 6:
            label = "6-DOF closed form alone (unchecked)"
            base_rate, base_median, _ = run(system, poses, lambda T: analytic_ik.solve(system, T))
        else:
            label = "QP alone from mid-range"
            base_rate, base_median, _ = run(
                system, poses, lambda T: qp_ik.solve(system, T, closed_form=False, random_seeds=0))
        print(f"{name}: {system.nq} joints, {n} random clear targets (seed {args.seed}), solve(system, T) without seeds")
        print(f"  {'one solve':<40}{rate:>9.2%} reached  median {median * 1e3:7.2f} ms   paths {paths}")
        print(f"  {'baseline: ' + label:<40}{base_rate:>9.2%} reached  median {base_median * 1e3:7.2f} ms"
              f"   (one solve: {median / base_median:.2f}x its median time)")
        bound = "" if system.nq != 6 else f", median <= 2 ms: {'PASS' if median <= 2e-3 else 'FAIL'}"
        print(f"  acceptance >= 99.5 %: {'PASS' if rate >= 0.995 else 'FAIL'}{bound}")
    system = carmkin.load_preset(MOTORIZED)
    poses_study = 30 if args.quick else 300
    runs = {}
    for label, kwargs in (("one process, every row solved (previous)", dict(workers=1, nested=False, bound=False)),
                          ("reach bound + nested rows + worker processes (now)", dict())):
        results, wall, cpu = timed_study(system, poses_study, **kwargs)
        runs[label] = (wall, cpu, [r.fraction for r in results])
        print(f"workspace --table-dofs compare ({poses_study} poses, seed 0), {label}: {wall:.1f} s wall, "
              f"{cpu:.1f} s CPU (all processes)")
        for row in table_workspace.table_rows(results):
            print("  " + row)
    (old_wall, old_cpu, old_fractions), (wall, cpu, fractions) = runs.values()
    print(f"  now / previous: {wall / old_wall:.2f}x wall, {cpu / old_cpu:.2f}x CPU; same fractions: "
          f"{'yes' if fractions == old_fractions else 'NO'}; acceptance <= 30 s wall at 300 poses"
          + (f": {'PASS' if wall <= 30 else 'FAIL'}" if poses_study == 300 else " (not checked at --quick)"))


def cpu_seconds() -> float:
    """User + system CPU (s) of this process and of its waited-for children (the study's workers)."""
    import resource

    return sum(getattr(resource.getrusage(who), field) for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)
               for field in ("ru_utime", "ru_stime"))


def timed_study(system, n, **kwargs):
    """(results, wall s, CPU s) of the four-row study over ``n`` poses, seed 0."""
    wall, cpu = time.perf_counter(), cpu_seconds()
    _, results = table_workspace.run_study(system, n=n, seed=0, **kwargs)
    return results, time.perf_counter() - wall, cpu_seconds() - cpu

if __name__ == "__main__":
    main()
