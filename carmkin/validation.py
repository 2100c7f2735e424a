"""The public boundary: user input to finite real numpy arrays, or a typed error naming the argument.

Every public function that takes numbers passes them through :func:`real_array` or :func:`real_scalar`
once, at the boundary, and trusts them afterwards. What is refused, with a :class:`carmkin.CarmkinError`
subclass that names the argument, the value and what was expected:

- ``None``, strings, bytes, objects numpy cannot read as numbers (never parsed: ``"1.5"`` is not 1.5);
- booleans (``True`` is not 1 mm or 1°);
- complex numbers, even with a zero imaginary part (numpy would cast them with a ``ComplexWarning``);
- NaN and ±inf (unless ``finite=False``);
- a wrong shape (``None`` in the expected shape matches any size);
- magnitudes above ``limit`` (no real C-arm or table is kilometres long).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from carmkin.errors import CarmkinError, InvalidParameterError

#: Largest magnitude (m or rad) of any number a public function accepts (joint values, pose entries,
#: points): a thousand kilometres. Far beyond any real C-arm, table or pose — the IK's out-of-range
#: branches near a singular pose reach thousands — and small enough that products of such numbers stay
#: finite, so no overflow warning can leak. Geometry parameters have tighter bounds
#: (:mod:`carmkin.model.bounds`).
MAGNITUDE_LIMIT = 1e6
#: Largest |joint value| (m or rad) accepted: only an overflow guard (squares stay finite). A joint value is
#: not bounded physically, because the IK's branches near a singular pose legitimately grow as 1/distance
#: (4e6 m at 1e-7 from case (c)) and must still be evaluated (FK, validity) to be reported out of range.
JOINT_VALUE_LIMIT = 1e150


def _describe(value) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _shape_text(shape: Sequence[int | None]) -> str:
    return "(" + ", ".join("N" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"


def real_array(
    value,
    name: str,
    shape: Sequence[int | None] | None = None,
    *,
    error: type[CarmkinError] = InvalidParameterError,
    finite: bool = True,
    limit: float | None = MAGNITUDE_LIMIT,
    unit: str = "",
) -> np.ndarray:
    """``value`` as a float64 array of ``shape``, or ``error`` naming ``name`` and what was expected.

    ``unit`` (e.g. ``"m"``, ``"rad"``) is quoted in the message; ``limit`` bounds every element's magnitude
    (``None``: no bound).
    """
    unit_text = f" ({unit})" if unit else ""
    if shape is not None and len(shape) == 0:
        expected = f"a real number{unit_text}"
    else:
        expected = f"real numbers{unit_text}" + (f" of shape {_shape_text(shape)}" if shape is not None else "")
    if value is None or isinstance(value, (str, bytes)):
        raise error(f"{name} must be {expected}, got {_describe(value)}")
    try:
        array = np.asarray(value)
    except (ValueError, TypeError) as exc:  # ragged nesting
        raise error(f"{name} must be {expected}, got {_describe(value)} ({exc})") from None
    if array.dtype.kind == "c":
        raise error(f"{name} must be {expected}, got complex values {_describe(value)}")
    if array.dtype.kind == "b":
        raise error(f"{name} must be {expected}, got booleans {_describe(value)}")
    if array.dtype.kind not in "iuf":
        raise error(f"{name} must be {expected}, got {_describe(value)} (dtype {array.dtype})")
    if array.dtype.kind in "iu" and array.size and np.max(np.abs(array.astype(object))) > 2**53:
        raise error(f"{name} must be {expected}, got integers too large to be exact as floats")
    array = array.astype(float)
    if shape is not None and (
        array.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, array.shape))
    ):
        raise error(f"{name} must be {expected}, got shape {array.shape}")
    if finite and not np.all(np.isfinite(array)):
        raise error(f"{name} must be finite (no NaN or Inf), got {_describe(value)}")
    if limit is not None and array.size and np.max(np.abs(np.nan_to_num(array, posinf=0.0, neginf=0.0))) > limit:
        raise error(f"{name} must be {expected} within ±{limit:g}{unit_text}, got {_describe(value)}")
    return array


def real_scalar(
    value,
    name: str,
    *,
    error: type[CarmkinError] = InvalidParameterError,
    low: float | None = None,
    high: float | None = None,
    limit: float | None = MAGNITUDE_LIMIT,
    unit: str = "",
) -> float:
    """``value`` as a float within [``low``, ``high``] (either may be ``None``), or ``error`` naming ``name``."""
    number = float(real_array(value, name, (), error=error, limit=limit, unit=unit))
    if (low is not None and number < low) or (high is not None and number > high):
        bounds = f"[{'-inf' if low is None else f'{low:g}'}, {'inf' if high is None else f'{high:g}'}]"
        raise error(f"{name} must be within {bounds}{f' {unit}' if unit else ''}, got {number:g}")
    return number
