"""`identify`: the kinematic and imaging parameters of a C-arm from joint readings and measured projection
matrices, by nonlinear least squares on the reprojection residual (scipy).

Residual (px): for view i and reference point X_k (:mod:`.reprojection`),
``r_ik = π(P̂_i(θ) X_k) − π(P_i X_k)``, the modelled minus the measured pixel, ``π`` the perspective division;
``P̂_i(θ)`` is the calibrated model's projection matrix at the joint readings ``q_i`` (readings + zero offsets
through the FK, the detector's rotation and sag). Only the parameters the views determine are fitted
(:mod:`.identifiability`); the others stay at their nominal values and are reported as unidentifiable.

Outlier views: after each fit, every view's **leave-one-view-out residual** ``e_i = (I − H_ii)⁻¹ r_i`` (the
residual the other views predict for it, to first order; ``H_ii`` its block of the hat matrix ``J (JᵀJ)⁻¹ Jᵀ``)
is compared with the others': a view whose RMS ``e_i`` exceeds :data:`OUTLIER_FACTOR` times the median over
the views (and :data:`OUTLIER_FLOOR_PX`) is named an outlier and the fit is repeated without it, the worst
first, one at a time (``CalibrationResult.outliers``).

Covariance: the larger, in every direction, of two estimates. (1) The model's: ``s² (JᵀJ)⁻¹`` (J in px per
mm, deg or px). A measured projection matrix has 11 degrees of freedom, so however many reference points a
view has, the N views give ``11 N`` independent numbers and ``s² = Σ r² / (11 N − p)`` for p fitted
parameters. It is right when the residual's points are the phantom's own (P estimated from pixels with
independent noise σ at those points): then ``s ≈ σ`` and the RMS of r per coordinate is
``σ √((11 N − p) / (2 M N))`` (M points per view). At other points (the default reference cube and a phantom
of another shape) the noise of P reaches them unevenly and (1) misjudges single parameters. (2) The views':
the leave-one-view-out (jackknife, "CR3") estimate ``Σ_i d_i d_iᵀ``, ``d_i = (JᵀJ)⁻¹ J_iᵀ e_i`` the change
of the estimates when view i is left out: built from the residuals actually fitted, right whatever the phantom,
but it needs many more views than parameters. The reported covariance is ``C1 + (C2 − C1)₊`` (the positive
part of the difference, by eigenvalues): at least each of them.
"""

from __future__ import annotations

import difflib
import enum
from dataclasses import dataclass

import numpy as np

from carmkin.errors import CalibrationError, InvalidParameterError
from carmkin.model.system import CArmSystem, require_system
from carmkin.validation import flag, projection_matrix, real_array

from . import quantities as params
from .identifiability import Identifiability, analyse
from .reprojection import MIN_POINTS, checked_readings, model_projections, pixels, reference_points

#: Independent numbers in one measured projection matrix (3 × 4 up to scale).
NUMBERS_PER_VIEW = 11
#: Step of the central-difference Jacobian, in each parameter's unit (mm, deg, px): 1e-4. Its truncation error
#: is ~1e-8 relative (the residual's curvature over 1e-4 mm or deg), its round-off ~1e-12 px per unit.
JACOBIAN_STEP = 1e-4
#: scipy.optimize.least_squares's ftol, xtol and gtol: 1e-12, far below the 0.1 px noise of a real P.
FIT_TOLERANCE = 1e-12
#: A view is an outlier when the RMS of its leave-one-view-out residual exceeds 5 times the median over the
#: views (25 times in squares). For clean views the squared RMS scatters like a chi-square with up to 11
#: degrees of freedom (the numbers of one P), whose 1e-5 quantile is 4.2 times its median; even with a single
#: effective degree of freedom (all of a view's noise along one direction) 25 times the median (11.4) is
#: exceeded with probability 7e-4. A 20 px error against 0.1 px noise is 200 times the median in RMS.
OUTLIER_FACTOR = 5.0
#: No view is an outlier below this RMS leave-one-view-out residual (px): 0.01 px, a thirtieth of the best
#: measured P's reprojection error (0.33 px, Table 2.1), so that noise-free views are never flagged on round-off.
OUTLIER_FLOOR_PX = 0.01
#: A joint counts as exercised when its readings span at least this fraction of its range (25 %); otherwise
#: the calibration is a fit at that joint's position and ``CalibrationResult.warnings`` names it.
EXERCISED_FRACTION = 0.25
#: The outlier test runs when the views but one still give at least twice as many numbers as parameters
#: (``11 (N − 1) >= 2 p``); with fewer, each view's leave-one-out residual is too uncertain to judge.
OUTLIER_TEST_REDUNDANCY = 2.0
#: Eigenvalues of ``I − H_ii`` below this are a view the others cannot predict at all (its direction is its
#: alone): left out of its leave-one-out residual (pseudo-inverse).
LEVERAGE_TOLERANCE = 1e-9


class WarningKind(enum.Enum):
    """What a :class:`FitWarning` is about."""

    OUTLIER_VIEWS = "outlier views"
    JOINTS_NOT_EXERCISED = "joints not exercised"
    OUTLIERS_NOT_TESTED = "outliers not tested"


@dataclass(frozen=True)
class FitWarning:
    """A caution attached to a :class:`CalibrationResult` (never a Python warning): ``kind``
    (:class:`WarningKind`), ``names`` (the views' indices as text, or the joints' names) and ``message``."""

    kind: WarningKind
    names: tuple[str, ...]
    message: str


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
        noise_px: s, the noise the residual implies (px, see the module docstring); dof: 11 N − p (N the views
            fitted, outliers left out).
        success, message: scipy's.
        outliers: indices of the views left out as outliers (their ``residual_px`` is against the final fit).
        warnings: :class:`FitWarning` s: outliers left out, joints the views do not move, outliers not tested.
        covariance_model, covariance_views: the two estimates ``covariance`` is the larger of (module docstring):
            ``s² (JᵀJ)⁻¹`` and the leave-one-view-out (jackknife) one.
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
    outliers: tuple[int, ...] = ()
    warnings: tuple[FitWarning, ...] = ()
    covariance_model: np.ndarray | None = None
    covariance_views: np.ndarray | None = None

    def estimate(self, name: str) -> tuple[float, float]:
        """``(value, standard deviation)`` of a fitted parameter, or CalibrationError saying why there is none."""
        if name in self.names:
            i = self.names.index(name)
            return float(self.values[i]), float(self.std[i])
        if name in self.unidentifiable:
            raise CalibrationError(f"{name} is not identifiable from these views: held at its nominal value")
        hint = difflib.get_close_matches(str(name), list(self.names), n=1)
        raise CalibrationError(f"no parameter {name!r} was fitted" + (f"; did you mean {hint[0]!r}?" if hint else ""))

    def report(self, view_names=None) -> str:
        """The result for people (mm, deg, px), one line per parameter and per held parameter; outlier views
        named by ``view_names`` (a name per view of ``q``) when given, else by index."""
        from .report import render

        if view_names is not None and (isinstance(view_names, str) or not hasattr(view_names, "__len__")
                                       or len(view_names) != len(self.residual_px)):
            raise CalibrationError(f"view_names must name each of the {len(self.residual_px)} views, got "
                                   f"{view_names!r:.80}")
        return render(self, None if view_names is None else [str(v) for v in view_names])

    def save_preset(self, path):
        """Write the calibrated system as a preset file (TOML) that :func:`carmkin.load_preset` reads back; each
        fitted value's comment gives its standard deviation (see :mod:`.output`)."""
        from .output import save_calibrated_preset

        return save_calibrated_preset(self, path)


def identify(system, q, P, points=None, parameters=None, reject_outliers=True) -> CalibrationResult:
    """Calibrate ``system`` from joint readings ``q`` (N, nq) (m, rad) and measured projection matrices
    ``P`` (N, 3, 4) (table-frame m to px, any scale per view).

    ``points``: the reference points of the residual, (M, 3) for every view or (N, M, 3) per view (m, table
    frame); default :func:`~carmkin.calibration.reprojection.reference_points`. Pass the phantom's own points
    when you have them: the model's covariance is then exact (module docstring). ``parameters``: the names to
    fit (default every one of :func:`~carmkin.calibration.quantities.parameters`); the views decide which of
    them are identifiable. ``reject_outliers``: leave out, one at a time, views whose leave-one-view-out
    residual is an outlier (:data:`OUTLIER_FACTOR`), naming them in ``outliers``.

    Raises :class:`~carmkin.errors.CalibrationError` naming the field: q or P not finite or mis-shaped, their
    counts different, a P not of rank 3 or with a reference point behind its source, a reading outside its
    joint's range, fewer than :data:`MIN_POINTS` reference points, or fewer numbers than parameters
    (``11 N <= p``: at least ``p // 11 + 1`` views); and when the fit runs a parameter to the model's bound
    (the views do not determine it), naming it.
    """
    from scipy.optimize import least_squares

    require_system(system, CalibrationError)
    reject_outliers = flag(reject_outliers, "reject_outliers", error=CalibrationError)
    readings, measured, X, chosen = _checked(system, q, P, points, parameters)
    observed = pixels(measured, X)
    n_views = len(readings)
    per_view = observed[0].size

    def residual(subset, x, views):
        try:
            candidate = params.with_values(system, subset, x)
        except InvalidParameterError:  # a trial step beyond a model bound (e.g. a negative SDD): a bad step
            return np.full(len(views) * per_view, np.inf)
        with np.errstate(all="ignore"):  # a trial step may put a point at the source: least_squares retreats
            return (pixels(model_projections(candidate, readings[views]), X[views]) - observed[views]).ravel()

    every = np.arange(n_views)
    nominal = params.values(system, chosen)
    before = _per_view(residual(chosen, nominal, every), n_views)
    views, outliers = every, []
    while True:
        report = analyse(_jacobian(lambda x: residual(chosen, x, views), nominal), [p.name for p in chosen])
        free = tuple(p for p in chosen if p.name in report.kept)
        start = params.values(system, free)

        def fun(x, free=free, views=views):
            return residual(free, x, views)

        try:
            with np.errstate(all="ignore"):  # scipy's own products of a rejected (infinite) trial step
                fit = least_squares(fun, start, jac=lambda x: _jacobian(fun, x), method="trf", x_scale="jac",
                                    ftol=FIT_TOLERANCE, xtol=FIT_TOLERANCE, gtol=FIT_TOLERANCE)
        except (ValueError, np.linalg.LinAlgError) as exc:  # pragma: no cover - _jacobian keeps scipy's input finite
            raise CalibrationError(f"q, P: the fit failed ({exc}); the views do not determine the parameters "
                                   f"{', '.join(p.name for p in free)} together") from exc
        _check_bounds(free, fit.x, start, fun)
        J = _jacobian(fun, fit.x)
        deleted, shifts = _leave_one_out(J, fit.fun, len(views))
        testable = NUMBERS_PER_VIEW * (len(views) - 1) >= OUTLIER_TEST_REDUNDANCY * len(free)
        if not (reject_outliers and testable and len(outliers) < (n_views - 1) // 2):
            break
        rms = np.sqrt(np.mean(deleted**2, axis=1))
        worst = int(np.argmax(rms))
        if rms[worst] <= max(OUTLIER_FACTOR * np.median(rms), OUTLIER_FLOOR_PX):
            break
        outliers.append(int(views[worst]))
        views = np.delete(views, worst)
    dof = NUMBERS_PER_VIEW * len(views) - len(free)
    s2 = float(fit.fun @ fit.fun) / dof
    _, sv, Vt = np.linalg.svd(J, full_matrices=False)
    model, by_views = s2 * (Vt.T / sv**2) @ Vt, shifts.T @ shifts
    covariance = _larger(model, by_views)
    calibrated = params.with_values(system, free, fit.x)
    after = _per_view(residual(free, fit.x, every), n_views)
    warnings = _warnings(system, readings, outliers, after, reject_outliers and not testable and not outliers)
    return CalibrationResult(
        system=calibrated, nominal=system, names=tuple(p.name for p in free),
        units=tuple(p.unit for p in free), values=fit.x, nominal_values=start, std=np.sqrt(np.diag(covariance)),
        covariance=covariance, unidentifiable=report.unidentifiable, identifiability=report,
        residual_px=after, residual_before_px=before, noise_px=float(np.sqrt(s2)),
        dof=dof, success=bool(fit.success), message=str(fit.message), outliers=tuple(outliers), warnings=warnings,
        covariance_model=model, covariance_views=by_views)


def _leave_one_out(J: np.ndarray, r: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per view, the leave-one-view-out residual ``e_i = (I − H_ii)⁻¹ r_i`` (n, m) and the change of the
    estimates ``d_i = (JᵀJ)⁻¹ J_iᵀ e_i`` (n, p) when view i is left out (first order)."""
    _, sv, Vt = np.linalg.svd(J, full_matrices=False)
    A = (Vt.T / sv**2) @ Vt
    rows = J.shape[0] // n
    deleted, shifts = np.empty((n, rows)), np.empty((n, J.shape[1]))
    for i in range(n):
        Ji, ri = J[i * rows:(i + 1) * rows], r[i * rows:(i + 1) * rows]
        w, U = np.linalg.eigh(np.eye(rows) - Ji @ A @ Ji.T)
        inverse = np.where(w > LEVERAGE_TOLERANCE, 1.0 / np.where(w > LEVERAGE_TOLERANCE, w, 1.0), 0.0)
        deleted[i] = U @ (inverse * (U.T @ ri))
        shifts[i] = A @ (Ji.T @ deleted[i])
    return deleted, shifts


def _larger(C1: np.ndarray, C2: np.ndarray) -> np.ndarray:
    """``C1 + (C2 − C1)₊``: C1 plus the positive part of the difference (eigenvalues below zero dropped)."""
    w, U = np.linalg.eigh((C2 - C1 + (C2 - C1).T) / 2)
    return C1 + (U * np.clip(w, 0.0, None)) @ U.T


def _check_bounds(free, x: np.ndarray, start: np.ndarray, fun) -> None:
    """CalibrationError naming the parameters the fit ran to a model bound (a step of :data:`JACOBIAN_STEP`
    either way leaves the model): the views do not determine them."""
    stuck = []
    for j, p in enumerate(free):
        step = np.zeros(len(x))
        step[j] = JACOBIAN_STEP
        if not (np.isfinite(fun(x + step)).all() and np.isfinite(fun(x - step)).all()):
            stuck.append(f"{p.name} = {x[j]:.6g} {p.unit} (nominal {start[j]:.6g} {p.unit})")
    if stuck:
        raise CalibrationError(
            "q, P: the fit ran to the model's bound: " + "; ".join(stuck) + ". These views do not determine it: "
            "add views that move more joints, or leave it out with parameters=[...]")


def _warnings(system, readings: np.ndarray, outliers, after: np.ndarray, untested: bool) -> tuple[FitWarning, ...]:
    """The result's cautions: outliers left out, joints whose readings span less than :data:`EXERCISED_FRACTION`
    of their range, the outlier test not run."""
    found = []
    if outliers:
        found.append(FitWarning(WarningKind.OUTLIER_VIEWS, tuple(str(i) for i in outliers),
                                "views " + ", ".join(f"{i} ({after[i]:.3g} px RMS against the fit)" for i in outliers)
                                + " disagree with the others and were left out of the fit"))
    width = system.upper - system.lower  # a locked joint (zero width) cannot be exercised: never named
    moved = readings.max(axis=0) - readings.min(axis=0)
    still = tuple(name for name, w, m in zip(system.joint_names, width, moved) if w > 0 and m < EXERCISED_FRACTION * w)
    if still:
        found.append(FitWarning(
            WarningKind.JOINTS_NOT_EXERCISED, still,
            f"the views do not move {', '.join(still)} (readings spanning less than {EXERCISED_FRACTION:.0%} of "
            "the range): the fit holds at their positions in these views; elsewhere the parameters it absorbed "
            "may be off by far more than their σ"))
    if untested:
        found.append(FitWarning(WarningKind.OUTLIERS_NOT_TESTED, (),
                                f"{len(readings)} views are too few to test each against the others (need "
                                f"11 (N − 1) >= {OUTLIER_TEST_REDUNDANCY:g} × the fitted parameters)"))
    return tuple(found)


def _jacobian(fun, x: np.ndarray) -> np.ndarray:
    """Central differences of ``fun`` at ``x`` with :data:`JACOBIAN_STEP` (px per parameter unit); one-sided
    where a step leaves the model (an infinite residual), on the side that stays in it."""
    columns = []
    f0 = None
    for j in range(len(x)):
        step = np.zeros(len(x))
        step[j] = JACOBIAN_STEP
        plus, minus = fun(x + step), fun(x - step)
        if np.isfinite(plus).all() and np.isfinite(minus).all():
            columns.append((plus - minus) / (2 * JACOBIAN_STEP))
            continue
        f0 = fun(x) if f0 is None else f0
        side = plus if np.isfinite(plus).all() else minus
        sign = 1.0 if side is plus else -1.0
        columns.append(sign * (side - f0) / JACOBIAN_STEP if np.isfinite(side).all() else np.zeros_like(f0))
    return np.column_stack(columns)


def _per_view(r: np.ndarray, n: int) -> np.ndarray:
    """RMS over each view's points of the pixel distance, from the flat residual."""
    d = r.reshape(n, -1, 2)
    return np.sqrt(np.mean(np.sum(d**2, axis=2), axis=1))


def _checked(system: CArmSystem, q, P, points, names):
    """The checked readings (N, nq), normalised P (N, 3, 4), points (N, M, 3) and parameters."""
    Q = checked_readings(system, q)
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
