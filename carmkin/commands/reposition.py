"""Radiation-free C-arm repositioning (§3.3, §4.5, §4.6.2), simulated.

A camera at the X-ray source (same intrinsics) sees an ArUco board under the table (16.5 mm squares,
5.5 mm apart); its pose gives the 6-DOF model (eq. 4.3) and the joint-by-joint guidance back to a
reference pose, stopping when every remaining move is below --threshold-mm / --threshold-deg.

  carmkin reposition simulate                one task: every guidance step (measured joints, next move)
  carmkin reposition experiment              the guidance's own §4.6.2-style run (+ sensitivity); the
                                             seed's §4.6.2 and its verdict: carmkin reproduce 4.6.2
  carmkin reposition calibration             calibration error vs position noise and number of positions

Units: lengths in mm, angles in degrees, image errors in pixels (800 x 600 X-ray image); joint values
print in mm for prismatic joints (table translation, vertical, horizontal) and degrees for revolute ones.
Noise model: Gaussian corner noise (--corner-noise-px) on every camera measurement; the operator moves a
joint by the shown amount with a relative error (--operator-relative) plus an absolute one
(--operator-mm, --operator-deg), then the joint stops at its limit. Exit status: 0 done, 1 when a task
failed (simulate) or fewer than 99 % were repositioned (experiment), 2 on bad input.
"""

from __future__ import annotations

import argparse
import math
import sys

from carmkin.extras import require

from ._common import add_json_argument, add_preset_argument, integer, joints_json, number, system_from_args, \
    write_json

HELP = "simulate radiation-free repositioning: guidance steps, the §4.6.2 experiment, table calibration"
#: ``experiment`` is the guidance package's own run, not the reproduction: it says where §4.6.2's verdict is.
ROUTE_4_6_2 = ("not the seed's §4.6.2: this run evaluates the guidance's filtered readings under this command's "
               "noise options; the seed's measurement, the fitted error model and the verdict: carmkin reproduce 4.6.2")
#: ``experiment`` exits 1 below this fraction of repositioned tasks (issue 14's acceptance).
MIN_SUCCESS = 0.99


#: Largest stop thresholds of the guidance (deg, mm): beyond them the stop rule accepts a pose far from the
#: reference (--threshold-deg 30 stopped with the source 242 mm away), which is no repositioning; a threshold
#: of 30 there was likely arcminutes (30' = 0.5°, the default), and the refusal says so.
MAX_THRESHOLD_DEG = 5.0
MAX_THRESHOLD_MM = 50.0


def _add_noise(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    parser.add_argument("--seed", type=integer(0), default=0, help="random seed (default 0)")
    parser.add_argument("--corner-noise-px", type=number(0, 100, unit="px"), default=0.2,
                        help="σ of the Gaussian noise on each detected corner, px (default 0.2)")
    parser.add_argument("--threshold-mm", type=number(0, MAX_THRESHOLD_MM, open_minimum=True, unit="mm"),
                        default=2.0, help="stop when every prismatic joint's remaining move is below this, mm "
                        f"(default 2, at most {MAX_THRESHOLD_MM:g})")
    parser.add_argument("--threshold-deg", type=number(0, MAX_THRESHOLD_DEG, open_minimum=True, unit="deg",
                                                       slips=(("arcmin", 1 / 60),)),
                        default=0.5, help="stop when every revolute joint's remaining move is below this, deg "
                        f"(default 0.5, at most {MAX_THRESHOLD_DEG:g})")
    parser.add_argument("--operator-relative", type=number(0, 1), default=0.1,
                        help="σ of the operator's relative error on each move, fraction (default 0.1)")
    parser.add_argument("--operator-mm", type=number(0, 1000, unit="mm"), default=1.0,
                        help="σ of the operator's absolute error on prismatic moves, mm (default 1)")
    parser.add_argument("--operator-deg", type=number(0, 180, unit="deg"), default=0.2,
                        help="σ of the operator's absolute error on revolute moves, deg (default 0.2)")
    add_json_argument(parser)


def register(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="reposition_command", required=True, metavar="ACTION")
    simulate = sub.add_parser("simulate", help="one repositioning task, printing every guidance step",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_noise(simulate)
    experiment = sub.add_parser("experiment", help="the guidance's own §4.6.2-style run (the seed's §4.6.2 with its "
                                "verdict: carmkin reproduce 4.6.2)",
                                description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_noise(experiment)
    experiment.add_argument("--tasks", type=integer(1), default=100, help="repositioning tasks (default 100; seed: 10)")
    experiment.add_argument("--sensitivity-tasks", type=integer(0), default=0,
                            help="also print the sensitivity table with this many tasks per row (default 0: no)")
    calibration = sub.add_parser("calibration", help="calibration error vs noise and number of positions",
                                 description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    calibration.add_argument("--noise-mm", default="0.1,0.2,0.5,1",
                             help="σ of the camera-position noise, mm, comma-separated (default 0.1,0.2,0.5,1)")
    calibration.add_argument("--positions", default="3,6,9,12",
                             help="numbers of positions, comma-separated (default 3,6,9,12)")
    calibration.add_argument("--span-mm", type=number(0, 10_000, open_minimum=True, unit="mm"), default=400.0,
                             help="longest move along each table axis, mm (default 400)")
    calibration.add_argument("--trials", type=integer(1), default=200, help="random rotations per cell (default 200)")
    calibration.add_argument("--method", choices=("svd", "lines"), default="svd", help="estimator (default svd)")
    calibration.add_argument("--seed", type=integer(0), default=0, help="random seed (default 0)")
    add_json_argument(calibration, "the error table (deg)")


def _config(args):
    from carmkin.reposition.experiment import ExperimentConfig
    from carmkin.reposition.guidance import GuidanceOptions
    from carmkin.reposition.world import OperatorModel

    return ExperimentConfig(
        corner_noise_px=args.corner_noise_px,
        operator=OperatorModel(args.operator_relative, args.operator_mm / 1e3, math.radians(args.operator_deg)),
        guidance=GuidanceOptions(translation_threshold=args.threshold_mm / 1e3,
                                 rotation_threshold=math.radians(args.threshold_deg)))


def _joints(system, q) -> str:
    return ", ".join(f"{name} {v * 1e3:.1f} mm" if p else f"{name} {math.degrees(v):.2f}°"
                     for name, p, v in zip(system.joint_names, system.prismatic, q))


def _simulate(args) -> int:
    import numpy as np

    from carmkin.reposition import experiment as ex

    system = system_from_args(args)
    config = _config(args)
    rng = np.random.default_rng(args.seed)
    world = ex.make_world(system, config, rng)
    count, last_q = [0], [None]

    def show(step, q_true, q_next, truth):
        count[0] += 1
        last_q[0] = q_true
        print(f"step {count[0]:2d}  measured: {_joints(system, step.q)}")
        if step.done:
            print(f"         stop rule met: every remaining joint move, as measured, is below {args.threshold_mm:g} mm / "
                  f"{args.threshold_deg:g}°")
            return
        if step.blocked:
            print(f"         blocked: {step.blocked}")
            return
        name, unit = system.joint_names[step.joint], system.prismatic[step.joint]
        move = f"{step.move * 1e3:+.1f} mm" if unit else f"{math.degrees(step.move):+.2f}°"
        actual = q_next[step.joint] - q_true[step.joint]
        done = f"{actual * 1e3:+.1f} mm" if unit else f"{math.degrees(actual):+.2f}°"
        print(f"         move {name} by {move} (path clear by >= {config.guidance.path_clearance * 1e3:.0f} mm, "
              f"{step.sweep.samples} checks); operator moved {done}; true path "
              f"{'clear' if truth.clear else 'COLLIDES'}, min distance {truth.min_distance * 1e3:.0f} mm")
        print(f"         this move takes {step.duration}; all remaining moves {step.remaining_duration}")

    from carmkin.reposition.calibration import rotation_angle

    off = math.degrees(rotation_angle(world.T_table_marker[:3, :3], world.tRm))
    print(f"{system.name}: calibrated marker→table rotation {off:.2f}° from the true mount; corner noise "
          f"{config.corner_noise_px} px")
    result = ex.run_task(world, config, rng, on_step=show)
    if not result.success:
        print(f"not repositioned: {result.reason}")
        write_json(args, {"preset": system.name, "success": False, "reason": str(result.reason), "steps": count[0]})
        return 1
    from carmkin.reposition.guidance import stop_rule_bound

    bound_m, bound_rad = stop_rule_bound(system, last_q[0], config.guidance)  # at the final configuration
    across = math.sqrt(max(result.translation**2 - result.along_beam**2, 0.0))
    print(f"repositioned (the stop rule holds) after {result.steps} moves. Residual against the reference, from "
          f"the simulation's truth: source {result.translation * 1e3:.2f} mm away ({result.along_beam * 1e3:.2f} mm "
          f"along the beam, {across * 1e3:.2f} mm across), rotated {math.degrees(result.rotation):.3f}° (mean over "
          f"3 axes); the table-top markers move {np.mean(result.image_errors):.2f} px between the two X-rays (mean "
          f"of 16 corners; max {np.max(result.image_errors):.2f}).")
    print(f"What the residual means: the stop rule bounds each joint's remaining move ({args.threshold_mm:g} mm / "
          f"{args.threshold_deg:g}°), not the pose; here the joints at their thresholds together may "
          f"leave the source up to {bound_m * 1e3:.1f} mm / {math.degrees(bound_rad):.2f}° away (first order); "
          "lower --threshold-mm / --threshold-deg for a closer match.")
    write_json(args, {"preset": system.name, "success": True, "moves": result.steps, "q": joints_json(system, last_q[0]),
                      "translation_mm": result.translation * 1e3, "along_beam_mm": result.along_beam * 1e3,
                      "rotation_deg": math.degrees(result.rotation),
                      "image_error_mean_px": float(np.mean(result.image_errors)),
                      "image_error_max_px": float(np.max(result.image_errors))})
    return 0


def _experiment(args) -> int:
    from carmkin.reposition import experiment as ex

    system = system_from_args(args)
    config = _config(args)
    from tqdm import tqdm

    with tqdm(total=args.tasks, unit="task", desc="reposition experiment", leave=False, file=sys.stderr) as bar:
        stats = ex.summary(ex.run_experiment(system, config, args.tasks, args.seed, progress=lambda i: bar.update(1)))
    print(f"§4.6.2 repositioning, simulated: {system.name}, {args.tasks} tasks (seed {args.seed}), corner noise "
          f"{config.corner_noise_px} px, operator {args.operator_relative:.0%} + {args.operator_mm} mm / "
          f"{args.operator_deg}°, thresholds {args.threshold_mm} mm / {args.threshold_deg}°")
    print(ex.format_table(stats))
    if args.sensitivity_tasks:
        print(f"\nsensitivity ({args.sensitivity_tasks} tasks per row, same seed; means over repositioned tasks):")
        print(ex.format_sensitivity(ex.sensitivity(system, args.sensitivity_tasks, args.seed, config)))
    print(ROUTE_4_6_2)
    write_json(args, {"preset": system.name, "tasks": args.tasks, "seed": args.seed, "statistics": stats})
    return 0 if stats["success"] >= MIN_SUCCESS else 1


def _numbers(text: str, flag: str, integer: bool = False) -> list:
    from carmkin.reposition.calibration import CalibrationError

    try:
        values = [int(v) if integer else float(v) for v in text.split(",")]
    except ValueError as exc:
        raise CalibrationError(f"{flag} must be {'integers' if integer else 'numbers'} separated by commas, "
                               f"got {text!r}") from exc
    if not values or not all(math.isfinite(v) for v in values):
        raise CalibrationError(f"{flag} values must be finite, got {text!r}")
    return values


def _calibration(args) -> int:
    import numpy as np

    from carmkin.reposition.calibration import CalibrationError, error_curve

    noise = _numbers(args.noise_mm, "--noise-mm")
    positions = _numbers(args.positions, "--positions", integer=True)
    if min(positions) < 3:
        raise CalibrationError(f"--positions must be >= 3 (a calibration needs three positions), got {args.positions}")
    curve = np.degrees(error_curve([n / 1e3 for n in noise], positions, args.trials, args.span_mm / 1e3,
                                   method=args.method, seed=args.seed))
    print(f"calibration error (deg, median / 95th percentile of {args.trials} random rotations), method "
          f"{args.method}, moves up to {args.span_mm:g} mm along the translation, height and lateral axes")
    print(f"{'noise (mm)':>12}" + "".join(f"{f'N = {n}':>18}" for n in positions))
    for i, n in enumerate(noise):
        print(f"{n:12.2f}" + "".join(f"{curve[i, j, 0]:9.3f} / {curve[i, j, 1]:6.3f}" for j in range(len(positions))))
    write_json(args, {"method": args.method, "trials": args.trials, "span_mm": args.span_mm, "noise_mm": noise,
                      "positions": positions, "median_deg": curve[..., 0], "p95_deg": curve[..., 1]})
    return 0


def run(args: argparse.Namespace) -> int:
    require("cv2", "reposition")  # checked here: a missing extra is a one-line usage error (exit 2)
    return {"simulate": _simulate, "experiment": _experiment, "calibration": _calibration}[args.reposition_command](args)
