"""Target poses at the IK's door: rigid ones as they are, nearly rigid ones projected, the rest refused.

A pose rounded by a user (4 decimals) or stored as float32 is rigid only to ~1e-5 or ~1e-7, far above
:data:`~carmkin.validation.RIGID_TOLERANCE` (1e-9). Such a pose, within
:data:`~carmkin.transforms.NEARLY_RIGID_TOLERANCE` of a rigid transform, is replaced by the nearest rigid
transform (:func:`carmkin.transforms.nearest_rigid`: rotation block by its SVD, last row [0, 0, 0, 1],
translation kept) and the correction ``‖T_rigid − T‖_F`` (dimensionless) is reported on the result; a
matrix farther from rigid is refused with an :class:`~carmkin.errors.InvalidPoseError` that names
``carmkin.transforms.nearest_rigid``. The rigidity test of a pose already rigid is written out on plain
floats (the generic check spends its time in small matrix products: the speed of the closed form).
"""

from __future__ import annotations

import math

import numpy as np

from carmkin.errors import InvalidPoseError
from carmkin.transforms import NEARLY_RIGID_TOLERANCE, check_rigid_transform, nearest_rigid
from carmkin.validation import MAGNITUDE_LIMIT, RIGID_TOLERANCE, real_array, rigidity

#: The native float64 dtype (a singleton: the fast path compares by identity) and a rigid pose's last row.
FLOAT64 = np.dtype(np.float64)
LAST_ROW = [0.0, 0.0, 0.0, 1.0]


def project(T, name: str, batch: bool = False):
    """``(T_rigid, correction)`` for a pose that failed the rigid check: the nearest rigid transform when
    ``T`` is nearly rigid (``correction``: float, or (N,) with ``batch``), else the typed error naming
    :func:`carmkin.transforms.nearest_rigid`. Shape, type and NaN errors are those of the rigid check."""
    array = real_array(T, name, error=InvalidPoseError, unit="m")
    expected = 3 if batch else 2
    if array.ndim != expected or array.shape[-2:] != (4, 4):
        check_rigid_transform(T, name, batch=batch)  # raises the shape error
    try:
        rigid, correction = nearest_rigid(array, name)
    except InvalidPoseError as exc:
        raise InvalidPoseError(
            f"{exc}; only a pose within carmkin.transforms.NEARLY_RIGID_TOLERANCE = {NEARLY_RIGID_TOLERANCE:g} "
            "of a rigid transform is projected (carmkin.transforms.nearest_rigid): pass a rigid 4x4 pose") from None
    return check_rigid_transform(rigid, name, batch=batch), correction


def pose_rows(T, name: str = "T"):
    """``(T (4, 4) float, rows as nested lists, correction)`` of a rigid or nearly rigid pose (see above)."""
    if type(T) is not np.ndarray or T.shape != (4, 4) or T.dtype is not FLOAT64:
        T = real_array(T, name, error=InvalidPoseError, unit="m")
        if T.shape != (4, 4):
            check_rigid_transform(T, name)  # raises the shape error
    rows = T.tolist()
    (a, b, c, px), (d, e, f, py), (g, h, i, pz), last = rows
    ok = (math.isfinite(a + b + c + d + e + f + g + h + i) and last == LAST_ROW
          and abs(px) <= MAGNITUDE_LIMIT and abs(py) <= MAGNITUDE_LIMIT and abs(pz) <= MAGNITUDE_LIMIT)
    # each comparison separately: NaN fails it (max(0.6, nan) is 0.6 and would let a NaN translation through)
    if ok:
        ortho, det = rigidity(a, b, c, d, e, f, g, h, i)
        ok = ortho <= RIGID_TOLERANCE * RIGID_TOLERANCE and abs(det - 1.0) <= RIGID_TOLERANCE
    if ok:
        return T, rows, 0.0
    try:
        return check_rigid_transform(T, name), rows, 0.0
    except InvalidPoseError:
        rigid, correction = project(T, name)
        return rigid, rigid.tolist(), correction


def pose_target(T, name: str = "target") -> tuple[np.ndarray, float]:
    """``(T (4, 4), correction)``: :func:`pose_rows` without the rows."""
    T, _, correction = pose_rows(T, name)
    return T, correction


def pose_batch(T, name: str = "Ts") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(T (N, 4, 4), rows (16, N) row-major entries, correction (N,))`` of rigid or nearly rigid poses:
    the tests of :func:`check_rigid_transform` element-wise on the rows, the nearly rigid ones projected."""
    if not isinstance(T, np.ndarray) or T.ndim != 3 or T.shape[1:] != (4, 4) or T.dtype != np.float64:
        T = real_array(T, name, error=InvalidPoseError, unit="m")
        if T.ndim != 3 or T.shape[1:] != (4, 4):
            check_rigid_transform(T, name, batch=True)  # raises the shape error
    rows = np.ascontiguousarray(T.reshape(len(T), 16).T)
    a, b, c, px, d, e, f, py, g, h, i, pz, l0, l1, l2, l3 = rows
    with np.errstate(invalid="ignore", over="ignore"):  # non-finite or huge entries fail `ok` below
        ortho, det = rigidity(a, b, c, d, e, f, g, h, i)
    tol = RIGID_TOLERANCE
    ok = (ortho <= tol * tol) & (np.abs(det - 1.0) <= tol) & (np.abs(l3 - 1.0) <= tol)
    ok &= (np.abs(l0) <= tol) & (np.abs(l1) <= tol) & (np.abs(l2) <= tol)
    ok &= (np.abs(px) <= MAGNITUDE_LIMIT) & (np.abs(py) <= MAGNITUDE_LIMIT) & (np.abs(pz) <= MAGNITUDE_LIMIT)
    correction = np.zeros(len(T))
    if not ok.all():  # NaN fails every comparison above
        bad = np.flatnonzero(~ok)
        T = T.copy()
        T[bad], correction[bad] = project(T[bad], name, batch=True)
        rows = np.ascontiguousarray(T.reshape(len(T), 16).T)
    return T, rows, correction
