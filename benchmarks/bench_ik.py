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
from _timing import per_target_medians, row  # noqa: E402

import carmkin  # noqa: E402
from carmkin import analytic_ik  # noqa: E402
from carmkin.analytic import dls as numerical_ik  # noqa: E402
from carmkin.model.sampling import random_configurations, random_system  # noqa: E402


def view_grid(system, shift_deg: float = 0.0) -> np.ndarray:
    """Poses of an integer-degree grid of views (issue 20): angle p about the wigwag axis (−89..89°), tilt s
    (−45..45°) and roll r about the beam (0, 60, ..., 300°), 179 x 91 x 6 = 97 734 poses, the source 0.6 m
    from a fixed point. At s = 0 and r = 0 or 180° the source X axis lies along the wigwag axis: cos θ4 = 0,
    the singular family (0.37 % of the grid). p = ±90° is left out: there the wigwag angle is ±90° (far
    outside its range), singular case (c), whose poses still go through damped least squares one by one
    (a separate cliff, not this benchmark's). ``shift_deg`` moves every angle off the integers."""
    R_K = analytic_ik.solver_for(system).R
    p, s, r = np.meshgrid(np.arange(-89, 90) + shift_deg, np.arange(-45, 46) + shift_deg,
                          np.arange(0, 360, 60) + shift_deg, indexing="ij")
    p, s, r = (np.radians(a.ravel()) for a in (p, s, r))

    def rot(axis, angle):
        c, s_ = np.cos(angle), np.sin(angle)
        R = np.zeros(angle.shape + (3, 3))
        i, j = [k for k in range(3) if k != axis]
        R[..., axis, axis] = 1.0
        R[..., i, i], R[..., j, j], R[..., i, j], R[..., j, i] = c, c, -s_, s_
        return R

    base = rot(1, np.array(-np.pi / 2))  # source X along the wigwag axis (K's Z) at p = s = r = 0
    R = R_K @ rot(2, p + np.pi / 2) @ rot(0, s) @ base @ rot(2, r)  # p = 0: the wigwag at 0 (γ3 of the preset)
    target = system.fk(0.5 * (system.lower + system.upper))[:3, 3]
    T = np.zeros((len(p), 4, 4))
    T[:, :3, :3], T[:, 3, 3] = R, 1.0
    T[:, :3, 3] = target - 0.6 * R[:, :, 2]
    return T


def grid_cliff(system, quick: bool) -> None:
    """The integer-degree view grid beside the same grid shifted by 0.37° (issue 20's cliff)."""
    grids = {"integer-degree grid": view_grid(system), "grid shifted by 0.37°": view_grid(system, 0.37)}
    times, counts = {}, {}
    for label, Ts in grids.items():
        analytic_ik.solve_batch(system, Ts[:10])
        runs = []
        for _ in range(2 if quick else 5):
            start = time.perf_counter()
            result = analytic_ik.solve_batch(system, Ts)
            runs.append(time.perf_counter() - start)
        times[label] = statistics.median(runs)
        singular = counts[label] = int((np.abs(result.det_j) < analytic_ik.SINGULAR_TOLERANCE).sum())
        print(f"solve_batch on the {label} ({len(Ts)} view poses): {times[label]:.3f} s; {singular} singular "
              f"({100 * singular / len(Ts):.2f} %), {int(result.numerical.sum())} solved numerically; "
              f"worst FK residual {float(np.nanmax(result.residual)):.1e}")
    # the damped-least-squares fallback these poses took before (issue 20): per pose, on a sample
    from carmkin.analytic import singular

    Ts = grids["integer-degree grid"]
    ik = analytic_ik.solver_for(system)
    family = [T for T in Ts if abs(analytic_ik.solve(system, T).det_j) < analytic_ik.SINGULAR_TOLERANCE][:20]
    start = time.perf_counter()
    for T in family:
        q0, q1, det_j, _ = ik.angles_and_translations(T.tolist())
        singular.solve_numerical(ik, T, T.tolist(), (0.0,) * 6, q0, q1, det_j)
    per_pose = (time.perf_counter() - start) / max(len(family), 1)
    print(f"the numerical fallback these singular poses took before: {per_pose * 1e3:.2f} ms per pose "
          f"(mean of {len(family)}), {per_pose * counts['integer-degree grid']:.2f} s for the grid's {counts['integer-degree grid']}")
    ratio = times["integer-degree grid"] / times["grid shifted by 0.37°"]
    print(f"integer-degree grid / shifted grid: {ratio:.2f}x (the singular family in closed form, vectorised)")


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

    t_cf = per_target_medians(lambda T: analytic_ik.solve(system, T).q, targets, inner=20)
    q_current = 0.5 * (lower + upper)
    t_cf_current = per_target_medians(lambda T: analytic_ik.solve(system, T, q_current).q, targets, inner=20)

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
    print(row("analytic_ik.solve(T).q, both branches + selection", t_cf, t_dls))
    print(row("analytic_ik.solve(T, q_current).q", t_cf_current, t_dls))
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

    grid_cliff(system, args.quick)

    # accuracy: FK(IK(T)) = T over many random systems (closed-form FK of the returned solutions)
    n_systems = 20 if args.quick else 100
    worst, total, numerical = 0.0, 0, 0
    for _ in range(n_systems):
        sys_r = random_system(rng, system)
        Ts = sys_r.fk(random_configurations(rng, sys_r, 1000))
        result = analytic_ik.solve_batch(sys_r, Ts)
        ok = result.reached
        for k in range(2):
            worst = max(worst, float(np.abs(sys_r.fk(result.solutions[k, ok[k]], check_units=False) - Ts[ok[k]]).max(initial=0.0)))
        total += len(Ts)
        numerical += int(result.numerical.sum())
    print(f"round trip FK(IK(T)) over {total} poses on {n_systems} random non-isocentric systems and table setups: "
          f"worst matrix-entry error {worst:.2e} (both branches; {numerical} singular poses solved numerically)")


if __name__ == "__main__":
    main()
