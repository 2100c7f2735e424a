"""The ``carmkin`` command line. Each subcommand lives in its own module of :mod:`carmkin.commands`.

A command module defines ``HELP`` (one line), ``register(parser)`` to add its arguments and
``run(args) -> int`` returning the exit code. Units on the command line are mm and degrees. Command modules
import only numpy and carmkin's light public face at module level, so that ``carmkin --help`` is fast; the
heavy libraries load inside ``run``.

Exit codes: 0 success; 1 a check or plan that was run failed (``verify`` FAIL, an invalid plan, ...);
2 a usage error, an input the command cannot use, an output that cannot be written, or a command that does
not apply to the system (one line on stderr naming the option); 3 an internal error (one line; set
``CARMKIN_DEBUG=1`` for the traceback); 130 interrupted.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import pkgutil
import re
import sys

from carmkin import _version
from carmkin.errors import CarmkinError

from . import commands

#: Order in which the subcommands are listed by ``--help``; modules not named here come last.
ORDER = ("verify", "ik", "urdf", "workspace", "singularity", "panorama", "view")
USAGE_ERROR, INTERNAL_ERROR, INTERRUPTED = 2, 3, 130
#: Exit status when stdout was closed early (``carmkin workspace | head``): the shell's status of a process
#: ended by SIGPIPE (128 + 13); the command stops quietly, as ``yes | head`` does.
BROKEN_PIPE = 141


#: An argument that is a value, not an option, though it starts with "-": a negative number or a comma-separated
#: list of numbers whose first is negative (``--primary-range-deg -90,90``, ``--q-mm-deg -5,200,0,100,0,0``).
#: argparse alone knows only a lone negative number, and read the list as an unknown option.
NEGATIVE_NUMBERS = re.compile(r"^-(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?:,\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)*$")


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line (``carmkin view: error: argument --q: ...``), exit 2,
    and which reads a value starting with a negative number as a value (:data:`NEGATIVE_NUMBERS`), no ``=``
    needed."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_NUMBERS  # argparse's own hook for "looks like a negative number"

    def error(self, message: str):
        self.exit(USAGE_ERROR, f"{self.prog}: error: {_one_line(message)} (see {self.prog} --help)\n")

    def parse_known_args(self, args=None, namespace=None):
        """A subcommand's parser refuses what it does not know itself, so the usage error names the subcommand
        (``carmkin view: error: unrecognized arguments: --bogus``), not ``carmkin``."""
        namespace, extras = super().parse_known_args(args, namespace)
        if extras and self.prog != "carmkin":
            self.error(f"unrecognized arguments: {' '.join(extras)}")
        return namespace, extras


class _VersionAction(argparse.Action):
    """``--version``: the installed version, read from the package metadata only when asked (importlib.metadata
    costs ``carmkin --help`` a tenth of its time)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help="show program's version number and exit"):
        super().__init__(option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"carmkin {_version()}")  # on stdout, as argparse's own version action prints it
        parser.exit()


def plain_text(doc: str | None) -> str | None:
    """A docstring as ``--help`` shows it: reST roles and literals (``:class:`X```, ````x````, ```x```) as plain
    text."""
    if doc is None:
        return None
    doc = re.sub(r":(?:py:)?[a-z]+:`~?([^`]+)`", r"\1", doc)
    return re.sub(r"``([^`]+)``|`([^`]+)`", lambda m: m[1] or m[2], doc)


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def _command_modules():
    names = [m.name for m in pkgutil.iter_modules(commands.__path__) if not m.name.startswith("_")]
    names.sort(key=lambda n: (ORDER.index(n) if n in ORDER else len(ORDER), n))
    return [(n, importlib.import_module(f"{commands.__name__}.{n}")) for n in names]


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="carmkin",
        description="Kinematics of a mobile X-ray C-arm + operating table as one chain. "
        "Lengths on the command line are in mm, angles in degrees.",
        epilog="exit codes: 0 ok, 1 a check failed, 2 usage error or unusable input, 3 internal error",
    )
    parser.add_argument("--version", action=_VersionAction)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=OneLineParser)
    for name, module in _command_modules():
        command = sub.add_parser(name, help=module.HELP, description=plain_text(module.__doc__),
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
        module.register(command)
        command.set_defaults(run=module.run)
        _name_every_parser(command)
    return parser


def _name_every_parser(parser: argparse.ArgumentParser) -> None:
    """``args.prog``: the full name of the (sub)command that parsed (``carmkin panorama map``), for error lines."""
    parser.set_defaults(prog=parser.prog)
    parser.description = plain_text(parser.description)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in action.choices.values():
                _name_every_parser(child)


def _quiet_stdout() -> None:
    """Point stdout's descriptor at the null device, so that the interpreter's last flush of a closed pipe
    prints no second error (the recipe of the Python docs on SIGPIPE)."""
    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # a stdout without a descriptor (captured in tests)
        pass


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    name = getattr(args, "prog", f"carmkin {args.command}")
    prefix = f"{name}: error:"
    if not sys.stderr.isatty():  # progress bars only on a terminal: no bar frames in a redirected log
        os.environ.setdefault("TQDM_DISABLE", "1")
    try:
        from carmkin.commands._common import STDOUT, check_output_paths
        from carmkin.commands._progress import Heartbeat

        check_output_paths(args)  # every file the command will write, before any work
        if getattr(args, "json", None) == STDOUT:  # the JSON alone on stdout, instead of the text report
            args.json_stream = sys.stdout
            with open(os.devnull, "w") as quiet, contextlib.redirect_stdout(quiet), Heartbeat(name):
                return int(args.run(args) or 0)
        with Heartbeat(name):  # a line on a terminal's stderr while a command without its own bar works
            return int(args.run(args) or 0)
    except CarmkinError as exc:
        print(f"{prefix} {_one_line(exc)}", file=sys.stderr)
        return USAGE_ERROR
    except BrokenPipeError:  # stdout closed by the reader: stop quietly, nothing more can be said on it
        _quiet_stdout()
        return BROKEN_PIPE
    except OSError as exc:  # a file that cannot be read or written
        where = f" {exc.filename}" if exc.filename else ""
        print(f"{prefix} cannot access{where}: {exc.strerror or _one_line(exc)}", file=sys.stderr)
        return USAGE_ERROR
    except KeyboardInterrupt:
        print(f"{name}: interrupted", file=sys.stderr)
        return INTERRUPTED
    except Exception as exc:  # a bug: still one line for the user, the traceback on request
        if os.environ.get("CARMKIN_DEBUG"):
            raise
        print(f"{name}: internal error: {type(exc).__name__}: {_one_line(exc)} "
              "(set CARMKIN_DEBUG=1 for the traceback and please report it)", file=sys.stderr)
        return INTERNAL_ERROR


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
