"""Arguments and helpers shared by several subcommands."""

from __future__ import annotations

import argparse

from carmkin.model.system import CArmSystem
from carmkin.presets import list_presets, load_preset

DEFAULT_PRESET = "siremobile-iso-c3d"


def add_preset_argument(parser: argparse.ArgumentParser) -> None:
    """``--preset NAME|FILE.toml`` (default: the Siremobile Iso-C 3D)."""
    parser.add_argument("--preset", default=DEFAULT_PRESET,
                        help=f"built-in preset ({', '.join(list_presets())}) or a preset .toml file "
                        f"(default: {DEFAULT_PRESET})")


def system_from_args(args: argparse.Namespace) -> CArmSystem:
    """The system named by ``--preset``."""
    return load_preset(args.preset)
