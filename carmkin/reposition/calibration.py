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
"""

from __future__ import annotations

import numpy as np

from carmkin.errors import (
    CalibrationError,  # noqa: F401 (defined there, raised here)
    )
from carmkin.validation import real_array

#: The centred displacements must span a plane: their second singular value must exceed this fraction of
#: the first (translations along a single direction leave the rotation about it undetermined).
SPAN_TOLERANCE = 1e-3
#: A move counts as along one table axis when its other components are below this fraction of its length.
AXIS_TOLERANCE = 1e-6
METHODS = ("svd", "lines")


def _check(positions, displacements) -> tuple[np.ndarray, np.ndarray]:
    P = real_array(positions, "camera_positions_marker", (None, 3), error=CalibrationError, unit="m")
    D = real_array(displacements, "camera_displacements_table", (None, 3), error=CalibrationError, unit="m")
    if D.shape != P.shape:
        raise CalibrationError(f"camera_displacements_table must have shape {P.shape} like the positions, got {D.shape}")
    if len(P) < 3:
        raise CalibrationError(f"calibration needs at least 3 positions (§3.3.3), got {len(P)}")
    s = np.linalg.svd(D - D.mean(axis=0), compute_uv=False)
    if s[0] == 0.0 or s[1] <= SPAN_TOLERANCE * s[0]:
        raise CalibrationError("the table displacements must span at least two directions (§3.3.3: e.g. "
                               "forward-backward and up-down); along one line the rotation about it is unknown")
    return P, D


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
    d = np.linalg.norm(np.asarray(R_a, float).T @ np.asarray(R_b, float) - np.eye(3)) / (2.0 * np.sqrt(2.0))
    return float(2.0 * np.arcsin(min(1.0, d)))


def calibrate_table(camera_positions_marker, camera_displacements_table, method: str = "svd") -> np.ndarray:
    """The rotation ``tRm`` (3, 3) with ``P_table = tRm @ P_marker``.

    ``camera_positions_marker`` (N, 3): the camera positions estimated in the marker frame (m);
    ``camera_displacements_table`` (N, 3): the same positions' displacements from the first, in the table
    frame (m) — the opposite of the known table translations. N ≥ 3, spanning two directions at least.
    ``method``: ``"svd"`` (Kabsch on all displacements) or ``"lines"`` (a line per table axis).
    """
    P, D = _check(camera_positions_marker, camera_displacements_table)
    if method == "svd":
        return _align(D - D.mean(axis=0), P - P.mean(axis=0))
    if method == "lines":
        fitted, axes = _axis_directions(P, D)
        return _align(np.array(axes), np.array(fitted))
    raise CalibrationError(f"method must be one of {METHODS}, got {method!r}")


def residual_rms(tRm, camera_positions_marker, camera_displacements_table) -> float:
    """RMS (m) of ``tRm (p_i − p̄) − (d_i − d̄)`` over the positions: the fit's consistency."""
    P, D = _check(camera_positions_marker, camera_displacements_table)
    r = (P - P.mean(axis=0)) @ np.asarray(tRm, float).T - (D - D.mean(axis=0))
    return float(np.sqrt(np.mean(np.sum(r**2, axis=1))))


def calibration_moves(positions: int, span: float, axes=(2, 1)) -> np.ndarray:
    """Camera displacements (positions, 3) in the table frame for a calibration run: the first position,
    then moves spread evenly up to ``span`` (m) along each of ``axes`` in turn (table-frame axis indices;
    default Z0, the translation, and Y0, the height), each from the first position."""
    if positions < 3:
        raise CalibrationError(f"positions must be >= 3, got {positions}")
    if not (np.isfinite(span) and span > 0):
        raise CalibrationError(f"span must be finite and > 0 (m), got {span}")
    axes = tuple(axes)
    if len(axes) < 2 or any(a not in (0, 1, 2) for a in axes):
        raise CalibrationError(f"axes must name at least two table axes among 0, 1, 2, got {axes!r}")
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

    if int(trials) < 1:
        raise CalibrationError(f"trials must be >= 1, got {trials}")
    rng = np.random.default_rng(seed)
    out = np.zeros((len(noise_levels), len(position_counts), 2))
    for i, sigma in enumerate(noise_levels):
        if not (np.isfinite(sigma) and sigma >= 0):
            raise CalibrationError(f"noise levels must be finite and >= 0 (m), got {sigma}")
        for j, count in enumerate(position_counts):
            moves = calibration_moves(int(count), span, axes)
            errors = []
            for R in Rotation.random(int(trials), random_state=rng).as_matrix():
                measured = moves @ R + rng.normal(0.0, sigma, moves.shape)
                E = calibrate_table(measured, moves, method=method)
                errors.append(rotation_angle(E, R))
            out[i, j] = np.median(errors), np.percentile(errors, 95)
    return out
