"""`identify`: the kinematic and imaging parameters of a C-arm from joint readings and measured projection
matrices, by nonlinear least squares on the reprojection residual (scipy).

Residual (px): for view i and reference point X_k (:mod:`.reprojection`),
``r_ik = π(P̂_i(θ) X_k) − π(P_i X_k)``, the modelled minus the measured pixel, ``π`` the perspective division;
``P̂_i(θ)`` is the calibrated model's projection matrix at the joint readings ``q_i`` (readings + zero offsets
through the FK, the detector's rotation and sag). Only the parameters the views determine are fitted
(:mod:`.identifiability`); the others stay at their nominal values and are reported as unidentifiable.

Covariance: ``s² (JᵀJ)⁻¹`` at the solution (J in px per mm, deg or px). A measured projection matrix has 11
degrees of freedom, so however many reference points a view has, the N views give ``11 N`` independent
numbers and ``s² = Σ r² / (11 N − p)`` for p fitted parameters. When P was estimated from pixels with
independent noise of σ px at the reference points themselves, ``s ≈ σ`` and the RMS of r per coordinate is
``σ √((11 N − p) / (2 M N))`` (M points per view): the residual is smaller than the noise by this known factor.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass

import numpy as np

from carmkin.errors import CalibrationError, InvalidParameterError
from carmkin.model.system import CArmSystem, require_system
from carmkin.validation import projection_matrix, real_array

from . import quantities as params
from .identifiability import Identifiability, analyse
from .reprojection import model_projections, pixels, reference_points

#: Independent numbers in one measured projection matrix (3 × 4 up to scale).
NUMBERS_PER_VIEW = 11
#: Fewest reference points per view: 6 points in general position fix the 11 numbers of a P.
MIN_POINTS = 6
#: Step of the central-difference Jacobian, in each parameter's unit (mm, deg, px): 1e-4. Its truncation error
#: is ~1e-8 relative (the residual's curvature over 1e-4 mm or deg), its round-off ~1e-12 px per unit.
JACOBIAN_STEP = 1e-4
#: scipy.optimize.least_squares's ftol, xtol and gtol: 1e-12, far below the 0.1 px noise of a real P.
FIT_TOLERANCE = 1e-12


@dataclass(frozen=True)
class CalibrationResult:
    """What :func:`identify` found. Values are in people's units: each parameter's (mm, deg, px).

    Attributes:
        system: the calibrated :class:`~carmkin.model.system.CArmSystem` (the held parameters nominal).
        nominal: the system the fit started from.
        names: the fitted parameters, in priority order. units: their units.
        values: their estimates; nominal_values: their values in ``nominal``; std: their standard deviations.
        covariance: (p, p) ``s² (JᵀJ)⁻¹`` in units² of the parameters.
        unidentifiable: names of the parameters held at nominal (see ``identifiability.held`` for the reasons).
        identifiability: the :class:`~carmkin.calibration.identifiability.Identifiability` report.
        residual_px: (N,) per view, the RMS over its reference points of the pixel distance, after the fit.
        residual_before_px: (N,) the same for the nominal system.
        noise_px: s, the noise the residual implies (px, see the module docstring); dof: 11 N − p.
        success, message: scipy's.
    """

    system: CArmSystem
    nominal: CArmSystem
    names: tuple[str, ...]
    units: tuple[str, ...]
    values: np.ndarray
    nominal_values: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    unidentifiable: tuple[str, ...]
    identifiability: Identifiability
    residual_px: np.ndarray
    residual_before_px: np.ndarray
    noise_px: float
    dof: int
    success: bool
    message: str

    def estimate(self, name: str) -> tuple[float, float]:
        """``(value, standard deviation)`` of a fitted parameter, or CalibrationError saying why there is none."""
        if name in self.names:
            i = self.names.index(name)
            return float(self.values[i]), float(self.std[i])
        if name in self.unidentifiable:
            raise CalibrationError(f"{name} is not identifiable from these views: held at its nominal value")
        hint = difflib.get_close_matches(str(name), list(self.names), n=1)
        raise CalibrationError(f"no parameter {name!r} was fitted" + (f"; did you mean {hint[0]!r}?" if hint else ""))

    def report(self) -> str:
        """The result for people (mm, deg, px), one line per parameter and per held parameter."""
        from .report import render

        return render(self)

    def save_preset(self, path):
        """Write the calibrated system as a preset file (TOML) that :func:`carmkin.load_preset` reads back; each
        fitted value's comment gives its standard deviation (see :mod:`.output`)."""
        from .output import save_calibrated_preset

        return save_calibrated_preset(self, path)


def identify(system, q, P, points=None, parameters=None) -> CalibrationResult:
    """Calibrate ``system`` from joint readings ``q`` (N, nq) (m, rad) and measured projection matrices
    ``P`` (N, 3, 4) (table-frame m to px, any scale per view).

    ``points``: the reference points of the residual, (M, 3) for every view or (N, M, 3) per view (m, table
    frame); default :func:`~carmkin.calibration.reprojection.reference_points`. ``parameters``: the names to
    fit (default every one of :func:`~carmkin.calibration.quantities.parameters`); the views decide which of
    them are identifiable.

    Raises :class:`~carmkin.errors.CalibrationError` naming the field: q or P not finite or mis-shaped, their
    counts different, a P not of rank 3 or with a reference point behind its source, a reading outside its
    joint's range, fewer than :data:`MIN_POINTS` reference points, or fewer numbers than parameters
    (``11 N <= p``: at least ``p // 11 + 1`` views).
    """
    from scipy.optimize import least_squares

    require_system(system, CalibrationError)
    readings, measured, X, chosen = _checked(system, q, P, points, parameters)
    observed = pixels(measured, X)
    nominal = params.values(system, chosen)

    def residual(subset, x):
        try:
            candidate = params.with_values(system, subset, x)
        except InvalidParameterError:  # a trial step beyond a model bound (e.g. a negative SDD): a bad step
            return np.full(observed.size, np.inf)
        with np.errstate(all="ignore"):  # a trial step may put a point at the source: least_squares retreats
            return (pixels(model_projections(candidate, readings), X) - observed).ravel()

    before = _per_view(residual(chosen, nominal), len(readings))
    report = analyse(_jacobian(lambda x: residual(chosen, x), nominal), [p.name for p in chosen])
    free = tuple(p for p in chosen if p.name in report.kept)
    start = params.values(system, free)
    fit = least_squares(lambda x: residual(free, x), start, jac=lambda x: _jacobian(lambda y: residual(free, y), x),
                        method="trf", x_scale="jac", ftol=FIT_TOLERANCE, xtol=FIT_TOLERANCE, gtol=FIT_TOLERANCE)
    J = _jacobian(lambda y: residual(free, y), fit.x)
    dof = NUMBERS_PER_VIEW * len(readings) - len(free)
    s2 = float(fit.fun @ fit.fun) / dof
    _, sv, Vt = np.linalg.svd(J, full_matrices=False)
    covariance = s2 * (Vt.T / sv**2) @ Vt
    return CalibrationResult(
        system=params.with_values(system, free, fit.x), nominal=system, names=tuple(p.name for p in free),
        units=tuple(p.unit for p in free), values=fit.x, nominal_values=start, std=np.sqrt(np.diag(covariance)),
        covariance=covariance, unidentifiable=report.unidentifiable, identifiability=report,
        residual_px=_per_view(fit.fun, len(readings)), residual_before_px=before, noise_px=float(np.sqrt(s2)),
        dof=dof, success=bool(fit.success), message=str(fit.message))


def _jacobian(fun, x: np.ndarray) -> np.ndarray:
    """Central differences of ``fun`` at ``x`` with :data:`JACOBIAN_STEP` (px per parameter unit)."""
    columns = []
    for j in range(len(x)):
        step = np.zeros(len(x))
        step[j] = JACOBIAN_STEP
        columns.append((fun(x + step) - fun(x - step)) / (2 * JACOBIAN_STEP))
    return np.column_stack(columns)


def _per_view(r: np.ndarray, n: int) -> np.ndarray:
    """RMS over each view's points of the pixel distance, from the flat residual."""
    d = r.reshape(n, -1, 2)
    return np.sqrt(np.mean(np.sum(d**2, axis=2), axis=1))


def _checked(system: CArmSystem, q, P, points, names):
    """The checked readings (N, nq), normalised P (N, 3, 4), points (N, M, 3) and parameters."""
    Q = real_array(q, "q (joint readings)", error=CalibrationError, unit="m, rad")
    if Q.ndim != 2 or Q.shape[1] != system.nq:
        raise CalibrationError(f"q (joint readings) must have shape (N, {system.nq}), one row per view, got {Q.shape}")
    P = real_array(P, "P (measured projection matrices)", error=CalibrationError, limit=None)
    if P.ndim != 3 or P.shape[1:] != (3, 4):
        raise CalibrationError(f"P (measured projection matrices) must have shape (N, 3, 4), got {P.shape}")
    if len(P) != len(Q):
        raise CalibrationError(f"q has {len(Q)} views (rows) but P has {len(P)}: need one projection matrix per "
                               "joint reading")
    _check_ranges(system, Q)
    chosen = params.select(system, names)
    if NUMBERS_PER_VIEW * len(Q) <= len(chosen):
        raise CalibrationError(
            f"q, P: {len(Q)} views give {NUMBERS_PER_VIEW * len(Q)} numbers (11 per projection matrix), not more "
            f"than the {len(chosen)} parameters to fit: need at least {len(chosen) // NUMBERS_PER_VIEW + 1} views")
    if points is None:
        X = reference_points(system, Q)
    else:
        X = real_array(points, "points", error=CalibrationError, unit="m")
        if X.ndim == 2 and X.shape[1] == 3:
            X = np.broadcast_to(X, (len(Q),) + X.shape)
        if X.ndim != 3 or X.shape[0] != len(Q) or X.shape[2] != 3:
            raise CalibrationError(f"points must have shape (M, 3) or ({len(Q)}, M, 3) (m), got {X.shape}")
        if X.shape[1] < MIN_POINTS:
            raise CalibrationError(f"points: need at least {MIN_POINTS} reference points per view, got {X.shape[1]}")
    measured = np.array([projection_matrix(P[i], f"P[{i}]", error=CalibrationError, points=X[i])
                         for i in range(len(P))])
    return Q, measured, np.ascontiguousarray(X), chosen


def _check_ranges(system: CArmSystem, Q: np.ndarray) -> None:
    """CalibrationError naming the first reading outside its joint's range (mm or deg)."""
    for j, (joint_range, prismatic, name) in enumerate(zip(system.joint_ranges, system.prismatic, system.joint_names)):
        outside = ~joint_range.contains(Q[:, j])
        if outside.any():
            i = int(np.argmax(outside))
            scale, unit = (1e3, "mm") if prismatic else (180 / np.pi, "deg")
            raise CalibrationError(
                f"q[{i}, {j}] ({name} reading) = {Q[i, j] * scale:.6g} {unit} is outside the joint's range "
                f"[{joint_range.lower * scale:.6g}, {joint_range.upper * scale:.6g}] {unit}")
