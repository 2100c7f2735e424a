"""Forward kinematics: closed form (scalar, batch of 100 000) next to Pinocchio's FK in the same run, on the
6-joint preset and the motorized table (11 joints); and the closed-form IK's scalar path next to
Pinocchio's damped least squares, as the two ratios issue 27 bounds:

- ``system.fk(q)`` for one configuration / Pinocchio's FK returning a 4x4 (forwardKinematics +
  updateFramePlacement + ``.homogeneous``): at most 8x;
- Pinocchio DLS (``carmkin.analytic.dls``, from mid-range) / ``analytic_ik.solve``: at least 50x.

Run: python benchmarks/bench_fk.py [--quick]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).parent))
from _timing import median_time, per_target_medians, row  # noqa: E402

import carmkin  # noqa: E402
from carmkin import analytic_ik  # noqa: E402
from carmkin.analytic import dls as numerical_ik  # noqa: E402
from carmkin.model.sampling import random_configurations  # noqa: E402

#: Issue 27's bounds on the two ratios printed last.
MAX_FK_RATIO, MIN_IK_RATIO = 8.0, 50.0


def scalar_fk(system, rng, repeat: int) -> tuple[float, float]:
    """``(Pinocchio FK returning a 4x4, system.fk(q))`` median seconds per call on the same q, same run."""
    model = system.pinocchio()[0]
    data = model.createData()
    frame = model.getFrameId("xray_source")
    q = random_configurations(rng, system, 1)[0]

    def pinocchio_fk_homogeneous():
        pin.forwardKinematics(model, data, q)
        return pin.updateFramePlacement(model, data, frame).homogeneous

    return median_time(pinocchio_fk_homogeneous, repeat, inner=20), median_time(lambda: system.fk(q), repeat, inner=20)


def ik_ratio(system, rng, n_targets: int, n_dls: int) -> tuple[float, float]:
    """``(Pinocchio DLS from mid-range, analytic_ik.solve)`` median seconds per target, same targets."""
    targets = list(system.fk(random_configurations(rng, system, n_targets)))
    analytic_ik.solve(system, targets[0])  # build the per-system solver once
    t_cf = per_target_medians(lambda T: analytic_ik.solve(system, T).q, targets, inner=20)
    dls, q_mid = numerical_ik.solver_for(system), 0.5 * (system.lower + system.upper)
    times = []
    for T in targets[:n_dls]:
        start = time.perf_counter()
        dls.solve(T, q_mid)
        times.append(time.perf_counter() - start)
    return statistics.median(times), t_cf


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer repetitions (CI)")
    args = parser.parse_args()
    repeat = 200 if args.quick else 3000
    n_batch = 100_000
    rng = np.random.default_rng(0)

    system = carmkin.load_preset("siremobile-iso-c3d")
    model = system.pinocchio()[0]
    data = model.createData()
    frame = model.getFrameId("xray_source")
    qs = random_configurations(rng, system, n_batch)
    q = qs[0]

    def pinocchio_fk():
        pin.forwardKinematics(model, data, q)
        return pin.updateFramePlacement(model, data, frame)

    t_pin = median_time(pinocchio_fk, repeat, inner=20)
    t_pin_np, t_cf = scalar_fk(system, rng, repeat)

    start = time.perf_counter()
    system.fk(qs)
    t_batch = (time.perf_counter() - start) / n_batch
    n_loop = n_batch // (10 if args.quick else 1)
    start = time.perf_counter()
    for qk in qs[:n_loop]:
        pin.forwardKinematics(model, data, qk)
        pin.updateFramePlacement(model, data, frame)
    t_pin_loop = (time.perf_counter() - start) / n_loop

    print("Forward kinematics of xray_source in the table frame (preset siremobile-iso-c3d)")
    print(row("Pinocchio forwardKinematics+frame (baseline)", t_pin))
    print(row("Pinocchio, returning a 4x4 numpy array", t_pin_np, t_pin))
    print(row("closed form system.fk(q), scalar", t_cf, t_pin))
    print(row(f"Pinocchio Python loop over {n_loop} q, per pose", t_pin_loop, t_pin))
    print(row(f"closed form system.fk(Q), batch of {n_batch}, per pose", t_batch, t_pin))
    print(f"batch throughput: {1 / t_batch / 1e6:.2f} M poses/s (Pinocchio loop: {1 / t_pin_loop / 1e6:.2f} M poses/s)")

    motorized = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
    t_pin_m, t_cf_m = scalar_fk(motorized, rng, repeat)
    print(f"\nmotorized table ({motorized.nq} joints; the table motion composes in front)")
    print(row("Pinocchio, returning a 4x4 numpy array", t_pin_m))
    print(row("closed form system.fk(q), scalar", t_cf_m, t_pin_m))

    t_dls, t_ik = ik_ratio(system, rng, *((300, 50) if args.quick else (3000, 300)))
    print("\nclosed-form IK, scalar path (siremobile-iso-c3d)")
    print(row("Pinocchio DLS from mid-range", t_dls))
    print(row("analytic_ik.solve(T).q", t_ik, t_dls))

    print(f"\nscalar FK ratio fk / pinocchio (4x4): {t_cf / t_pin_np:.2f}x (siremobile-iso-c3d), "
          f"{t_cf_m / t_pin_m:.2f}x (motorized table); bound <= {MAX_FK_RATIO:g}x")
    print(f"closed-form IK ratio pinocchio DLS / analytic_ik.solve: {t_dls / t_ik:.0f}x; bound >= {MIN_IK_RATIO:g}x")


if __name__ == "__main__":
    main()
