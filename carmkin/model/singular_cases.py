"""The singular cases of the 6-DOF chain (§4.3.2, eq. 4.7): one vocabulary, the factors of det J, distances.

``det J = sin(θ2 + γ3) · sin γ1 · cos θ4`` (eq. 4.7; dimensionless, Jacobian rows ``[v; ω]`` in the table
axes, checked against Pinocchio in ``tests/test_singularity.py``). Each factor vanishes on one singular set:

- :attr:`SingularCase.TABLE_PARALLEL_TO_VERTICAL` ("a"): sin γ1 = 0, the table axis Z0 ∥ the vertical axis
  Z1 (a property of the setup, not of q);
- :attr:`SingularCase.ORBITAL_PARALLEL_TO_WIGWAG` ("b"): cos θ4 = 0, the orbital axis Z5 ∥ the wigwag axis Z2;
- :attr:`SingularCase.TABLE_PARALLEL_TO_HORIZONTAL` ("c"): sin(θ2 + γ3) = 0, the horizontal axis Z3 ∥ the
  horizontal projection of the table axis.

Each factor is the sine of an angle, so :func:`distances` reports ``asin|factor|`` (rad): how far γ1, θ4 or
θ2 is from its set. Used by :mod:`carmkin.singularity`, :mod:`carmkin.analytic_ik` and
:mod:`carmkin.studies.workspace`. Numpy only.
"""

from __future__ import annotations

import math
from enum import StrEnum
from typing import NamedTuple

import numpy as np

from .params import TableSetup


class SingularCase(StrEnum):
    """The three singular cases of §4.3.2; the value is the paper's letter (``SingularCase("a")``)."""

    TABLE_PARALLEL_TO_VERTICAL = "a"
    ORBITAL_PARALLEL_TO_WIGWAG = "b"
    TABLE_PARALLEL_TO_HORIZONTAL = "c"

    @property
    def letter(self) -> str:
        """The paper's letter: "a", "b" or "c"."""
        return self.value

    @property
    def long_name(self) -> str:
        """Letter and description, e.g. ``"a_table_parallel_to_vertical"``."""
        return f"{self.value}_{self.name.lower()}"

    @property
    def title(self) -> str:
        """The geometric condition in words, with the vanishing factor."""
        return _TITLES[self]

    @property
    def loss(self) -> str:
        """What is lost in this case, in words (directions in the table frame; n is the lost axis)."""
        return _LOSSES[self]


#: The cases in the order of the factors of :class:`SingularFactors` (a, b, c).
CASES = tuple(SingularCase)

_TITLES = {
    SingularCase.TABLE_PARALLEL_TO_VERTICAL: "table axis Z0 parallel to vertical axis Z1 (sin γ1 = 0)",
    SingularCase.ORBITAL_PARALLEL_TO_WIGWAG: "orbital axis Z5 parallel to wigwag axis Z2 (cos θ4 = 0)",
    SingularCase.TABLE_PARALLEL_TO_HORIZONTAL:
        "horizontal axis Z3 parallel to the table axis's horizontal projection (θ2 = −γ3 mod π)",
}
_LOSSES = {
    SingularCase.TABLE_PARALLEL_TO_VERTICAL:
        "table translation and vertical move the source along the same line (self-motion ḋ0 = ∓ḋ1); "
        "with its orientation held, the source cannot translate along n = Z1 × Z3 (horizontal, across "
        "the C-arm's horizontal arm)",
    SingularCase.ORBITAL_PARALLEL_TO_WIGWAG:
        "wigwag and orbital turn the source about parallel axes (self-motion θ̇2 = ±θ̇5 with compensating "
        "prismatic moves); the source cannot rotate about n = Z2 × Z4 (horizontal, across the arm)",
    SingularCase.TABLE_PARALLEL_TO_HORIZONTAL:
        "table translation, vertical and horizontal are coplanar (self-motion of d0, d1, d3 only); with "
        "its orientation held, the source cannot translate along n = Z0 × Z1 (the common normal X1)",
}


class SingularFactors(NamedTuple):
    """The three factors of eq. 4.7 (dimensionless; arrays broadcast over configurations)."""

    a: np.ndarray  #: sin γ1
    b: np.ndarray  #: cos θ4
    c: np.ndarray  #: sin(θ2 + γ3) = sγ3 cθ2 + cγ3 sθ2


def factors(setup: TableSetup, theta2, theta4) -> SingularFactors:
    """Factors (sin γ1, cos θ4, sin(θ2 + γ3)) of eq. 4.7 for wigwag and angular angles (rad), broadcast."""
    theta2, theta4 = np.asarray(theta2, dtype=float), np.asarray(theta4, dtype=float)
    shape = np.broadcast_shapes(theta2.shape, theta4.shape)
    a = np.full(shape, math.sin(setup.gamma1))  # constant of the setup, shaped like the others
    return SingularFactors(a, np.cos(theta4), np.sin(theta2 + setup.gamma3))


def det_closed_form(setup: TableSetup, theta2, theta4):
    """``det J`` by eq. 4.7 (dimensionless) for wigwag and angular angles (rad), broadcast."""
    f = factors(setup, theta2, theta4)
    return f.a * f.b * f.c


def distances(f: SingularFactors) -> dict[SingularCase, np.ndarray]:
    """Distance to each singular set (rad): ``asin|factor|``, keyed by :class:`SingularCase`."""
    return {case: np.arcsin(np.minimum(np.abs(v), 1.0)) for case, v in zip(CASES, f)}


def cases_below(f, tolerance: float) -> tuple[SingularCase, ...]:
    """The cases whose factor (three floats, a b c) is below ``tolerance`` in magnitude; at least the one
    with the smallest factor (for a pose already known to be singular)."""
    found = tuple(case for case, v in zip(CASES, f) if abs(v) < tolerance)
    return found or (CASES[int(np.argmin(np.abs(np.asarray(f, dtype=float))))],)
