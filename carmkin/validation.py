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

import math
from typing import Sequence

import numpy as np

from carmkin.errors import CarmkinError, InvalidParameterError, InvalidPoseError

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
    # finite arrays need no nan_to_num (a third of this function's time on a 6-vector)
    if limit is not None and array.size and (
            np.abs(array) if finite else np.abs(np.nan_to_num(array, posinf=0.0, neginf=0.0))).max() > limit:
        raise error(f"{name} must be {expected} within ±{limit:g}{unit_text}, got {_describe(value)}")
    return array


def plain_floats(value, n: int, limit: float = MAGNITUDE_LIMIT) -> list[float] | None:
    """The ``n`` values of ``value`` as a list of Python floats when it is plainly valid — a float64 array
    of shape (n,), or a list or tuple of ``n`` Python floats, every value finite and within ``limit`` — and
    None for anything else (the caller then takes its full check, :func:`real_array`, which says what is
    wrong). The scalar fast paths of FK and IK: ~10x cheaper than building a checked array."""
    if type(value) is np.ndarray:
        if value.shape != (n,) or value.dtype != np.float64:
            return None
        values = value.tolist()
    elif type(value) in (list, tuple) and len(value) == n and all(type(v) is float for v in value):
        values = list(value)
    else:
        return None
    # a NaN or inf makes the sum non-finite; a sum that overflows has a value beyond any limit
    if not (values and math.isfinite(sum(values)) and max(map(abs, values)) <= limit):
        return None
    return values


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
        raise error(f"{name} must be within {bounds}{f' {unit}' if unit else ''}, got {number:g}"
                    f"{unit_slip(number, low, high, unit)}")
    return number


#: Units a value is often given in by mistake, for each unit the toolkit speaks: ``(unit given, factor to the
#: expected unit)``. Used by :func:`unit_slip` to name the likely slip of an implausible length or angle.
UNIT_SLIPS = {
    "m": (("mm", 1e-3), ("cm", 1e-2)),
    "mm": (("m", 1e3), ("cm", 10.0)),
    "rad": (("degrees", math.pi / 180.0),),
    "deg": (("radians", 180.0 / math.pi),),
}


def unit_slip(number: float, low: float | None, high: float | None, unit: str) -> str:
    """``": given in mm? 1750 mm = 1.75 m"`` when ``number``, read in another unit of :data:`UNIT_SLIPS`, lies
    within [``low``, ``high``] (both bounds needed: a one-sided bound cannot say which slip it was); else ``""``.
    The hint for an error message; the value itself is refused either way, never converted."""
    if low is None or high is None or not math.isfinite(number):
        return ""
    for other, factor in UNIT_SLIPS.get(unit.strip(), ()):
        if low <= number * factor <= high:
            return f": given in {other}? {number:g} {other} = {number * factor:.4g} {unit.strip()}"
    return ""


# --- The kinds of outside geometry: one way in for each -------------------------------------------------
# Every module that accepts a rotation, a rigid transform, camera intrinsics, a projection matrix, points,
# pixels, a length or a joint index converts it through the function below (docs/inputs.md lists what each
# accepts and refuses).

#: Tolerance on ``||R^T R - I||_F``, ``|det R - 1|`` and the last row of a rigid transform (dimensionless).
RIGID_TOLERANCE = 1e-9
#: Tolerance (relative to the focal length) on the entries of K below the diagonal, and absolute on
#: ``K[2, 2] - 1``. K is not normalised silently: a K whose last row is not (0, 0, 1) is refused, naming the
#: division by K[2, 2] that would make it one (a K scaled by 5 is a focal length 5x off, not a rounding).
INTRINSICS_TOLERANCE = 1e-12
#: Largest focal length and |principal point| of K (px): 1e7 px (a 1 µm pixel at 10 m).
MAX_FOCAL_PX = 1e7
#: Largest condition number of a projection matrix's left 3x3 block, after the scale is normalised: beyond
#: it the block is rank-deficient in floating point (no finite centre of projection).
MAX_PROJECTION_CONDITION = 1e12
#: Largest length (m) a public function accepts as a physical distance (source-to-isocentre, object
#: distance, marker size, ...): 10 m, as :data:`carmkin.model.bounds.MAX_LENGTH`.
MAX_DISTANCE = 10.0
#: Smallest strictly positive length (m): 1 µm.
MIN_DISTANCE = 1e-6


def _deviation_text(value: float) -> str:
    return f"{value:.3g}"


def rotation(value, name: str, *, error: type[CarmkinError] = InvalidParameterError,
             tolerance: float = RIGID_TOLERANCE) -> np.ndarray:
    """``value`` as a proper rotation matrix (3, 3), or ``error`` saying by how much it is off.

    Orthonormal to ``tolerance`` (``||R^T R - I||_F``) and ``det R = +1`` to ``tolerance``: a scaled matrix,
    a reflection and a zero matrix are refused (never read as angles).
    """
    R = real_array(value, name, (3, 3), error=error, limit=None)
    ortho = float(np.linalg.norm(R.T @ R - np.eye(3)))
    if not ortho <= tolerance:
        raise error(f"{name} must be a rotation matrix (orthonormal), got ||R^T R - I|| = "
                    f"{_deviation_text(ortho)} > {tolerance:g}")
    det = float(np.linalg.det(R))
    if not abs(det - 1.0) <= tolerance:
        raise error(f"{name} must be a proper rotation (det +1), got det = {det:.6g} (a reflection?)")
    return R


def rigidity(a, b, c, d, e, f, g, h, i):
    """``(||RᵀR − I||_F², det R)`` of R = [[a, b, c], [d, e, f], [g, h, i]] for floats or arrays (written out:
    on plain floats this is ~20x cheaper than numpy's norm and det of a 3x3)."""
    m00, m11, m22 = a * a + d * d + g * g - 1.0, b * b + e * e + h * h - 1.0, c * c + f * f + i * i - 1.0
    m01, m02, m12 = a * b + d * e + g * h, a * c + d * f + g * i, b * c + e * f + h * i
    ortho = m00 * m00 + m11 * m11 + m22 * m22 + 2.0 * (m01 * m01 + m02 * m02 + m12 * m12)
    return ortho, a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def _is_rigid_4x4(T: np.ndarray, tolerance: float) -> bool:
    """The checks of :func:`rigid_transform` on one float64 (4, 4) array, on plain floats (the common case of
    a pose that is rigid; anything else returns False and takes the full path, which says what is wrong)."""
    (a, b, c, px), (d, e, f, py), (g, h, i, pz), last = T.tolist()
    if not (math.isfinite(a + b + c + d + e + f + g + h + i) and last == [0.0, 0.0, 0.0, 1.0]
            and abs(px) <= MAGNITUDE_LIMIT and abs(py) <= MAGNITUDE_LIMIT and abs(pz) <= MAGNITUDE_LIMIT):
        return False  # (each comparison separately: NaN fails it)
    ortho, det = rigidity(a, b, c, d, e, f, g, h, i)
    return ortho <= tolerance * tolerance and abs(det - 1.0) <= tolerance


def rigid_transform(value, name: str, *, error: type[CarmkinError] = InvalidPoseError, batch: bool = False,
                    tolerance: float = RIGID_TOLERANCE) -> np.ndarray:
    """``value`` as a rigid transform (4, 4) (or a stack (N, 4, 4) with ``batch``), or ``error``.

    Entries finite and within :data:`MAGNITUDE_LIMIT` (m), last row [0, 0, 0, 1], rotation orthonormal with
    det +1, each to ``tolerance`` (:data:`RIGID_TOLERANCE`); the message says by how much it is off and
    names :func:`carmkin.transforms.nearest_rigid` for a matrix that is only rounded.
    """
    if (not batch and type(value) is np.ndarray and value.shape == (4, 4) and value.dtype == np.float64
            and _is_rigid_4x4(value, tolerance)):
        return value.copy()  # a copy, as the full path returns: callers may write into it
    T = real_array(value, name, (None, 4, 4) if batch else (4, 4), error=error, unit="m")
    row = np.abs(T[..., 3, :] - (0, 0, 0, 1)).max(initial=0.0)
    if row > tolerance:
        raise error(f"{name}: last row must be [0, 0, 0, 1], off by {_deviation_text(row)}")
    R = T[..., :3, :3]
    ortho = np.linalg.norm(np.swapaxes(R, -1, -2) @ R - np.eye(3), axis=(-2, -1))
    if ortho.max(initial=0.0) > tolerance:
        raise error(f"{name}: rotation is not orthonormal (||R^T R - I|| = {ortho.max():.3g} > {tolerance:g}; "
                    "a pose rounded by hand can be projected with carmkin.transforms.nearest_rigid)")
    det = np.linalg.det(R)
    if np.abs(det - 1.0).max(initial=0.0) > tolerance:
        raise error(f"{name}: rotation has det = {det.min():.6g}, expected +1 (a reflection?)")
    return T


def intrinsics(value, name: str = "K", *, error: type[CarmkinError] = InvalidParameterError) -> np.ndarray:
    """``value`` as a pinhole matrix ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` (px), or ``error``.

    Finite and real; zero below the diagonal and ``K[2, 2] = 1`` (to :data:`INTRINSICS_TOLERANCE`, never
    normalised silently); ``0 < fx, fy <= MAX_FOCAL_PX``; ``|s|, |cx|, |cy| <= MAX_FOCAL_PX``.
    """
    K = real_array(value, name, (3, 3), error=error, limit=None, unit="px")
    text = np.array2string(K, precision=4)
    if not abs(K[2, 2] - 1.0) <= INTRINSICS_TOLERANCE:
        raise error(f"{name} must have K[2, 2] = 1 (pinhole [[fx, s, cx], [0, fy, cy], [0, 0, 1]]), got "
                    f"{K[2, 2]:.6g}; divide K by K[2, 2] if it is only scaled: {text}")
    if not (0.0 < K[0, 0] <= MAX_FOCAL_PX and 0.0 < K[1, 1] <= MAX_FOCAL_PX):
        raise error(f"{name} must have focal lengths 0 < fx, fy <= {MAX_FOCAL_PX:g} px, got "
                    f"fx = {K[0, 0]:.6g}, fy = {K[1, 1]:.6g}")
    below = max(abs(K[1, 0]), abs(K[2, 0]), abs(K[2, 1]))
    if not below <= INTRINSICS_TOLERANCE * max(K[0, 0], K[1, 1], 1.0):
        raise error(f"{name} must be upper triangular (pinhole [[fx, s, cx], [0, fy, cy], [0, 0, 1]]), got {text}")
    if np.abs(K[:2, 1:]).max() > MAX_FOCAL_PX or abs(K[0, 2]) > MAX_FOCAL_PX:
        raise error(f"{name} must have |s|, |cx|, |cy| <= {MAX_FOCAL_PX:g} px, got {text}")
    return K


def projection_matrix(value, name: str = "P", *, error: type[CarmkinError] = InvalidParameterError,
                      points=None) -> np.ndarray:
    """``value`` as a projection matrix (3, 4) normalised to ``||P[2, :3]|| = 1`` with ``det P[:, :3] > 0``.

    Real and finite (any non-zero scale, negative included, is divided out); rank 3 (the condition number
    of the normalised left block at most :data:`MAX_PROJECTION_CONDITION`), so the centre of projection is
    finite. With ``points`` (N, 3) given, each must lie in front of the centre (positive depth), else
    ``error``. In the normalised P, ``P[2] @ (X, 1)`` is the depth (in world units) of a world point X.
    """
    P = real_array(value, name, (3, 4), error=error, limit=None)
    big = float(np.abs(P[2, :3]).max())  # the norm taken after dividing by the largest entry: no overflow
    scale = big * float(np.linalg.norm(P[2, :3] / big)) if big > 0.0 else 0.0
    if not np.isfinite(scale) or scale == 0.0:
        raise error(f"{name} must be a projection matrix with a non-zero third row, got P[2, :3] = {P[2, :3]}")
    with np.errstate(all="ignore"):
        P = P / scale
        det = float(np.linalg.det(P[:, :3]))
        cond = float(np.linalg.cond(P[:, :3])) if np.all(np.isfinite(P)) else np.inf
    if not np.all(np.isfinite(P)) or not np.isfinite(cond) or cond > MAX_PROJECTION_CONDITION or det == 0.0:
        raise error(f"{name} must have a left 3x3 block of rank 3 (a finite centre of projection), got condition "
                    f"number {cond:.3g} > {MAX_PROJECTION_CONDITION:g}")
    if det < 0:
        P = -P
    if points is not None:
        X = point_array(points, "points", error=error)
        depth = X @ P[2, :3] + P[2, 3]
        if not np.all(depth > 0):
            raise error(f"{name}: {int(np.sum(depth <= 0))} of {len(depth)} points lie behind the centre of "
                        f"projection (depth {depth.min():.6g})")
    return P


def point_array(value, name: str, dim: int = 3, *, error: type[CarmkinError] = InvalidParameterError,
                min_count: int = 1, unit: str = "m", limit: float | None = MAGNITUDE_LIMIT) -> np.ndarray:
    """``value`` as an (N, ``dim``) array of finite real coordinates with N >= ``min_count``, or ``error``.

    A single point of shape (``dim``,) is read as N = 1.
    """
    X = real_array(value, name, error=error, unit=unit, limit=limit)
    if X.ndim == 1 and X.shape[0] == dim:
        X = X[None, :]
    if X.ndim != 2 or X.shape[1] != dim:
        raise error(f"{name} must have shape (N, {dim}) ({unit}), got shape {X.shape}")
    if len(X) < min_count:
        raise error(f"{name} must hold at least {min_count} points, got {len(X)}")
    return X


def pixel_array(value, name: str, *, error: type[CarmkinError] = InvalidParameterError,
                min_count: int = 1) -> np.ndarray:
    """``value`` as an (N, 2) array of finite pixel coordinates (px), or ``error`` (bound :data:`MAGNITUDE_LIMIT`)."""
    return point_array(value, name, 2, error=error, min_count=min_count, unit="px")


def distance(value, name: str, *, error: type[CarmkinError] = InvalidParameterError, low: float = MIN_DISTANCE,
             high: float = MAX_DISTANCE, unit: str = "m") -> float:
    """``value`` as a physical length in [``low``, ``high``] (default 1 µm to 10 m), or ``error``."""
    return real_scalar(value, name, error=error, low=low, high=high, unit=unit)


def target_point(value, name: str, *, error: type[CarmkinError] = InvalidParameterError) -> np.ndarray:
    """``value`` as a point (3,) in m, table frame, each coordinate within :data:`MAX_DISTANCE` (10 m: no C-arm
    reaches farther from its table), or ``error``; beyond it the message names the likely unit slip
    (``(0, -100, 0)`` for 100 mm above the origin: "given in mm? 100 mm = 0.1 m")."""
    point = real_array(value, name, (3,), error=error, unit="m")
    far = float(np.abs(point).max())
    if far > MAX_DISTANCE:
        raise error(f"{name} must lie within {MAX_DISTANCE:g} m of the table frame's origin along each axis, got "
                    f"{point.tolist()} m{unit_slip(far, 0.0, MAX_DISTANCE, 'm')}")
    return point


def joint_index(value, name: str, nq: int, *, names: Sequence[str] | None = None,
                error: type[CarmkinError] = InvalidParameterError) -> int:
    """``value`` as a joint index ``0 <= i < nq``: an integer (no bool, no float, no negative alias) or, with
    ``names``, one of the joint names. Else ``error`` naming the valid range (and names)."""
    choices = f"an integer in [0, {nq - 1}]" + (f" or one of {', '.join(names)}" if names else "")
    if isinstance(value, str) and names is not None:
        if value in names:
            return list(names).index(value)
        raise error(f"{name} must be {choices}, got {value!r}")
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or not 0 <= value < nq:
        raise error(f"{name} must be {choices}, got {_describe(value)}")
    return int(value)


def integer(value, name: str, *, low: int | None = None, high: int | None = None,
            error: type[CarmkinError] = InvalidParameterError, unit: str = "") -> int:
    """``value`` as a Python int within [``low``, ``high``] (a count, a size in pixels, a seed), or ``error``.

    An ``int`` or numpy integer only: no bool, no float (``2.0`` is refused, never truncated), no string.
    """
    unit_text = f" {unit}" if unit else ""
    bounds = f" in [{'-inf' if low is None else low}, {'inf' if high is None else high}]{unit_text}"
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer))
            or (low is not None and value < low) or (high is not None and value > high)):
        raise error(f"{name} must be an integer{bounds}, got {_describe(value)}")
    return int(value)


def sequence_length(value) -> int | None:
    """The number of items of a sequence (list, tuple, 1-d or larger array); ``None`` for a string, bytes, a
    dict, a scalar or a 0-d array — whose ``len()`` would raise TypeError or count characters or keys (issue 41:
    a 0-d string array, a complex number or a dict as a size)."""
    if isinstance(value, (str, bytes, dict)):
        return None
    try:
        return len(value)
    except TypeError:
        return None


def flag(value, name: str, *, error: type[CarmkinError] = InvalidParameterError) -> bool:
    """``value`` as a bool when it is True or False (Python or numpy), else ``error`` naming ``name``: a string
    ``"False"`` would read as True, None or a number as a guess."""
    if not isinstance(value, (bool, np.bool_)):
        raise error(f"{name} must be True or False, got {_describe(value)}")
    return bool(value)


def instance(value, kind: type, name: str, *, error: type[CarmkinError] = InvalidParameterError,
             hint: str = ""):
    """``value`` when it is a ``kind`` (e.g. a :class:`carmkin.CArmSystem`), else ``error`` naming ``name``."""
    if not isinstance(value, kind):
        raise error(f"{name} must be a {kind.__module__}.{kind.__qualname__}{f' ({hint})' if hint else ''}, "
                    f"got {_describe(value)}")
    return value


def frozen_instance(cls, values: dict):
    """An instance of the frozen dataclass ``cls`` holding ``values`` (its instance dictionary: every field by
    name, a field stored by a descriptor under the descriptor's own key) without running the generated
    ``__init__``, whose one ``object.__setattr__`` per field is the cost of a scalar solve's results. Only
    for dataclasses without ``__post_init__`` or ``__slots__``, from values already of their fields' types."""
    instance = object.__new__(cls)
    instance.__dict__.update(values)
    return instance
