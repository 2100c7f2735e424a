"""Forward kinematics: closed form (scalar, batch of 100 000) next to Pinocchio's FK in the same run.

Run: python benchmarks/bench_fk.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).parent))
from _timing import median_time, row  # noqa: E402

import carmkin  # noqa: E402
from carmkin.model.sampling import random_configurations  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer repetitions (CI)")
    args = parser.parse_args()
    repeat = 200 if args.quick else 3000
    n_batch = 100_000

    system = carmkin.load_preset("siremobile-iso-c3d")
    model = system.pinocchio()[0]
    data = model.createData()
    frame = model.getFrameId("xray_source")
    rng = np.random.default_rng(0)
    qs = random_configurations(rng, system, n_batch)
    q = qs[0]

    def pinocchio_fk():
        pin.forwardKinematics(model, data, q)
        return pin.updateFramePlacement(model, data, frame)

    def pinocchio_fk_homogeneous():
        return pinocchio_fk().homogeneous

    t_pin = median_time(pinocchio_fk, repeat, inner=20)
    t_pin_np = median_time(pinocchio_fk_homogeneous, repeat, inner=20)
    t_cf = median_time(lambda: system.fk(q), repeat, inner=20)

    start = time.perf_counter()
    system.fk(qs)
    t_batch = (time.perf_counter() - start) / n_batch
    start = time.perf_counter()
    for qk in qs[: n_batch // (10 if args.quick else 1)]:
        pinocchio_fk()
    t_pin_loop = (time.perf_counter() - start) / (n_batch // (10 if args.quick else 1))

    print("Forward kinematics of xray_source in the table frame (preset siremobile-iso-c3d)")
    print(row("Pinocchio forwardKinematics+frame (baseline)", t_pin))
    print(row("Pinocchio, returning a 4x4 numpy array", t_pin_np, t_pin))
    print(row("closed form system.fk(q), scalar", t_cf, t_pin))
    print(row(f"Pinocchio Python loop over {n_batch} q, per pose", t_pin_loop, t_pin))
    print(row(f"closed form system.fk(Q), batch of {n_batch}, per pose", t_batch, t_pin))
    print(f"batch throughput: {1 / t_batch / 1e6:.2f} M poses/s (Pinocchio loop: {1 / t_pin_loop / 1e6:.2f} M poses/s)")


if __name__ == "__main__":
    main()
