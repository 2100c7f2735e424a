"""3D sweeps (issue 22): plan + export time with swept clearance, the exports' agreement with P, and the
RTK reconstruction of a Shepp–Logan phantom (time and error).

Preset ``siremobile-iso-c3d`` with a 500 × 300 × 1600 mm box patient on the table; 190° orbital sweep.

1. Plan + export (ASTRA, TIGRE, DICOM angles) of a 190-frame sweep with the certified swept clearance
   (conservative advancement). Baseline in the same run: checking the same arc densely at 0.1° with exact
   coal distances (1901 queries, no guarantee between them).
2. The compensated sweep of a non-isocentric variant (a1 = 50 mm, a2 = 40 mm): target off the axis
   (compensated) beside the plain orbital rotation's drift.
3. RTK (cbct extra): GetMatrix vs P, relative; Joseph forward projection (baseline) and Parker + FDK of a
   128³ phantom from 100 frames of 256² px (``--quick``: 32³ from 30 frames of 64²), RMSE vs the phantom;
   the same over 200° on a hypothetical ±100° orbital range (a complete short scan: 180° + 13.4° fan).

    python benchmarks/bench_sweep.py            # full size
    python benchmarks/bench_sweep.py --quick    # CI
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time

import numpy as np
from _timing import median_time, row

import carmkin
from carmkin.model.params import JointRange
from carmkin.world import Obstacle, World
from carmkin.sweeps import astra_vectors, plan_sweep, positioner_angles, tigre_geometry

PATIENT = [Obstacle.box("patient", (0.5, 0.3, 1.6), center=(0.0, 0.0, 0.0))]


def plan_and_export(system):
    sweep = plan_sweep(system, [0.0, 0.0, 0.0], arc_deg=190.0, n_views=190, patient=PATIENT)
    astra_vectors(sweep), tigre_geometry(sweep), positioner_angles(sweep)
    return sweep


def dense_check(system, sweep):
    scene = World(system, PATIENT)
    data = scene.model.createData()
    phis = np.append(np.arange(sweep.angles[0], sweep.angles[-1], math.radians(0.1)), sweep.angles[-1])
    return min(scene.distances(data, q=sweep.configuration(p)).min() for p in phis)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small reconstruction, fewer repeats (CI)")
    args = parser.parse_args()
    system = carmkin.load_preset("siremobile-iso-c3d")
    repeat = 3 if args.quick else 10

    print("1. plan + export of a 190-frame, 190° sweep with swept clearance")
    sweep = plan_and_export(system)
    dense = median_time(lambda: dense_check(system, sweep), repeat=1)
    planned = median_time(lambda: plan_and_export(system), repeat=repeat)
    print(row("dense 0.1° check, exact distances (baseline)", dense, unit="ms"))
    print(row("plan + swept clearance + exports", planned, dense, unit="ms"))
    print(f"  certified swept clearance {sweep.min_clearance * 1e3:.2f} mm from {sweep.clearance_samples} samples; "
          f"dense 0.1° minimum {dense_check(system, sweep) * 1e3:.2f} mm; acceptance ≤ 1 s: "
          f"{'met' if planned <= 1.0 else 'NOT met'}")
    print(f"  {sweep.short_scan}")

    print("2. non-isocentric variant (a1 = 50 mm, a2 = 40 mm), target 200 mm above the isocentre")
    offset = system.replace(carm=dataclasses.replace(system.carm, a1=0.05, a2=0.04))
    compensated = plan_sweep(offset, [0.1, -0.2, 0.0])
    T = offset.fk(compensated.q)
    rel = compensated.target - T[:, :3, 3]
    depth = np.einsum("ni,ni->n", rel, T[:, :3, 2])
    off = np.linalg.norm(rel - depth[:, None] * T[:, :3, 2], axis=1)
    print(f"  compensated: target off the axis ≤ {off.max():.1e} m, depth error ≤ "
          f"{np.abs(depth - compensated.distance).max():.1e} m (acceptance 1e-9 m); plain orbital rotation drift: "
          f"max {compensated.drift.max() * 1e3:.1f} mm, mean {compensated.drift.mean() * 1e3:.1f} mm")

    try:
        from carmkin.sweeps import export
        from carmkin.sweeps import reconstruct as rc

        start = time.perf_counter()
        export._rtk()
        print(f"3. RTK (wrappers loaded in {time.perf_counter() - start:.1f} s)")
    except carmkin.CarmkinError as exc:
        print(f"3. RTK skipped: {exc}")
        return
    M = export.rtk_matrices(export.rtk_geometry(sweep))
    A = export.pixel_from_detector(sweep)
    worst = 0.0
    for k in range(sweep.n_views):
        ours = sweep.P[k] / np.linalg.norm(sweep.P[k])
        theirs = A @ M[k] @ np.diag([1e3, 1e3, 1e3, 1.0])
        theirs /= np.linalg.norm(theirs) * np.sign(np.vdot(theirs, ours))
        worst = max(worst, float(np.abs(theirs - ours).max()))
    print(f"  GetMatrix vs P over {sweep.n_views} frames: {worst:.1e} relative (acceptance 1e-9)")
    size, views, pixels = (32, 30, 64) if args.quick else (128, 100, 256)
    small = plan_sweep(rc.with_detector(system, pixels, pixels), [0.0, 0.0, 0.0], n_views=views, patient=PATIENT)
    volume = rc.Volume(size)
    frame = rc.reconstruction_frame(small)
    local = rc.in_frame(small, frame)
    drawn = rc.phantom(volume)
    start = time.perf_counter()
    projections = rc.forward_project(local, drawn)
    forward = time.perf_counter() - start
    start = time.perf_counter()
    recon = rc.fdk(local, projections, volume)
    backward = time.perf_counter() - start
    import itk

    truth = np.array(itk.GetArrayFromImage(drawn), dtype=np.float64)
    rmse = float(np.sqrt(np.mean((recon - truth)[volume.mask()] ** 2)))
    print(row(f"Joseph forward projection, {views} × {pixels}² (baseline)", forward, unit="s"))
    print(row(f"Parker + FDK, {size}³", backward, forward, unit="s"))
    print(f"  {size}³ Shepp–Logan (0…{truth.max():g}) from {views} frames of {pixels}² px over 190°: RMSE {rmse:.4f} "
          f"inside the field of view; total {forward + backward:.1f} s on CPU")
    # the same with a complete short scan (200° ≥ 180° + 13.4°), on a hypothetical orbital range of ±100°
    wide = system.replace(carm=dataclasses.replace(system.carm, orbital=JointRange(-math.radians(100.0),
                                                                                   math.radians(100.0), "orbital")))
    full = plan_sweep(rc.with_detector(wide, pixels, pixels), [0.0, 0.0, 0.0], arc_deg=200.0, n_views=views,
                      patient=PATIENT)
    complete = rc.simulate_and_reconstruct(full, volume)
    print(f"  the same over 200° (orbital range widened to ±100°: {full.short_scan}): RMSE {complete.rmse:.4f}")


if __name__ == "__main__":
    main()
