"""Kinematic singularities of the 6-DOF chain (§4.3.2): classify a configuration, draw maps, check eq. 4.7.

Prints, for the configuration given by --q-mm-deg (default: revolute joints at 0°, prismatic joints
mid-range), the three factors of eq. 4.7, the distance to each singular set (deg), the rank of the
Jacobian of `xray_source` (Pinocchio, LOCAL_WORLD_ALIGNED, rows [v; ω]), |det J|, σmin, condition number
and Yoshikawa manipulability of the Jacobian scaled by a characteristic length (default: the orbital
offset), and the lost directions. With --png, writes a PNG with |det J| over (wigwag, angular) and a
second measure over --pair, singular curves overlaid (axes in deg / mm). With --check N, compares
Pinocchio's det J with eq. 4.7 on N random configurations (spread over --random-setups random
non-isocentric systems) and exits 1 above --tolerance.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from ._common import (
    JOINTS_FLAG,
    UsageError,
    add_joints_argument,
    add_json_argument,
    add_png_argument,
    add_preset_argument,
    format_joints,
    integer,
    joints_json,
    number,
    parse_joints,
    plot_path,
    require_six_joints,
    system_from_args,
    write_json,
)

HELP = "singular cases, |det J| / manipulability maps, and the eq. 4.7 check"
#: Measures of the second map, as named by carmkin.singularity.MAP_MEASURES (checked in run; a test keeps them equal).
MEASURES_HELP = "det, manipulability, inverse-condition or sigma-min"


def register(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    add_joints_argument(parser)
    add_png_argument(parser, "the two singularity maps", old_names=("--plot",))
    add_json_argument(parser, "the singular cases, rank and measures at the configuration (and the --check result)")
    parser.add_argument("--pair", default="angular,orbital",
                        help="joints of the second map, e.g. 'angular,orbital' or 'wigwag,horizontal' "
                        "(default angular,orbital)")
    parser.add_argument("--measure", default="inverse-condition",
                        help=f"measure of the second map: {MEASURES_HELP} (default inverse-condition)")
    parser.add_argument("--grid", type=integer(2, 1001), default=61, help="grid points per map axis (default 61)")
    parser.add_argument("--length-mm", type=number(0.0, open_minimum=True, unit="mm"), default=None,
                        help="characteristic length for the scaling (default: orbital offset)")
    parser.add_argument("--near-deg", type=number(0.0, 180.0, unit="deg"), default=5.0,
                        help="report a singular set as near within this angle (default 5)")
    parser.add_argument("--check", type=integer(0), default=0, metavar="N",
                        help="compare Pinocchio's det J with eq. 4.7 on N random configurations")
    parser.add_argument("--random-setups", type=integer(0), default=100, metavar="K",
                        help="spread --check over K random non-isocentric systems too (default 100)")
    parser.add_argument("--seed", type=integer(0), default=0, help="random seed of --check (default 0)")
    parser.add_argument("--tolerance", type=number(0.0), default=1e-9,
                        help="pass threshold of --check, m and rad (default 1e-9)")


def configuration(system, text: str | None) -> np.ndarray:
    """q (SI) from --q-mm-deg, or the default (revolute 0, prismatic mid-range)."""
    if text is None:
        mid = (system.lower + system.upper) / 2
        return np.where(system.prismatic, mid, 0.0)
    return parse_joints(text, system, JOINTS_FLAG)


def pair_of(text: str, system=None) -> tuple[int, int]:
    """Joint indices of ``system`` from 'name,name' (names, symbols or indices)."""
    from carmkin import singularity as sing
    from carmkin.errors import SingularityError

    names = [int(n) if n.strip().isdigit() else n for n in text.split(",")]
    if len(names) != 2:
        raise UsageError(f"--pair needs two joint names separated by a comma, got {text!r}")
    try:
        return sing.joint_index(names[0], system), sing.joint_index(names[1], system)
    except SingularityError as exc:
        raise UsageError(f"--pair: {exc}") from None


def run(args: argparse.Namespace) -> int:
    from carmkin import singularity as sing

    system = system_from_args(args)
    require_six_joints(system, "carmkin singularity (eq. 4.7, its singular cases and maps)",
                       "use --preset siremobile-iso-c3d, or carmkin.singularity.measures(system, q) in Python for "
                       f"the rank and σmin of the 6×{system.nq} Jacobian")
    if args.measure not in sing.MAP_MEASURES:
        raise UsageError(f"--measure {args.measure!r}: expected one of {', '.join(sing.MAP_MEASURES)}")
    plot = None if args.png is None else plot_path(args.png, "--png")
    pair = pair_of(args.pair, system)
    length = None if args.length_mm is None else args.length_mm / 1e3
    q = configuration(system, args.q_mm_deg)
    print(f"preset {system.name}: q = {format_joints(system, q, digits=4, sign=False)}")
    found = sing.classify(system, q, near=math.radians(args.near_deg), length=length)
    print(found.describe())
    out = {"preset": system.name, "q": joints_json(system, q), "rank": int(found.rank),
           "det_j": float(found.measures.det), "sigma_min": float(found.measures.sigma_min),
           "manipulability": float(found.measures.manipulability),
           "cases": [{"case": c.title, "singular": bool(c.singular), "near": bool(c.near),
                      "distance_deg": math.degrees(c.distance)} for c in found.cases.values()]}
    status = 0
    if args.check:
        worst = sing.check_determinant(system, args.check, args.random_setups, args.seed)
        ok = worst <= args.tolerance
        print(f"det J (Pinocchio) vs eq. 4.7 on {args.check} configurations, {args.random_setups} random "
              f"non-isocentric systems: max |difference| {worst:.3e} {'<=' if ok else '>'} {args.tolerance:g}: "
              f"{'PASS' if ok else 'FAIL'}")
        status = 0 if ok else 1
        out["check"] = {"configurations": args.check, "max_difference": worst, "tolerance": args.tolerance, "pass": ok}
    if plot is not None:
        from carmkin import plots

        plots.singularity_maps(system, q, plot, pair=pair, n=args.grid, measure=args.measure, length=length)
        print(f"wrote {plot}")
    write_json(args, out)
    return status
