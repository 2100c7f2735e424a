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

**Refusal under corner noise** (issue 31). A camera position estimated from noisy corners scatters by
several millimetres along the line of sight (at 1 px corner noise, 2–4 mm sd at the §3.3.3 working
distance, more when few markers are in view), so a fixed 5 mm tolerance refuses calibrations that the noise
alone explains. With ``covariances`` (the estimator's (N, 3, 3) position covariances, marker frame) a
position is refused only when its discrepancy exceeds the fixed tolerance **and** is improbable under the
covariances: the length test's ``z = (|p_i − p_0| − |d_i − d_0|) / σ`` per position, and, for the fit, the
weighted residual ``rᵀ Σ⁻¹ r`` of all displacements (``Σ``: the positions' covariances, rotated, with the
first position's shared by all) against χ² with 3(N − 1) − 3 degrees of freedom, each at the
false-rejection rate :data:`FALSE_REJECTION`. With covariances ``"svd"`` also weights the fit by them
(Gauss–Newton from the Kabsch rotation, :func:`_weighted_rotation`): the camera's depth is several times
less certain than its lateral position, and the unweighted fit lets that error tilt the rotation. And the
fit is robust to one outlier: when the test refuses all N ≥ 4 positions, the best fit of the N − 1 that
pass is returned (``Calibration.outlier`` names the one left out). Measured at 1.34 px per estimate (3 px
corner noise filtered over five frames) with two markers in view, about one calibration in twenty has a
position tens of millimetres off — a planar pose estimate near its mirror-ambiguity, far outside its
linearised covariance; a real operator would re-measure it.
"""

from __future__ import annotations

import dataclasses
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
#: With the positions' covariances, the probability that the noise they state alone gets a correct
#: calibration refused, per test (one length test per position, one residual test for the fit). 1e-6 —
#: about 4.9 σ for a length, χ² = 49 for the 12 degrees of freedom of six positions' residual — so that a
#: six-position calibration is refused wrongly at most once in 140 000, while a stale pose or a wrong move
#: list (errors of tens of σ) is still refused.
FALSE_REJECTION = 1e-6


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


def _covariances(covariances, n: int) -> np.ndarray | None:
    """The positions' (N, 3, 3) covariances (m², marker frame), checked, or None."""
    if covariances is None:
        return None
    C = real_array(covariances, "covariances", (n, 3, 3), error=CalibrationError, unit="m², marker frame")
    if not np.allclose(C, np.swapaxes(C, 1, 2), rtol=1e-9, atol=1e-18) or np.any(np.linalg.eigvalsh(C)[:, 0] < 0):
        raise CalibrationError("covariances must be symmetric positive semi-definite (3, 3) matrices (m²), one per position")
    return C


def _difference_covariances(C: np.ndarray) -> np.ndarray:
    """Covariances (N, 3, 3) of ``p_i − p_0`` (the first row: zero)."""
    out = C + C[0]
    out[0] = 0.0
    return out


def _explained(values: np.ndarray, variances: np.ndarray, dof: int) -> np.ndarray:
    """Which squared-normalised discrepancies ``values`` (N,) with ``variances`` (N,) the noise explains at
    :data:`FALSE_REJECTION` (χ² with ``dof`` degrees of freedom)."""
    from scipy.stats import chi2

    limit = chi2.isf(FALSE_REJECTION, dof)
    with np.errstate(divide="ignore", invalid="ignore"):
        statistic = np.where(variances > 0, values / np.where(variances > 0, variances, 1.0), np.inf)
    return (statistic <= limit) | (values == 0)


def _stacked(tRm: np.ndarray, P: np.ndarray, D: np.ndarray, C: np.ndarray):
    """Residuals ``tRm (p_i − p_0) − (d_i − d_0)`` (3(N−1),) for i ≥ 1, their covariance (table frame: the
    positions' own plus the shared first position's) and the Jacobian of the residuals in ``ω`` of
    ``exp([ω]) tRm``."""
    n = len(P) - 1
    a = (P[1:] - P[0]) @ tRm.T
    r = (a - (D[1:] - D[0])).ravel()
    Ct = tRm @ C @ tRm.T
    S = np.kron(np.ones((n, n)), Ct[0])
    for i in range(n):
        S[3 * i:3 * i + 3, 3 * i:3 * i + 3] += Ct[i + 1]
    J = np.concatenate([-np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]]) for v in a])
    return r, S, J


def _weighted_ssr(tRm, P, D, C) -> tuple[float, int]:
    """``rᵀ Σ⁻¹ r`` of :func:`_stacked` and its degrees of freedom, 3(N − 1) − 3 (the fitted rotation)."""
    r, S, _ = _stacked(tRm, P, D, C)
    return float(r @ np.linalg.pinv(S, hermitian=True) @ r), max(len(r) - 3, 1)


#: Gauss–Newton steps of the covariance-weighted rotation fit from the Kabsch start (it converges in two or
#: three at calibration noise; a step below 1e-12 rad stops it).
WEIGHTED_STEPS = 10


def _weighted_rotation(tRm, P, D, C) -> np.ndarray:
    """The rotation minimising ``rᵀ Σ⁻¹ r`` (:func:`_stacked`), by Gauss–Newton from ``tRm``: the Kabsch fit
    weights every coordinate alike, while a camera position is several times less certain along the line of
    sight than across it."""
    from scipy.spatial.transform import Rotation

    for _ in range(WEIGHTED_STEPS):
        r, S, J = _stacked(tRm, P, D, C)
        W = np.linalg.pinv(S, hermitian=True)
        step = np.linalg.lstsq(J.T @ W @ J, -J.T @ W @ r, rcond=None)[0]
        tRm = Rotation.from_rotvec(step).as_matrix() @ tRm
        if np.linalg.norm(step) < 1e-12:
            break
    return tRm


def _check_seen(P: np.ndarray, D: np.ndarray, tolerance: float, C: np.ndarray | None = None) -> None:
    """The camera saw the commanded moves: its displacements span two directions and match in length."""
    s = np.linalg.svd(P - P.mean(axis=0), compute_uv=False)
    if s[0] == 0.0 or s[1] <= SPAN_TOLERANCE * s[0]:
        raise CalibrationError("camera_positions_marker do not span two directions: the camera saw the marker "
                               f"{'still' if s[0] == 0.0 else 'move along one line only'} while the table moved "
                               "along two (a marker out of view, a stale pose?)")
    measured = np.linalg.norm(P - P[0], axis=1)
    commanded = np.linalg.norm(D - D[0], axis=1)
    excess = np.abs(measured - commanded) - _tolerance(D, tolerance)
    noise = ""
    if C is not None:
        direction = (P - P[0]) / np.maximum(measured, 1e-300)[:, None]
        variance = np.einsum("ni,nij,nj->n", direction, _difference_covariances(C), direction)
        excess = np.where(_explained((measured - commanded) ** 2, variance, 1), -1.0, excess)
        noise = " and beyond its noise"
    if np.any(excess > 0):
        i = int(np.argmax(excess))
        raise CalibrationError(f"camera_positions_marker[{i}] moved {1e3 * measured[i]:.2f} mm from the first "
                               f"position where the table was moved {1e3 * commanded[i]:.2f} mm (tolerance "
                               f"{1e3 * _tolerance(D, tolerance)[i]:.2f} mm{noise}): the camera did not see the "
                               "commanded move (a still marker, a wrong pose or a wrong move list)")


@dataclass(frozen=True)
class Calibration:
    """Result of :func:`calibrate`: ``tRm`` (3, 3) with ``P_table = tRm @ P_marker``; ``residuals`` (N, 3) m:
    ``tRm (p_i − p_0) − (d_i − d_0)`` in the table frame; ``rms`` (m) of their norms; ``outlier``: the index
    of the one position left out by the robust fit (:data:`FALSE_REJECTION`), else None — the residuals are
    then those of the other positions (relative to the first of them)."""

    tRm: np.ndarray
    residuals: np.ndarray
    rms: float
    outlier: int | None = None


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
              tolerance: float = LENGTH_TOLERANCE, covariances=None) -> Calibration:
    """The rotation ``tRm`` with its residuals (:class:`Calibration`), or :class:`CalibrationError`.

    ``camera_positions_marker`` (N, 3): the camera positions estimated in the marker frame (m);
    ``camera_displacements_table`` (N, 3): the same positions' displacements from the first, in the table
    frame (m) — the opposite of the known table translations. N ≥ 3, both spanning two directions at least,
    matching in length and, after the rotation, in direction to ``tolerance`` (m) + :data:`LENGTH_RELATIVE`
    of each move. ``method``: ``"svd"`` (Kabsch on all displacements) or ``"lines"`` (a line per table axis).
    ``covariances`` (N, 3, 3) m², marker frame: the estimator's covariances of the positions; with them a
    position is refused only when its noise cannot explain it either (module docstring, :data:`FALSE_REJECTION`).
    """
    P, D = _check(camera_positions_marker, camera_displacements_table)
    tolerance = real_scalar(tolerance, "tolerance", error=CalibrationError, low=0.0, unit="m")
    if not isinstance(method, str) or method not in METHODS:
        raise CalibrationError(f"method must be one of {METHODS}, got {method!r}")
    C = _covariances(covariances, len(P))
    try:
        return _fit(P, D, tolerance, method, C)
    except CalibrationError as first:
        if C is None or len(P) < 4:
            raise
        kept = []  # robust: the one position whose removal leaves a fit its noise explains, the best such
        for i in range(len(P)):
            keep = np.arange(len(P)) != i
            try:
                _check(P[keep], D[keep])
                fit = _fit(P[keep], D[keep], tolerance, method, C[keep])
            except CalibrationError:
                continue
            kept.append((_weighted_ssr(fit.tRm, P[keep], D[keep], C[keep])[0], i, fit))
        if not kept:
            raise first from None
        _, i, fit = min(kept, key=lambda k: k[0])
        return dataclasses.replace(fit, outlier=i)


def _fit(P, D, tolerance: float, method: str, C) -> Calibration:
    """The calibration of all the given positions, or :class:`CalibrationError` (module docstring)."""
    _check_seen(P, D, tolerance, C)
    if method == "svd":
        tRm = _align(D - D.mean(axis=0), P - P.mean(axis=0))
        if C is not None:
            tRm = _weighted_rotation(tRm, P, D, C)
    else:
        fitted, axes = _axis_directions(P, D)
        tRm = _align(np.array(axes), np.array(fitted))
    residuals = (P - P[0]) @ tRm.T - (D - D[0])
    norms = np.linalg.norm(residuals, axis=1)
    excess = norms - _tolerance(D, tolerance)
    noise = ""
    if C is not None:
        ssr, dof = _weighted_ssr(tRm, P, D, C)
        if _explained(np.array([ssr]), np.ones(1), dof)[0]:
            excess = np.full_like(excess, -1.0)
        noise = f" and beyond its noise: weighted residual {ssr:.1f} for {dof} degrees of freedom"
    if np.any(excess > 0):
        i = int(np.argmax(excess))
        raise CalibrationError(f"no rotation maps the camera's displacements onto the table's: position {i} is "
                               f"{1e3 * norms[i]:.2f} mm off after the fit (tolerance "
                               f"{1e3 * _tolerance(D, tolerance)[i]:.2f} mm{noise})")
    return Calibration(tRm, residuals, float(np.sqrt(np.mean(norms**2))))


def calibrate_table(camera_positions_marker, camera_displacements_table, method: str = "svd",
                    tolerance: float = LENGTH_TOLERANCE, covariances=None) -> np.ndarray:
    """The rotation ``tRm`` (3, 3) with ``P_table = tRm @ P_marker``: :func:`calibrate`'s, without the
    residuals (same arguments, same refusals)."""
    return calibrate(camera_positions_marker, camera_displacements_table, method, tolerance, covariances).tRm


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
