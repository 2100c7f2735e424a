"""Synthetic datasets (carmkin.datasets), with a parametric patient on the table:

1. pose sampling per prior on one core: poses/s and the accepted fraction, and the acceptance of issue 28 on
   every row — joints in range, exact coal clearance (validity's scene, pair by pair) ≥ the margin, P equal to
   K[R|t] of FK(q) to 1e-12 (relative), XA angles equal to the view's (DICOM route);
2. the standard-view prior's angles: KS test against N(view, 2.5°) and how much the feasibility cut moves them;
3. sampling on Ray: 2 workers against 1 (the same tasks, one at a time vs two at once, in the same Ray);
4. rendering: images/s end to end (sample, render in batches, label, write a Parquet shard) against raw
   nanodrr batched rendering of the same poses in the same run, at each size, on CPU and (when torch sees one)
   on the GPU, whose name is printed.

Run: python benchmarks/bench_dataset.py [--quick] [--part sampling|sd|ray|rendering]
(quick: 500 poses a prior, 40x30 images, CI-sized)
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

import carmkin
from carmkin import datasets, imaging
from carmkin.datasets import render, scale
from carmkin.errors import CarmkinError
from carmkin.interop import dicom
from carmkin.model.params import JOINT_RANGE_TOLERANCE
from carmkin.patient import ParametricPatient


def acceptance(system, patient, samples) -> dict:
    """Worst cases of the acceptance checks over every row (independent routes)."""
    from carmkin.robot import validity
    from carmkin.world import World

    scene = World(system, patient.obstacles())
    in_range = bool(np.all((samples.q >= system.lower - JOINT_RANGE_TOLERANCE)
                           & (samples.q <= system.upper + JOINT_RANGE_TOLERANCE)))
    worst_clear, worst_p, worst_angle, invalid = np.inf, 0.0, 0.0, 0
    for i, q in enumerate(samples.q):
        report = validity.check(system, q, margin=datasets.DEFAULT_MARGIN, world=scene)
        invalid += not report.reachable
        worst_clear = min(worst_clear, float(np.min(scene.distances(q=q))))
        P = imaging.projection_matrix(system, q)
        worst_p = max(worst_p, float(np.linalg.norm(samples.P[i] - P) / np.linalg.norm(P)))
        p, s, _ = dicom.xa_angles(system.fk(q), patient.pose())
        if np.isfinite(samples.nominal[i, 0]):
            worst_angle = max(worst_angle, abs((p - samples.nominal[i, 0] + 180) % 360 - 180),
                              abs(s - samples.nominal[i, 1]))
        else:
            worst_angle = max(worst_angle, abs(p - samples.primary_deg[i]), abs(s - samples.secondary_deg[i]))
    return {"in_range": in_range, "invalid": invalid, "min_clearance_mm": worst_clear * 1e3, "worst_P": worst_p,
            "worst_angle_deg": worst_angle}


def sampling(system, patient, n: int) -> None:
    print(f"--- pose sampling, {n} poses a prior, one core, {system.name} with a parametric patient "
          f"(margin {datasets.DEFAULT_MARGIN * 1e3:g} mm)")
    print(f"{'prior':<18}{'poses/s':>10}{'accepted':>10}  acceptance (every row)")
    for prior in datasets.PRIORS:
        datasets.sample_poses(system, prior, 20, seed=9, patient=patient)  # warm-up: world, lazy imports
        start = time.perf_counter()
        samples = datasets.sample_poses(system, prior, n, seed=0, patient=patient)
        seconds = time.perf_counter() - start
        a = acceptance(system, patient, samples)
        ok = a["in_range"] and not a["invalid"] and a["min_clearance_mm"] >= datasets.DEFAULT_MARGIN * 1e3 \
            and a["worst_P"] <= 1e-12 and a["worst_angle_deg"] <= 1e-6
        print(f"{prior:<18}{n / seconds:>10.0f}{samples.rejections.fraction:>10.1%}  "
              f"{'PASS' if ok else 'FAIL'}: joints in range {a['in_range']}, invalid {a['invalid']}, min clearance "
              f"{a['min_clearance_mm']:.1f} mm, worst |P-K[R|t]|/|P| {a['worst_P']:.1e}, worst angle "
              f"{a['worst_angle_deg']:.1e} deg")
        for note in samples.rejections.notes:
            print(f"{'':<18}note: {note}")


def clinical_sd(system, patient, n: int) -> None:
    from scipy import stats

    from carmkin.views.standard import STANDARD_VIEWS

    samples = datasets.sample_poses(system, "standard-views", n, seed=1, patient=patient)
    base = np.array([[STANDARD_VIEWS[v].primary_deg, STANDARD_VIEWS[v].secondary_deg] for v in samples.labels])
    offsets = samples.nominal - base
    offsets[:, 0] = (offsets[:, 0] + 180) % 360 - 180
    print(f"--- standard views, {n} poses: offsets from the view vs N(0, {datasets.CLINICAL_SD_DEG} deg)")
    for k, name in enumerate(("primary", "secondary")):
        result = stats.kstest(offsets[:, k] / datasets.CLINICAL_SD_DEG, "norm")
        print(f"{name:<10} mean {offsets[:, k].mean():+.3f} deg, SD {offsets[:, k].std():.3f} deg, KS p {result.pvalue:.3f}")
    low = datasets.sample_poses(system, "standard-views", max(200, n // 10), seed=1, patient=patient,
                                views=["ap", "judet-rao-45"], target_m=[0.0, 0.02, 0.0])
    print("the cut, target 13 cm above the back (AP, Judet RAO 45): proposed vs accepted (mean/SD primary, "
          "mean/SD secondary, deg)")
    for view, cut in low.rejections.statistics.items():
        p, a = low.rejections.groups[view]
        print(f"  {view:<14} {a}/{p} accepted; proposed {np.round(cut['proposed'], 2).tolist()} -> accepted "
              f"{np.round(cut['accepted'], 2).tolist()}")


def _sample_task(system, patient, seed, shard, n):
    return len(datasets.sample_poses(system, "standard-views", n, seed=seed, patient=patient, shard=shard))


def ray_scaling(system, patient, tasks: int, n: int) -> None:
    try:
        import ray
    except ImportError as exc:
        print(f"--- Ray: skipped ({exc})")
        return
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    try:
        task = ray.remote(num_cpus=1)(_sample_task)
        ray.get([task.remote(system, patient, 0, k, 10) for k in range(2)])  # warm both workers
        start = time.perf_counter()
        for k in range(tasks):
            ray.get(task.remote(system, patient, 1, k, n))
        one = time.perf_counter() - start
        start = time.perf_counter()
        ray.get([task.remote(system, patient, 1, k, n) for k in range(tasks)])
        two = time.perf_counter() - start
    finally:
        ray.shutdown()
    total = tasks * n
    print(f"--- Ray sampling ({tasks} tasks of {n} standard-view poses, {os.cpu_count()} cores on this machine, "
          f"shared): 1 worker {total / one:.0f} poses/s, 2 workers {total / two:.0f} poses/s: {one / two:.2f}x")


def rendering(system, patient, sizes, n: int, devices) -> None:
    import torch

    from carmkin.datasets import shards
    from carmkin.interop import simulators

    for device in devices:
        name = torch.cuda.get_device_name() if device == "cuda" else f"CPU, {torch.get_num_threads()} threads"
        print(f"--- rendering on {device} ({name}), {n} images a size, batches of {render.BATCH}, "
              f"{shards.Spec.n_samples} samples per ray")
        for size in sizes:
            spec = datasets.Spec(system, "standard-views", 2 * n, size, 0, patient, shard_size=n, device=device)
            with tempfile.TemporaryDirectory() as out:
                shards.prepare(out, spec)
                shards.make_and_write(out, spec, 0)  # warm-up: CT, renderer, kernels
                if device == "cuda":
                    torch.cuda.synchronize()
                start = time.perf_counter()
                shards.make_and_write(out, spec, 1)
                end_to_end = time.perf_counter() - start
            samples = datasets.sample_poses(system, "standard-views", n, 0, patient, shard=1)
            renderer = shards.renderer_for(spec, samples.provenance["parameters"]["target_m"]).renderer
            T_ct = np.linalg.inv(renderer.T_table_ct)
            rt_inv = torch.tensor(np.stack([simulators.nanodrr_rt_inv(simulators.to_millimetres(T_ct @ T))
                                            for T in samples.source_pose]), dtype=torch.float32, device=device)
            start = time.perf_counter()
            with torch.no_grad():
                for a in range(0, n, render.BATCH):
                    image = renderer.drr(renderer.subject, rt_inv[a:a + render.BATCH],
                                         n_samples=renderer.n_samples)
                    image.cpu()
            if device == "cuda":
                torch.cuda.synchronize()
            raw = time.perf_counter() - start
            print(f"{renderer.size[0]}x{renderer.size[1]:<8} end to end {n / end_to_end:8.1f} images/s, raw nanodrr "
                  f"{n / raw:8.1f} images/s: {raw / end_to_end:.2f}x")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="small counts and one small image size (CI)")
    parser.add_argument("--part", choices=("all", "sampling", "sd", "ray", "rendering"), default="all",
                        help="run one part only (default all)")
    args = parser.parse_args()
    system = carmkin.load_preset("siremobile-iso-c3d")
    patient = ParametricPatient.on_table(system)
    n = 500 if args.quick else 10_000
    if args.part in ("all", "sampling"):
        sampling(system, patient, n)
    if args.part in ("all", "sd"):
        clinical_sd(system, patient, 1000 if args.quick else 10_000)
    if args.part in ("all", "ray"):
        ray_scaling(system, patient, 4 if args.quick else 8, 500 if args.quick else 2000)
    if args.part not in ("all", "rendering"):
        return 0
    try:
        import torch

        scale.check(datasets.Spec(system, "standard-views", 1, "40x30"))
    except (ImportError, CarmkinError) as exc:
        print(f"--- rendering: skipped ({exc})")
        return 0
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    for device in devices:
        sizes = ["40x30"] if args.quick else (["200x150", "400x300", "800x600"] if device == "cuda" else ["200x150"])
        rendering(system, patient, sizes, 16 if args.quick else (512 if device == "cuda" else 32), [device])
    return 0


if __name__ == "__main__":
    sys.exit(main())
