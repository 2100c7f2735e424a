"""Kinematic singularities of the 6-DOF chain (§4.3.2): classify a configuration, draw maps, check eq. 4.7.

Prints, for the configuration given by --q-mm-deg (default: revolute joints at 0°, prismatic joints
mid-range), the three factors of eq. 4.7, the distance to each singular set (deg), the rank of the
Jacobian of `xray_source` (Pinocchio, LOCAL_WORLD_ALIGNED, rows [v; ω]), |det J|, σmin, condition number
and Yoshikawa manipulability of the Jacobian scaled by a characteristic length (default: the orbital
offset), and the lost directions. With --plot, writes a PNG with |det J| over (wigwag, angular) and a
second measure over --pair, singular curves overlaid (axes in deg / mm). With --check N, compares
Pinocchio's det J with eq. 4.7 on N random configurations (spread over --random-setups random
non-isocentric systems) and exits 1 above --tolerance.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from carmkin import singularity as sing
from carmkin.model.params import JOINT_NAMES, PRISMATIC

from ._common import add_preset_argument, system_from_args

HELP = "singular cases, |det J| / manipulability maps, and the eq. 4.7 check"


def register(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    parser.add_argument("--q-mm-deg", metavar="D0,D1,T2,D3,T4,T5",
                        help="configuration, mm for d0 d1 d3 and deg for θ2 θ4 θ5 "
                        "(default: revolute 0°, prismatic mid-range)")
    parser.add_argument("--plot", metavar="OUT.png", help="write the two singularity maps to this PNG")
    parser.add_argument("--pair", default="angular,orbital",
                        help="joints of the second map, e.g. 'angular,orbital' or 'wigwag,horizontal' "
                        "(default angular,orbital)")
    parser.add_argument("--measure", default="inverse-condition", choices=sing.MAP_MEASURES,
                        help="measure of the second map (default inverse-condition)")
    parser.add_argument("--grid", type=int, default=61, help="grid points per map axis (default 61)")
    parser.add_argument("--length-mm", type=float, default=None,
                        help="characteristic length for the scaling (default: orbital offset)")
    parser.add_argument("--near-deg", type=float, default=5.0,
                        help="report a singular set as near within this angle (default 5)")
    parser.add_argument("--check", type=int, default=0, metavar="N",
                        help="compare Pinocchio's det J with eq. 4.7 on N random configurations")
    parser.add_argument("--random-setups", type=int, default=100, metavar="K",
                        help="spread --check over K random non-isocentric systems too (default 100)")
    parser.add_argument("--seed", type=int, default=0, help="random seed of --check (default 0)")
    parser.add_argument("--tolerance", type=float, default=1e-9, help="pass threshold of --check (default 1e-9)")


def configuration(system, text: str | None) -> np.ndarray:
    """q (SI) from 'D0,D1,T2,D3,T4,T5' in mm/deg, or the default (revolute 0, prismatic mid-range)."""
    if text is None:
        mid = (system.lower + system.upper) / 2
        return np.where(system.prismatic, mid, 0.0)
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError as exc:
        raise sing.SingularityError(f"--q-mm-deg must be six numbers separated by commas, got {text!r}") from exc
    if len(values) != 6:
        raise sing.SingularityError(f"--q-mm-deg needs 6 values (d0,d1,θ2,d3,θ4,θ5), got {len(values)}")
    return np.array([v / 1e3 if p else math.radians(v) for v, p in zip(values, PRISMATIC)])


def pair_of(text: str) -> tuple[int, int]:
    """Joint indices from 'name,name'."""
    names = text.split(",")
    if len(names) != 2:
        raise sing.SingularityError(f"--pair needs two joint names separated by a comma, got {text!r}")
    return sing.joint_index(names[0]), sing.joint_index(names[1])


def run(args: argparse.Namespace) -> int:
    system = system_from_args(args)
    length = None if args.length_mm is None else args.length_mm / 1e3
    q = configuration(system, args.q_mm_deg)
    shown = ", ".join(f"{n}={v * 1e3 if p else math.degrees(v):g}{'mm' if p else '°'}"
                      for n, v, p in zip(JOINT_NAMES, q, PRISMATIC))
    print(f"preset {system.name}: q = {shown}")
    print(sing.classify(system, q, near=math.radians(args.near_deg), length=length).describe())
    status = 0
    if args.check:
        worst = sing.check_determinant(system, args.check, args.random_setups, args.seed)
        ok = worst <= args.tolerance
        print(f"det J (Pinocchio) vs eq. 4.7 on {args.check} configurations, {args.random_setups} random "
              f"non-isocentric systems: max |difference| {worst:.3e} {'<=' if ok else '>'} {args.tolerance:g}: "
              f"{'PASS' if ok else 'FAIL'}")
        status = 0 if ok else 1
    if args.plot:
        pair = pair_of(args.pair)
        from carmkin import plots

        plots.singularity_maps(system, q, args.plot, pair=pair, n=args.grid, measure=args.measure, length=length)
        print(f"wrote {args.plot}")
    return status
