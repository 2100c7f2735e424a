"""What a real C-arm and table can measure: the bounds every value is checked against at construction.

A value beyond these bounds is refused with :class:`~carmkin.errors.InvalidParameterError` before it can
reach a solver (a 1e16 m offset or a ±1e17 rad joint range makes the closed form and Pinocchio disagree by
metres, or a branch search run for ever). The bounds are generous: no mobile C-arm or operating table
comes within a factor of three of them.
"""

from __future__ import annotations

import math

import numpy as np

from carmkin.errors import InvalidParameterError
from carmkin.validation import real_scalar

#: Largest length (m) of any C-arm or table dimension, offset, position or prismatic joint limit: 10 m.
MAX_LENGTH = 10.0
#: Smallest strictly positive length (m): 1 µm (offsets, source-to-detector distance, box sizes).
MIN_LENGTH = 1e-6
#: Largest |angle| (rad) of a revolute joint limit or a setup angle γ1..γ3: one full turn, 2π.
MAX_ANGLE = 2.0 * math.pi
#: Largest |D1|, |D2|, |D3| (m) of a table setup. They are DH constants, not physical lengths: they grow
#: as 1/sin γ1 when the table axis nears the vertical axis (singular case a); 1000 km keeps the closed form
#: at 1e-10 m precision.
MAX_SETUP_DISTANCE = 1e6
#: Largest detector size in pixels per side, and largest |principal point coordinate| (px).
MAX_PIXELS = 100_000
#: Sine of the smallest angle (rad, ≈ 1e-6) between a table axis and the C-arm's vertical axis that
#: :meth:`~carmkin.model.params.TableSetup.from_pose` accepts; below it, down to
#: :data:`PARALLEL_AXES_SIN`, the common normal is too ill-conditioned to compute (singular case a).
NEAR_PARALLEL_SIN = 1e-6
#: Sine of the angle below which the table axis counts as parallel to the vertical axis (DH convention).
PARALLEL_AXES_SIN = 1e-12


def check_real(what: str, value, low: float = -math.inf, high: float = math.inf, unit: str = "") -> float:
    """``value`` as a float if it is a real, finite number in ``[low, high]``; else InvalidParameterError.

    Refuses bool, str, complex and arrays (no silent cast, no ComplexWarning): see
    :func:`carmkin.validation.real_scalar`. ``what`` names the value in the message, ``unit`` is appended to
    the numbers quoted.
    """
    return real_scalar(value, what, error=InvalidParameterError, low=None if low == -math.inf else low,
                       high=None if high == math.inf else high, limit=None, unit=unit)


def check_length(what: str, value, positive: bool = False) -> float:
    """A length (m) within ±:data:`MAX_LENGTH`, and at least :data:`MIN_LENGTH` if ``positive``."""
    return check_real(what, value, MIN_LENGTH if positive else -MAX_LENGTH, MAX_LENGTH, "m")


def check_count(what: str, value, high: int = MAX_PIXELS) -> int:
    """A positive integer ≤ ``high`` (bool refused)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or not 0 < value <= high:
        raise InvalidParameterError(f"{what} must be an integer in [1, {high}], got {value!r}")
    return int(value)


def check_joint_limits(joint_range, prismatic: bool, owner: str) -> None:
    """Refuse a joint range beyond ±:data:`MAX_LENGTH` (prismatic, m) or ±:data:`MAX_ANGLE` (revolute, rad)."""
    bound, unit = (MAX_LENGTH, "m") if prismatic else (MAX_ANGLE, "rad")
    for side in ("lower", "upper"):
        check_real(f"{owner}.{joint_range.name}.{side}", getattr(joint_range, side), -bound, bound, unit)

