"""The ``carmkin`` command line. Each subcommand lives in its own module of :mod:`carmkin.commands`.

A command module defines ``HELP`` (one line), ``register(parser)`` to add its arguments and
``run(args) -> int`` returning the exit code. Units on the command line are mm and degrees.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from carmkin.errors import CarmkinError

from . import commands

#: Order in which the subcommands are listed by ``--help``; modules not named here come last.
ORDER = ("verify", "ik", "urdf", "workspace", "singularity", "panorama", "view")


def _command_modules():
    names = [m.name for m in pkgutil.iter_modules(commands.__path__) if not m.name.startswith("_")]
    names.sort(key=lambda n: (ORDER.index(n) if n in ORDER else len(ORDER), n))
    return [(n, importlib.import_module(f"{commands.__name__}.{n}")) for n in names]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="carmkin",
        description="Kinematics of a mobile X-ray C-arm + operating table (6-DOF chain). "
        "Lengths on the command line are in mm, angles in degrees.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, module in _command_modules():
        command = sub.add_parser(name, help=module.HELP, description=module.__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
        module.register(command)
        command.set_defaults(run=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except CarmkinError as exc:
        print(f"carmkin {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
