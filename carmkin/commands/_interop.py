"""Arguments shared by the interop commands (``project``, ``dicom``, ``drr``): a configuration of any
number of joints in mm / degrees, and its printout, through the one CLI parser/printer of :mod:`._common`."""

from __future__ import annotations

import argparse

import numpy as np

from carmkin.errors import InvalidParameterError

from ._common import JOINTS_FLAG, MM_PER_M, add_joints_argument, format_joints, parse_joints, parse_numbers


def add_configuration_argument(parser: argparse.ArgumentParser, what: str = "configuration") -> None:
    add_joints_argument(parser, what)


def configuration(system, text: str | None, flag: str = JOINTS_FLAG) -> np.ndarray:
    """q (nq,) in SI from 'v1,v2,...' (mm / deg, within the joint ranges), or the default (prismatic
    mid-range, revolute 0)."""
    if text is None:
        return np.where(system.prismatic, 0.5 * (system.lower + system.upper), 0.0)
    return parse_joints(text, system, flag)


def describe(system, q) -> str:
    """'name=value unit, ...' of a configuration in mm / degrees."""
    return format_joints(system, q)


def millimetres(text: str | None, flag: str) -> np.ndarray | None:
    """Three lengths 'x,y,z' given in mm, returned in m (3,); ``None`` stays ``None``."""
    return None if text is None else parse_numbers(text, 3, flag, error=InvalidParameterError) / MM_PER_M
