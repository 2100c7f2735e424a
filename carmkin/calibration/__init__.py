"""Calibration from measured projection matrices (issue 30): given joint readings and a measured P per view,
identify the C-arm's kinematic and imaging parameters by nonlinear least squares (scipy), with their
covariance, the residual per view and an identifiability report; write the calibrated preset.

>>> result = carmkin.calibration.identify(system, q, P)      # q (N, nq) readings, P (N, 3, 4) table m -> px
>>> result.system, result.covariance, result.residual_px, result.unidentifiable
>>> result.outliers, result.warnings     # views left out; cautions (joints the views do not move, ...)

See docs/calibration.md. Modules: :mod:`.quantities` (the parameter list, units, priority order),
:mod:`.reprojection` (reference points, the residual's pixels), :mod:`.identifiability` (the rule),
:mod:`.fit` (:func:`identify`), :mod:`.simulate` (measured P of a simulated device), :mod:`.report`,
:mod:`.output` (the calibrated preset), :mod:`.files` (phantom and views files for ``carmkin calibrate``).
scipy loads on first use.
"""

from .fit import CalibrationResult, FitWarning, WarningKind, identify
from .identifiability import MIN_SINGULAR_VALUE, Held, Identifiability, Reason
from .quantities import Parameter, adjust, parameters, values
from .reprojection import REFERENCE_CUBE, model_projections, reference_points
from .simulate import EXAMPLE_PERTURBATION, estimate_projection, measured_projections, spread_readings

__all__ = ["EXAMPLE_PERTURBATION", "MIN_SINGULAR_VALUE", "REFERENCE_CUBE", "CalibrationResult", "FitWarning", "Held",
           "Identifiability", "Parameter", "Reason", "adjust", "estimate_projection", "identify",
           "measured_projections", "model_projections", "parameters", "reference_points", "spread_readings",
           "values", "WarningKind"]
