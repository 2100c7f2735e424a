"""The reproduced experiments (issue 21): time of one unit of each, against one camera reading.

Baseline, measured in the same run: one displayed camera reading (a pose estimate of the pattern under the
table, the unit every guidance update costs). Then one §4.6.2 task, one §4.6.3 panorama, one Table 3.1
procedure and one Table 3.2 procedure under the fitted error model, each as a multiple of the baseline,
and the projected time of the commands (`carmkin reproduce 4.6.2` runs ten tasks, `4.6.3` five panoramas,
`fit` 36 grid points × 10 tasks).

    python benchmarks/bench_reproduce.py            # 10 tasks, 3 procedures each
    python benchmarks/bench_reproduce.py --quick    # 2 tasks, 1 procedure each (CI)
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _timing import median_time, row

import carmkin
from carmkin.reproduce import chapter3, measure, repositioning, stitching
from carmkin.reproduce.error_model import ErrorModel
from carmkin.reproduce.fit import BEST_FIT


def per_unit(call, count: int) -> float:
    start = time.perf_counter()
    for _ in range(count):
        call()
    return (time.perf_counter() - start) / count


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    tasks, procedures = (2, 1) if args.quick else (10, 3)
    system = carmkin.load_preset("siremobile-iso-c3d")
    model = ErrorModel(corner_noise_px=BEST_FIT[0]).with_operator_scale(BEST_FIT[1])
    rng = np.random.default_rng(0)
    room = repositioning.make_room(system, model, rng)
    T = room.system.fk(np.array([0.0, 0.05, 0.0, 0.1, 0.1, 0.1]))
    baseline = median_time(lambda: measure.camera_reading(room.world, T, room.T_source_camera, rng), repeat=50)
    print(row("one camera reading (baseline)", baseline, unit="ms"))
    task = per_unit(lambda: repositioning.run_task(room, rng), tasks)
    print(row("one §4.6.2 task", task, baseline, unit="ms"))
    panorama = per_unit(lambda: stitching.run_procedure(room, rng), procedures)
    print(row("one §4.6.3 panorama", panorama, baseline, unit="ms"))
    print(row("one Table 3.1 procedure", per_unit(lambda: chapter3.overlap_errors(room, rng), procedures), baseline,
              unit="ms"))
    print(row("one Table 3.2 procedure", per_unit(lambda: chapter3.metric_measurements(room, rng), procedures),
              baseline, unit="ms"))
    print(f"projected: reproduce 4.6.2 {10 * task:.1f} s, 4.6.3 {5 * panorama:.1f} s, fit {360 * task:.0f} s "
          "(noisier grid points take more moves)")


if __name__ == "__main__":
    main()
