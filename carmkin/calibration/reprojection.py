"""The residual of a calibration: reference points projected by the measured and by the modelled projection
matrices, in pixels.

Reference points (default, :func:`reference_points`): per view, a 3 × 3 × 3 grid filling a cube of
:data:`REFERENCE_CUBE` (200 mm) with its edges along the table frame's axes, centred on the view's nominal
isocentre (the point of the principal axis at the source–isocentre distance ``carm.source_to_orbital_axis``
of the nominal system, at the view's joint readings) — a phantom's worth of points that every view sees in
front of its source. The residual compares two projection matrices there, whether or not a detector of that
size would catch every point.
"""

from __future__ import annotations

import numpy as np

from carmkin.errors import CalibrationError
from carmkin.imaging.projection import projection_matrices
from carmkin.model.system import CArmSystem, require_system
from carmkin.validation import real_array

#: Edge of the cube of default reference points (m): 200 mm, about a calibration phantom around the isocentre.
REFERENCE_CUBE = 0.2
#: Points per edge of the default grid (3 × 3 × 3 = 27 points).
REFERENCE_GRID = 3
#: Fewest reference points per view: 6 points in general position fix the 11 numbers of a P.
MIN_POINTS = 6


def checked_readings(system, readings) -> np.ndarray:
    """``system`` checked and ``readings`` as finite joint readings (N, nq) (m, rad), or
    :class:`~carmkin.errors.CalibrationError` naming the argument."""
    require_system(system, CalibrationError)
    Q = real_array(readings, "q (joint readings)", error=CalibrationError, unit="m, rad")
    if Q.ndim != 2 or Q.shape[1] != system.nq:
        raise CalibrationError(f"q (joint readings) must have shape (N, {system.nq}), one row per view, got {Q.shape}")
    return Q


def model_projections(system: CArmSystem, readings: np.ndarray) -> np.ndarray:
    """Projection matrices (N, 3, 4) of joint readings (N, nq): the model joint values ``readings + zero
    offsets`` through the FK and the calibrated detector (:func:`carmkin.imaging.projection_matrices`)."""
    readings = checked_readings(system, readings)
    return projection_matrices(system, system.calibration.model_joints(readings))


def reference_points(system: CArmSystem, readings: np.ndarray) -> np.ndarray:
    """The default reference points (N, 27, 3) (m, table frame) of joint readings (N, nq)."""
    readings = checked_readings(system, readings)
    T = system.fk(system.calibration.model_joints(readings))
    centres = T[:, :3, 3] + system.carm.source_to_orbital_axis * T[:, :3, 2]
    steps = np.linspace(-REFERENCE_CUBE / 2, REFERENCE_CUBE / 2, REFERENCE_GRID)
    grid = np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), axis=-1).reshape(-1, 3)
    return centres[:, None, :] + grid[None, :, :]


def pixels(P: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Pixels (N, M, 2) of points X (N, M, 3) (m) through projection matrices P (N, 3, 4)."""
    h = np.einsum("nij,nmj->nmi", P[:, :, :3], X) + P[:, None, :, 3]
    return h[..., :2] / h[..., 2:]
