"""Radiation-free repositioning (issue 14): pose accuracy, image path, calibration, guidance, experiment.

Preset ``siremobile-iso-c3d`` (camera = X-ray intrinsics: SID 980 mm, 230 mm over 800 × 600 px), the
45 × 22 ArUco board (16.5 mm squares, 5.5 mm gaps) under the table top.

1. Pose from corner lists with 0.2 px Gaussian noise at the working distance (zero configuration: the board
   415 mm from the source) and at random reference configurations: rotation (deg) and translation (mm)
   errors, median and 95th percentile; the covariance's prediction; MINPACK LM (default) beside
   ``cv2.solvePnPRefineLM``. Baseline of the timings: the corner-list path.
2. The image path (render → ArUco detection → PnP) at the same poses: errors and time, ratio to the
   corner-list path.
3. Calibration error vs position noise and number of positions (§3.3.3).
4. Guidance on simulated tasks (§4.6.2 protocol, the experiment's noise model): success rate (thresholds
   reached, every true move collision-free by conservative advancement), and the time of one guidance step
   (pose estimate + IK + swept validity of the next move).
5. The experiment table beside the seed's numbers, and the sensitivity table.

    python benchmarks/bench_reposition.py            # 1000 guidance tasks, 2000 pose trials
    python benchmarks/bench_reposition.py --quick    # 30 tasks, 200 trials (CI)
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np
from _timing import row

import carmkin
from carmkin.reposition import calibration, camera, experiment, pose, render
from carmkin.reposition.calibration import rotation_angle
from carmkin.reposition.guidance import Guide
from carmkin.reposition.model import model_from_pose
from carmkin.reposition.world import World, system_mount

PRESET = "siremobile-iso-c3d"
SIGMA_PX = 0.2


def pose_errors(T_est, T_true) -> tuple[float, float]:
    """(rotation error deg, translation error mm)."""
    return math.degrees(rotation_angle(T_est[:3, :3], T_true[:3, :3])), 1e3 * float(np.linalg.norm(T_est[:3, 3] - T_true[:3, 3]))


def summarize(label: str, errors) -> tuple[float, float]:
    e = np.asarray(errors)
    med, p95 = np.median(e, axis=0), np.percentile(e, 95, axis=0)
    print(f"  {label:<44} rotation {med[0]:6.3f} / {p95[0]:6.3f} deg   translation {med[1]:6.2f} / {p95[1]:6.2f} mm")
    return float(med[0]), float(med[1])


def bench_pose(system, trials: int, rng) -> dict:
    board = carmkin.reposition.pattern.MarkerBoard()
    mount = system_mount(system, board)
    K, size = system.carm.intrinsics(), (system.carm.detector_columns, system.carm.detector_rows)
    world = World(system, board, mount, mount[:3, :3])
    config = experiment.ExperimentConfig()
    from carmkin.world import World as CollisionWorld

    scene = CollisionWorld(system)
    references = [experiment.sample_reference(world, config, rng, scene) for _ in range(max(20, trials // 20))]
    cases = {"zero configuration (board 415 mm)": [np.zeros(system.nq)], "random references": references}
    print(f"1. pose from corner lists, {SIGMA_PX} px noise, {trials} trials per row (median / p95)")
    out = {}
    for label, qs in cases.items():
        for refine in pose.REFINERS:
            errors, predicted, times = [], [], []
            for k in range(trials):
                T_true = camera.camera_in_marker(mount, system.fk(qs[k % len(qs)]))
                view = camera.with_noise(camera.visible_corners(board, K, size, T_true), SIGMA_PX, rng)
                start = time.perf_counter()
                estimate = pose.pose_from_view(view, K, sigma_px=SIGMA_PX, refine=refine)
                times.append(time.perf_counter() - start)
                errors.append(pose_errors(estimate.T, T_true))
                predicted.append(np.sqrt(np.trace(estimate.covariance[3:, 3:])) * 1e3)
            out[(label, refine)] = summarize(f"{label}, LM {refine}", errors) + (statistics.median(times),)
        print(f"  {'':<44} covariance: position sd {np.median(predicted):.2f} mm (median)")
    return out


def bench_model_noise(system, trials: int, rng) -> None:
    """Pose noise → γ1..3, D1..3 at the zero configuration: linear propagation against a Monte Carlo."""
    from carmkin.reposition import model

    board = carmkin.reposition.pattern.MarkerBoard()
    mount = system_mount(system, board)
    K, size = system.carm.intrinsics(), (system.carm.detector_columns, system.carm.detector_rows)
    q = np.zeros(system.nq)
    T_table = system.fk(q)
    view = camera.visible_corners(board, K, size, camera.camera_in_marker(mount, T_table))
    estimate = pose.pose_from_view(view, K, sigma_px=SIGMA_PX)
    linear = np.sqrt(np.diag(model.setup_covariance(system, T_table, q, model.to_table_frame(estimate.covariance, mount[:3, :3]))))
    samples = []
    for _ in range(trials):
        noisy = pose.pose_from_view(camera.with_noise(view, SIGMA_PX, rng), K)
        setup = model.setup_from_pose(system, mount @ noisy.T, q)
        samples.append([setup.gamma1, setup.gamma2, setup.gamma3, setup.D1, setup.D2, setup.D3])
    monte_carlo = np.std(np.array(samples), axis=0)
    scale = np.array([180 / math.pi] * 3 + [1e3] * 3)
    print(f"\n1b. model from one measured pose (eq. 4.3), zero configuration, {SIGMA_PX} px: sd of "
          "γ1, γ2, γ3 (deg) and D1, D2, D3 (mm)")
    print("  linear propagation " + " ".join(f"{v:8.3f}" for v in linear * scale))
    print(f"  Monte Carlo ({trials}) " + " ".join(f"{v:8.3f}" for v in monte_carlo * scale))


def bench_image_path(system, trials: int, rng) -> None:
    board = carmkin.reposition.pattern.MarkerBoard()
    mount = system_mount(system, board)
    K, size = system.carm.intrinsics(), (system.carm.detector_columns, system.carm.detector_rows)
    render.board_texture(board)  # build the texture once, outside the timings
    image_errors, corner_errors, corner_rms = [], [], []
    t_render, t_detect, t_corners = [], [], []
    # poses around the working distance: table ±20 mm, vertical 0..20 mm, wigwag/angular/orbital ±2°
    spread = np.array([0.02, 0.0, math.radians(2), 0.0, math.radians(2), math.radians(2)])
    for _ in range(trials):
        q = rng.uniform(-spread, spread)
        q[1], q[3] = rng.uniform(0.0, 0.02), rng.uniform(0.0, 0.02)
        T_true = camera.camera_in_marker(mount, system.fk(q))
        truth = camera.visible_corners(board, K, size, T_true)
        start = time.perf_counter()
        image = render.render(board, K, size, T_true, rng=rng)
        t_render.append(time.perf_counter() - start)
        start = time.perf_counter()
        detected = pose.detect_corners(image, board)
        estimate = pose.pose_from_view(detected, K)
        t_detect.append(time.perf_counter() - start)
        image_errors.append(pose_errors(estimate.T, T_true))
        if np.array_equal(detected.ids, truth.ids):
            corner_rms.append(np.sqrt(np.mean((detected.image_points - truth.image_points) ** 2)))
        start = time.perf_counter()
        estimate = pose.pose_from_view(camera.with_noise(truth, SIGMA_PX, rng), K)
        t_corners.append(time.perf_counter() - start)
        corner_errors.append(pose_errors(estimate.T, T_true))
    print(f"\n2. image path (render 2x supersampled, blur 0.8 px, noise 2 gray levels → ArucoDetector sub-pixel → PnP) "
          f"around the working distance, {trials} random poses")
    print(f"  detected corners vs truth: RMS {np.median(corner_rms):.3f} px per coordinate (median over images)")
    image_med = summarize("image path", image_errors)
    corner_med = summarize(f"corner-list path ({SIGMA_PX} px)", corner_errors)
    print(f"  error ratio image / corner-list: rotation {image_med[0] / corner_med[0]:.2f}, translation "
          f"{image_med[1] / corner_med[1]:.2f} (acceptance: within 2x)")
    baseline = statistics.median(t_corners)
    print(row("  corner-list path: PnP (baseline)", baseline, unit="ms"))
    print(row("  image path: detect + PnP", statistics.median(t_detect), baseline, unit="ms"))
    print(row("  rendering one image", statistics.median(t_render), baseline, unit="ms"))


def bench_calibration(trials: int) -> None:
    noise, positions = [0.1, 0.2, 0.5, 1.0], [3, 6, 9, 12]
    curve = np.degrees(calibration.error_curve([n / 1e3 for n in noise], positions, trials))
    print(f"\n3. calibration error (deg, median / p95 of {trials} random rotations; SVD; moves up to 400 mm along "
          "the translation, height and lateral axes)")
    print(f"  {'noise (mm)':>10}" + "".join(f"{f'N = {n}':>18}" for n in positions))
    for i, n in enumerate(noise):
        print(f"  {n:10.2f}" + "".join(f"{curve[i, j, 0]:9.3f} / {curve[i, j, 1]:6.3f}" for j in range(len(positions))))


def bench_guidance(system, tasks: int, seed: int) -> None:
    config = experiment.ExperimentConfig()
    start = time.perf_counter()
    results = experiment.run_experiment(system, config, tasks, seed)
    elapsed = time.perf_counter() - start
    ok = [r for r in results if r.success]
    collided = [r for r in results if r.reason and r.reason.startswith("collision")]
    print(f"\n4. guidance, {tasks} simulated tasks (seed {seed}): repositioned {100 * len(ok) / tasks:.1f} % "
          f"(acceptance >= 99 %), true collisions along a move: {len(collided)}, "
          f"smallest true clearance along all moves {1e3 * min(r.min_clearance for r in results):.1f} mm, "
          f"moves per task {np.mean([r.steps for r in ok]):.1f}, {elapsed / tasks:.2f} s per task")
    for r in results:
        if not r.success:
            print(f"  failed: {r.reason[:200]}")
    # one guidance step: the camera's estimate + IK (joints read off the pose) + swept validity of the move
    rng = np.random.default_rng(seed)
    world = experiment.make_world(system, config, rng)
    from carmkin.world import World as CollisionWorld

    scene = CollisionWorld(system)
    times, estimate_times, cpu_times = [], [], []
    for _ in range(max(10, tasks // 10)):
        q_ref = experiment.sample_reference(world, config, rng, scene)
        q = experiment.start_configuration(world, config, q_ref, rng)
        guide = Guide(model_from_pose(system, world.measure(q, rng), q), world.measure(q_ref, rng), q)
        for _ in range(10):
            q_now = q + (q_ref - q) * rng.uniform(0.0, 1.0)
            start, cpu = time.perf_counter(), time.process_time()
            T = world.measure(q_now, rng)
            middle = time.perf_counter()
            guide.step(T)
            end = time.perf_counter()
            cpu_times.append(time.process_time() - cpu)
            times.append(end - start)
            estimate_times.append(middle - start)
    print(row("  one guidance step (estimate + IK + validity)", statistics.median(times), unit="ms")
          + "  (acceptance <= 10 ms)")
    print(row("    the same, CPU time of this process", statistics.median(cpu_times), unit="ms")
          + "  (the wall time includes waiting for a shared CPU)")
    print(row("    of which the pose estimate", statistics.median(estimate_times), unit="ms"))


def bench_experiment(system, tasks: int, sensitivity_tasks: int, seed: int) -> None:
    config = experiment.ExperimentConfig()
    print(f"\n5. the §4.6.2 experiment, simulated ({tasks} tasks, seed {seed}; the seed ran 10)")
    print(experiment.format_table(experiment.summary(experiment.run_experiment(system, config, tasks, seed))))
    print(f"\n   sensitivity ({sensitivity_tasks} tasks per row, seed {seed}; means over repositioned tasks)")
    print(experiment.format_sensitivity(experiment.sensitivity(system, sensitivity_tasks, seed, config)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="small sizes for CI")
    args = parser.parse_args()
    system = carmkin.load_preset(PRESET)
    rng = np.random.default_rng(0)
    trials = 200 if args.quick else 2000
    bench_pose(system, trials, rng)
    bench_model_noise(system, trials // 2, rng)
    bench_image_path(system, 10 if args.quick else 100, rng)
    bench_calibration(50 if args.quick else 500)
    bench_guidance(system, 30 if args.quick else 1000, seed=1)
    bench_experiment(system, 10 if args.quick else 200, 5 if args.quick else 50, seed=2)


if __name__ == "__main__":
    main()
