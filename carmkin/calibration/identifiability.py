"""Which parameters the given views determine: the rule, from the column-scaled Jacobian of the residual.

Scale each column of the Jacobian (px per mm, deg or px) to unit length, so that units drop out and a column
measures only *how* a parameter moves the reference points' pixels. Then, in the priority order of
:func:`.quantities.parameters`, keep a parameter when the columns kept so far plus its own still have a
smallest singular value of at least :data:`MIN_SINGULAR_VALUE`; otherwise it is **held** at its nominal value
and named unidentifiable, with the reason:

- ``NO_EFFECT``: its column is (numerically) zero, below :data:`NO_EFFECT` px per unit: these views do not
  see it at all;
- ``CONFOUNDED``: its column lies within the tolerance of the span of kept ones: its effect on every
  projection equals that of a combination of them (named, in each one's unit per unit of it), so the data
  cannot tell them apart. E.g. ``length_offset`` always, with ``horizontal_zero_offset`` (DH row 3 adds
  d3 + l1): 1 mm of l1 is 1 mm of horizontal zero offset.

The smallest singular value of unit columns is the sine of the smallest angle between a kept column and the
span of the others (at most): the rule keeps each parameter's standard deviation within
1 / :data:`MIN_SINGULAR_VALUE` of what it would be if its effect were orthogonal to the rest. The singular
values of all the scaled columns, and the combinations (right singular vectors) below the tolerance, are
reported too.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

#: Smallest singular value (dimensionless, of unit-length columns) the kept parameters' Jacobian may have:
#: 1e-3, a standard deviation at most 1000 times that of a parameter whose effect is orthogonal to the others'.
#: Exact redundancies give ~1e-9 (the central differences' round-off); the 30-view acceptance set keeps every
#: other parameter with ~1e-2 or more (docs/calibration.md).
MIN_SINGULAR_VALUE = 1e-3
#: A column below this norm (px per mm, deg or px, over all reference points of all views) has no effect.
NO_EFFECT = 1e-9
#: A kept parameter is named in a held one's combination when its scaled weight is at least this fraction
#: of the largest weight.
NAMED_WEIGHT = 0.05


class Reason(enum.Enum):
    """Why a parameter is held at its nominal value."""

    NO_EFFECT = "no-effect"
    CONFOUNDED = "confounded"


@dataclass(frozen=True)
class Held:
    """A parameter the views cannot determine.

    Attributes:
        name: the parameter. reason: :class:`Reason`.
        equivalent: ``((name, amount), ...)``: one unit of the held parameter moves the projections as these
            amounts (in each kept parameter's unit) of kept parameters do (empty for ``NO_EFFECT``).
        separation: the smallest singular value with its column added (below :data:`MIN_SINGULAR_VALUE`).
    """

    name: str
    reason: Reason
    equivalent: tuple[tuple[str, float], ...]
    separation: float


@dataclass(frozen=True)
class Identifiability:
    """The identifiability report of a Jacobian.

    Attributes:
        names: every parameter asked for, in priority order. kept: those the views determine.
        held: :class:`Held` for each of the others.
        singular_values: of the column-scaled Jacobian of all the parameters asked for, descending.
        combinations: for each singular value below :data:`MIN_SINGULAR_VALUE` (of the largest), the
            right singular vector as ``((name, weight), ...)`` (scaled units, largest weights first).
        smallest_kept: the smallest singular value of the kept parameters' scaled Jacobian.
    """

    names: tuple[str, ...]
    kept: tuple[str, ...]
    held: tuple[Held, ...]
    singular_values: tuple[float, ...]
    combinations: tuple[tuple[tuple[str, float], ...], ...]
    smallest_kept: float

    @property
    def unidentifiable(self) -> tuple[str, ...]:
        """The names of the held parameters."""
        return tuple(h.name for h in self.held)


def analyse(J: np.ndarray, names) -> Identifiability:
    """The report for a Jacobian J (m residuals, p parameters in priority order) and the parameters' names."""
    names = tuple(names)
    norms = np.linalg.norm(J, axis=0)
    live = norms > NO_EFFECT
    scaled = np.where(live, J / np.where(live, norms, 1.0), 0.0)
    R = np.linalg.qr(scaled, mode="r")  # same singular values as any column subset of `scaled`
    kept: list[int] = []
    held = []
    for j, name in enumerate(names):
        if not live[j]:
            held.append(Held(name, Reason.NO_EFFECT, (), 0.0))
            continue
        smallest = np.linalg.svd(R[:, kept + [j]], compute_uv=False)[-1]
        if smallest >= MIN_SINGULAR_VALUE:
            kept.append(j)
            continue
        weights = np.linalg.lstsq(R[:, kept], R[:, j], rcond=None)[0] if kept else np.zeros(0)
        big = np.abs(weights).max() if len(weights) else 0.0
        equivalent = tuple((names[k], float(w * norms[j] / norms[k]))
                           for k, w in sorted(zip(kept, weights), key=lambda kw: -abs(kw[1]))
                           if abs(w) >= NAMED_WEIGHT * big)
        held.append(Held(name, Reason.CONFOUNDED, equivalent, float(smallest)))
    _, s, Vt = np.linalg.svd(scaled, full_matrices=False)
    small = s < MIN_SINGULAR_VALUE * s[0]
    combinations = tuple(tuple((names[k], float(v[k])) for k in np.argsort(-np.abs(v)) if abs(v[k]) >= 0.1)
                         for v in Vt[small])
    smallest_kept = float(np.linalg.svd(R[:, kept], compute_uv=False)[-1]) if kept else 0.0
    return Identifiability(names, tuple(names[k] for k in kept), tuple(held), tuple(float(x) for x in s),
                           combinations, smallest_kept)
