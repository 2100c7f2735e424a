"""Marker→table rotation from table translations (§3.3.3).

The table moves by known translations (along at least two of its axes) while the camera stays still; the
camera positions estimated in the marker frame then move by the opposite translations, which are known in
the table frame. With ``P_table = tRm · P_marker`` for every displacement, ``tRm`` is the rotation that best
maps the marker-frame displacements onto the table-frame ones:

* ``method="svd"`` (the seed's choice, [201, 202]): orthogonal Procrustes (Kabsch) on the displacements
  about their centroids, by SVD — :meth:`scipy.spatial.transform.Rotation.align_vectors`.
* ``method="lines"``: one straight line per table axis, fitted by least squares to the camera positions
  against the known distance along that axis (``p = a + s·u``), then the rotation taking the fitted
  directions ``u`` onto the table axes (again by SVD). Needs each move to be along a single table axis.

Why not hand-eye calibration: with the table only translating, both motions of ``AX = XB`` are pure
translations (``R_A = R_B = I``). The rotation part ``R_A R_X = R_X R_B`` then holds for every ``R_X`` and
carries no information, while the translation part ``R_A t_X + t_A = R_X t_B + t_X`` reduces to
``t_A = R_X t_B``: ``t_X`` cancels and only the rotation is constrained — by exactly the vector alignment
done here. Classic solvers (Tsai–Lenz, Park, Daniilidis; ``cv2.calibrateHandEye``) estimate ``R_X`` from
the rotation axes of the motions, which pure translations do not have, so they are degenerate; the
origin offset of the marker in the table frame is unobservable and is set by convention (the seed puts
the table origin at the marker origin).

**Refusal.** Kabsch returns *a* rotation for any input — the identity, or an arbitrary one, for a marker
that never moved. So the camera's measured displacements ``p_i − p_0`` must (1) span two directions, like
the commanded ones, and (2) match the commanded ``d_i − d_0`` in length, and the fitted rotation must map
one onto the other, each to :data:`LENGTH_TOLERANCE` plus :data:`LENGTH_RELATIVE` of the move; else
:class:`CalibrationError` naming the worst position. :func:`calibrate` returns the residuals with the
rotation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from carmkin.errors import (
    CalibrationError,  # noqa: F401 (defined there, raised here)
    )
from carmkin.validation import distance, point_array, real_array, real_scalar, rotation

#: The centred displacements must span a plane: their second singular value must exceed this fraction of
#: the first (translations along a single direction leave the rotation about it undetermined).
SPAN_TOLERANCE = 1e-3
#: A move counts as along one table axis when its other components are below this fraction of its length.
AXIS_TOLERANCE = 1e-6
METHODS = ("svd", "lines")
#: A measured displacement may differ from the commanded one (in length, and after the fitted rotation) by
#: this much (m) plus :data:`LENGTH_RELATIVE` of the commanded move: 5 mm is five times the camera's
#: position sd across the line of sight at the working distance with 0.2 px corner noise (~1 mm).
LENGTH_TOLERANCE = 0.005
#: The relative part of the tolerance: a 2 % scale error (e.g. a focal length 2 % off) is still accepted.
LENGTH_RELATIVE = 0.02


def _check(positions, displacements) -> tuple[np.ndarray, np.ndarray]:
    P = point_array(positions, "camera_positions_marker", error=CalibrationError, unit="m, marker frame")
    D = point_array(displacements, "camera_displacements_table", error=CalibrationError, unit="m, table frame")
    if D.shape != P.shape:
        raise CalibrationError(f"camera_displacements_table must have shape {P.shape} like the positions, got {D.shape}")
    if len(P) < 3:
        raise CalibrationError(f"calibration needs at least 3 positions (§3.3.3), got {len(P)}")
    s = np.linalg.svd(D - D.mean(axis=0), compute_uv=False)
    if s[0] == 0.0 or s[1] <= SPAN_TOLERANCE * s[0]:
        raise CalibrationError("the table displacements must span at least two directions (§3.3.3: e.g. "
                               "forward-backward and up-down); along one line the rotation about it is unknown")
    return P, D


def _tolerance(D: np.ndarray, tolerance: float) -> np.ndarray:
    return tolerance + LENGTH_RELATIVE * np.linalg.norm(D - D[0], axis=1)


def _check_seen(P: np.ndarray, D: np.ndarray, tolerance: float) -> None:
    """The camera saw the commanded moves: its displacements span two directions and match in length."""
    s = np.linalg.svd(P - P.mean(axis=0), compute_uv=False)
    if s[0] == 0.0 or s[1] <= SPAN_TOLERANCE * s[0]:
        raise CalibrationError("camera_positions_marker do not span two directions: the camera saw the marker "
                               f"{'still' if s[0] == 0.0 else 'move along one line only'} while the table moved "
                               "along two (a marker out of view, a stale pose?)")
    measured = np.linalg.norm(P - P[0], axis=1)
    commanded = np.linalg.norm(D - D[0], axis=1)
    excess = np.abs(measured - commanded) - _tolerance(D, tolerance)
    if np.any(excess > 0):
        i = int(np.argmax(excess))
        raise CalibrationError(f"camera_positions_marker[{i}] moved {1e3 * measured[i]:.2f} mm from the first "
                               f"position where the table was moved {1e3 * commanded[i]:.2f} mm (tolerance "
                               f"{1e3 * _tolerance(D, tolerance)[i]:.2f} mm): the camera did not see the "
                               "commanded move (a still marker, a wrong pose or a wrong move list)")


@dataclass(frozen=True)
class Calibration:
    """Result of :func:`calibrate`: ``tRm`` (3, 3) with ``P_table = tRm @ P_marker``; ``residuals`` (N, 3) m:
    ``tRm (p_i − p_0) − (d_i − d_0)`` in the table frame; ``rms`` (m) of their norms."""

    tRm: np.ndarray
    residuals: np.ndarray
    rms: float


def _align(table_vectors: np.ndarray, marker_vectors: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    rotation, _ = Rotation.align_vectors(table_vectors, marker_vectors)
    return rotation.as_matrix()


def _axis_directions(P: np.ndarray, D: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Fitted directions (marker frame) and the table axes they belong to."""
    length = np.linalg.norm(D, axis=1)
    still = length <= AXIS_TOLERANCE * max(length.max(), 1e-300)
    fitted, axes = [], []
    for k in range(3):
        off_axis = np.linalg.norm(np.delete(D, k, axis=1), axis=1)
        along = ~still & (off_axis <= AXIS_TOLERANCE * length) & (np.abs(D[:, k]) > 0)
        if not along.any():
            continue
        group = along | still
        if np.count_nonzero(group) < 2 or np.ptp(D[group, k]) == 0:
            continue
        s = D[group, k]
        u = ((s - s.mean()) @ (P[group] - P[group].mean(axis=0))) / np.sum((s - s.mean()) ** 2)
        fitted.append(u / np.linalg.norm(u))
        axes.append(np.eye(3)[k])
    moved = ~still
    classified = np.zeros(len(D), bool)
    for k in range(3):
        off_axis = np.linalg.norm(np.delete(D, k, axis=1), axis=1)
        classified |= moved & (off_axis <= AXIS_TOLERANCE * length)
    if not np.all(classified | still):
        raise CalibrationError("method 'lines' needs every table displacement along a single table axis")
    if len(fitted) < 2:
        raise CalibrationError("method 'lines' needs moves along at least two table axes")
    return fitted, axes


def rotation_angle(R_a, R_b) -> float:
    """Angle (rad) of ``R_aᵀ R_b`` from ``||R_aᵀ R_b − I||_F = 2√2 sin(θ/2)``: accurate for tiny angles,
    where ``acos((tr − 1) / 2)`` loses half the digits."""
    R_a, R_b = rotation(R_a, "R_a", error=CalibrationError), rotation(R_b, "R_b", error=CalibrationError)
    d = np.linalg.norm(R_a.T @ R_b - np.eye(3)) / (2.0 * np.sqrt(2.0))
    return float(2.0 * np.arcsin(min(1.0, d)))


def calibrate(camera_positions_marker, camera_displacements_table, method: str = "svd",
              tolerance: float = LENGTH_TOLERANCE) -> Calibration:
    """The rotation ``tRm`` with its residuals (:class:`Calibration`), or :class:`CalibrationError`.

    ``camera_positions_marker`` (N, 3): the camera positions estimated in the marker frame (m);
    ``camera_displacements_table`` (N, 3): the same positions' displacements from the first, in the table
    frame (m) — the opposite of the known table translations. N ≥ 3, both spanning two directions at least,
    matching in length and, after the rotation, in direction to ``tolerance`` (m) + :data:`LENGTH_RELATIVE`
    of each move. ``method``: ``"svd"`` (Kabsch on all displacements) or ``"lines"`` (a line per table axis).
    """
    P, D = _check(camera_positions_marker, camera_displacements_table)
    tolerance = real_scalar(tolerance, "tolerance", error=CalibrationError, low=0.0, unit="m")
    if not isinstance(method, str) or method not in METHODS:
        raise CalibrationError(f"method must be one of {METHODS}, got {method!r}")
    _check_seen(P, D, tolerance)
    if method == "svd":
        tRm = _align(D - D.mean(axis=0), P - P.mean(axis=0))
    else:
        fitted, axes = _axis_directions(P, D)
        tRm = _align(np.array(axes), np.array(fitted))
    residuals = (P - P[0]) @ tRm.T - (D - D[0])
    norms = np.linalg.norm(residuals, axis=1)
    excess = norms - _tolerance(D, tolerance)
    if np.any(excess > 0):
        i = int(np.argmax(excess))
        raise CalibrationError(f"no rotation maps the camera's displacements onto the table's: position {i} is "
                               f"{1e3 * norms[i]:.2f} mm off after the fit (tolerance "
                               f"{1e3 * _tolerance(D, tolerance)[i]:.2f} mm)")
    return Calibration(tRm, residuals, float(np.sqrt(np.mean(norms**2))))


def calibrate_table(camera_positions_marker, camera_displacements_table, method: str = "svd",
                    tolerance: float = LENGTH_TOLERANCE) -> np.ndarray:
    """The rotation ``tRm`` (3, 3) with ``P_table = tRm @ P_marker``: :func:`calibrate`'s, without the
    residuals (same arguments, same refusals)."""
    return calibrate(camera_positions_marker, camera_displacements_table, method, tolerance).tRm


def residual_rms(tRm, camera_positions_marker, camera_displacements_table) -> float:
    """RMS (m) of ``tRm (p_i − p̄) − (d_i − d̄)`` over the positions: the fit's consistency."""
    R = rotation(tRm, "tRm", error=CalibrationError)
    P, D = _check(camera_positions_marker, camera_displacements_table)
    r = (P - P.mean(axis=0)) @ R.T - (D - D.mean(axis=0))
    return float(np.sqrt(np.mean(np.sum(r**2, axis=1))))


def _count(value, name: str, low: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < low:
        raise CalibrationError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


def calibration_moves(positions: int, span: float, axes=(2, 1)) -> np.ndarray:
    """Camera displacements (positions, 3) in the table frame for a calibration run: the first position,
    then moves spread evenly up to ``span`` (m) along each of ``axes`` in turn (table-frame axis indices;
    default Z0, the translation, and Y0, the height), each from the first position."""
    positions = _count(positions, "positions", 3)
    span = distance(span, "span", error=CalibrationError)
    if isinstance(axes, (str, bytes)) or not hasattr(axes, "__iter__"):
        raise CalibrationError(f"axes must name at least two table axes among 0, 1, 2, got {axes!r}")
    axes = tuple(axes)
    if len(axes) < 2 or any(isinstance(a, (bool, np.bool_)) or not isinstance(a, (int, np.integer))
                            or a not in (0, 1, 2) for a in axes) or len(set(axes)) != len(axes):
        raise CalibrationError(f"axes must name at least two different table axes among 0, 1, 2, got {axes!r}")
    moves = np.zeros((positions, 3))
    per_axis = np.array_split(np.arange(1, positions), len(axes))
    for axis, rows in zip(axes, per_axis):
        moves[rows, axis] = span * np.arange(1, len(rows) + 1) / max(len(rows), 1)
    return moves


def error_curve(noise_levels, position_counts, trials: int = 200, span: float = 0.4, axes=(2, 1, 0),
                method: str = "svd", seed: int = 0) -> np.ndarray:
    """Calibration error against position noise and number of positions, by simulation.

    For each noise σ (m, Gaussian on every coordinate of every camera position) and each count N of
    positions (:func:`calibration_moves` with ``span`` and ``axes``), ``trials`` random rotations are
    calibrated; returns (len(noise_levels), len(position_counts), 2): the median and 95th percentile of the
    rotation error (rad).
    """
    from scipy.spatial.transform import Rotation

    trials, seed = _count(trials, "trials", 1), _count(seed, "seed", 0)
    noise_levels = real_array(noise_levels, "noise_levels", (None,), error=CalibrationError, unit="m")
    if np.any(noise_levels < 0):
        raise CalibrationError(f"noise_levels must be >= 0 (m), got {noise_levels.tolist()}")
    if isinstance(position_counts, (str, bytes, dict)) or not hasattr(position_counts, "__iter__"):
        raise CalibrationError(f"position_counts must be a list of integers >= 3, got {position_counts!r}")
    counts = [_count(c, "position_counts[]", 3) for c in position_counts]
    rng = np.random.default_rng(seed)
    out = np.zeros((len(noise_levels), len(counts), 2))
    for i, sigma in enumerate(noise_levels):
        for j, count in enumerate(counts):
            moves = calibration_moves(count, span, axes)
            errors = []
            for R in Rotation.random(trials, random_state=rng).as_matrix():
                measured = moves @ R + rng.normal(0.0, sigma, moves.shape)
                # the simulated noise is the point of the curve: the tolerance grows with it (10 σ)
                E = calibrate_table(measured, moves, method=method, tolerance=LENGTH_TOLERANCE + 10 * sigma)
                errors.append(rotation_angle(E, R))
            out[i, j] = np.median(errors), np.percentile(errors, 95)
    return out
