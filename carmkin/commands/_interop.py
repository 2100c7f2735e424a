"""Arguments shared by the interop commands (``project``, ``dicom``, ``drr``): a configuration of any
number of joints in mm / degrees, and its printout."""

from __future__ import annotations

import argparse
import math

import numpy as np

from carmkin.errors import InvalidConfigurationError, InvalidParameterError


def add_configuration_argument(parser: argparse.ArgumentParser, flag: str = "--q-mm-deg",
                               what: str = "configuration") -> None:
    parser.add_argument(flag, metavar="V1,V2,...",
                        help=f"{what}: one value per joint, mm for prismatic and deg for revolute joints "
                        "(default: prismatic joints mid-range, revolute 0°)")


def configuration(system, text: str | None, flag: str = "--q-mm-deg") -> np.ndarray:
    """q (nq,) in SI from 'v1,v2,...' (mm / deg), or the default (prismatic mid-range, revolute 0)."""
    if text is None:
        return np.where(system.prismatic, 0.5 * (system.lower + system.upper), 0.0)
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError as exc:
        raise InvalidConfigurationError(f"{flag} must be numbers separated by commas, got {text!r}") from exc
    if len(values) != system.nq or not all(math.isfinite(v) for v in values):
        raise InvalidConfigurationError(
            f"{flag} needs {system.nq} finite values ({', '.join(system.joint_names)}), got {text!r}")
    return np.array([v / 1e3 if p else math.radians(v) for v, p in zip(values, system.prismatic)])


def describe(system, q) -> str:
    """'name=value unit, ...' of a configuration in mm / degrees."""
    return ", ".join(f"{n}={v * 1e3 if p else math.degrees(v):.6g}{'mm' if p else '°'}"
                     for n, v, p in zip(system.joint_names, q, system.prismatic))


def millimetres(text: str | None, flag: str) -> np.ndarray | None:
    """Three lengths 'x,y,z' given in mm, returned in m (3,); ``None`` stays ``None``."""
    if text is None:
        return None
    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError as exc:
        raise InvalidParameterError(f"{flag} must be three numbers (mm) separated by commas, got {text!r}") from exc
    if values.shape != (3,) or not np.all(np.isfinite(values)):
        raise InvalidParameterError(f"{flag} must be three finite numbers (mm), got {text!r}")
    return values / 1e3
