"""Cross-check the closed-form DH kinematics against Pinocchio on the generated URDF.

Compares the pose of every DH frame, `xray_source` and `detector` over random configurations (uniform over
the joint ranges widened by 25 % each side, revolute joints over at least a full turn). With
--random-setups, the samples are spread over random table poses and non-isocentric C-arms (a1, a2 ≠ 0) as
well. Prints the worst position error (m) and rotation error (rad) per frame; exits 1 if any exceeds the
tolerance (default 1e-12). Then plans the preset's own zero view (AP through the table origin, no patient);
a chain that cannot reach it exits 1 naming why.
"""

from __future__ import annotations

import argparse

from ._common import add_json_argument, add_preset_argument, integer, number, system_from_args, write_json

HELP = "cross-check closed-form kinematics against Pinocchio (exit 1 above tolerance)"


def register(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    parser.add_argument("--samples", type=integer(1), default=10_000, help="number of configurations (default 10000)")
    parser.add_argument("--random-setups", nargs="?", type=integer(0), const=100, default=0, metavar="K",
                        help="also use K random table setups and non-isocentric geometries (default K=100)")
    parser.add_argument("--seed", type=integer(0), default=0, help="random seed (default 0)")
    parser.add_argument("--tolerance", type=number(0.0), default=1e-12, help="pass threshold in m and rad (default 1e-12)")
    add_json_argument(parser, "the worst errors per frame (m, rad)")


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from carmkin.errors import PresetError
    from carmkin.robot.verify import FRAMES, verify
    from carmkin.studies.acceptance import zero_view

    system = system_from_args(args)
    with tqdm(total=args.samples, unit="q", desc="verify", leave=False) as bar:
        report = verify(system, args.samples, args.random_setups, args.seed, progress=bar.update)
    print(f"preset {system.name}: {report.samples} configurations on {report.systems} system(s)")
    print(f"{'frame':<14}{'position error (m)':>22}{'rotation error (rad)':>24}")
    for frame in FRAMES:
        print(f"{frame:<14}{report.position_error[frame]:>22.3e}{report.rotation_error[frame]:>24.3e}")
    ok = report.worst <= args.tolerance
    print(f"worst {report.worst:.3e} {'<=' if ok else '>'} tolerance {args.tolerance:g}: {'PASS' if ok else 'FAIL'}")
    try:
        plan = zero_view(system)
        print(f"zero view (AP through the table origin): reachable, clearance {plan.clearance * 1e3:.1f} mm: PASS")
        reached = True
    except PresetError as error:
        print(f"zero view: FAIL: {error}")
        reached = False
    write_json(args, {"preset": system.name, "samples": report.samples, "systems": report.systems,
                      "position_error_m": {f: report.position_error[f] for f in FRAMES},
                      "rotation_error_rad": {f: report.rotation_error[f] for f in FRAMES},
                      "worst": report.worst, "tolerance": args.tolerance, "zero_view": reached,
                      "pass": bool(ok and reached)})
    return 0 if ok and reached else 1
