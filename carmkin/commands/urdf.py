"""Write the URDF of a preset, generated from urdf/carm_table.urdf.xacro (lengths in m, angles in rad)."""

from __future__ import annotations

import argparse
import sys

from ._common import add_preset_argument, output_path, system_from_args

HELP = "write the URDF of a preset (to stdout or -o FILE)"


def register(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    parser.add_argument("-o", "--output", help="file to write; its folder must exist (default: standard output)")


def run(args: argparse.Namespace) -> int:
    output = None if args.output is None else output_path(args.output, "--output")
    text = system_from_args(args).urdf()
    if output is not None:
        with open(output, "w") as stream:
            stream.write(text)
        print(f"wrote {args.output}", file=sys.stderr)
    else:
        sys.stdout.write(text)
    return 0
