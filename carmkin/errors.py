"""Typed errors raised by carmkin.

Every error names the offending field or argument, so that a user can fix the input without reading the
source. All derive from :class:`CarmkinError`, itself a :class:`ValueError`.
"""


class CarmkinError(ValueError):
    """Base class of all carmkin input errors."""


class InvalidParameterError(CarmkinError):
    """A geometry, limit or setup value is not acceptable (NaN, negative length, lower > upper, ...)."""


class PresetError(InvalidParameterError):
    """A preset file is malformed: bad TOML, an unknown section or key, a wrong type or value.

    The message names the file, the key and (for a misspelling) the nearest valid name; values are quoted
    in the preset's units (mm, deg).
    """


class UnknownPresetError(PresetError, KeyError):
    """No preset file of that name ships with carmkin (also for an unknown ``base = "..."``)."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


class InvalidConfigurationError(CarmkinError):
    """A joint configuration has the wrong shape or non-finite values."""


class NearSingularSetupError(InvalidParameterError):
    """The table axis is within a small angle of the C-arm's vertical axis (near singular case a)."""


class InvalidPoseError(CarmkinError):
    """A pose is not a 4x4 rigid transform (wrong shape, NaN/Inf, not orthonormal, det != 1)."""


# --- carmkin.extras ------------------------------------------------------------------------------


class MissingExtraError(CarmkinError):
    """An optional dependency (an extra: OpenCV, pydicom, torch/nanodrr/nibabel, ...) is not installed.

    The message names the missing module and the pip command that installs the extra. Attributes:
    ``module`` (the import name), ``extra`` (the name in ``carmkin[...]``).
    """

    def __init__(self, message: str, module: str = "", extra: str = "") -> None:
        super().__init__(message)
        self.module, self.extra = module, extra


# --- carmkin.robot.collision ---------------------------------------------------------------------


class CollisionSceneError(CarmkinError):
    """An obstacle or collision pair is ill-defined (unknown geometry name, bad size, duplicate name)."""


# --- carmkin.analytic_ik -------------------------------------------------------------------------


class AnalyticIKError(CarmkinError):
    """Base class of the errors of the closed-form IK."""


class UnsupportedSystemError(AnalyticIKError):
    """The closed form covers the paper's 6-DOF chain; the system has extra (motorized) table joints."""


class UnsupportedMountError(UnsupportedSystemError):
    """The mount's closed form (:mod:`carmkin.analytic.mount`) needs six revolute joints whose last three axes
    meet in one point and whose second and third are parallel (a KUKA KR 210 class robot); the system has no
    mount or another one (the QP, :func:`carmkin.qp_ik.solve`, solves it)."""


class SingularPoseError(AnalyticIKError):
    """A singular pose that damped least squares could not solve to :data:`NUMERICAL_TOLERANCE`.

    Attributes: ``cases`` (names from :data:`SINGULAR_CASES`), ``residuals`` (per branch, m/rad).
    """

    def __init__(self, message: str, cases: tuple[str, ...], residuals: tuple[float, ...]) -> None:
        super().__init__(message)
        self.cases, self.residuals = cases, residuals


# --- carmkin.analytic.five_dof -------------------------------------------------------------------


class FiveDofTargetError(CarmkinError):
    """A 5-DOF target (source position, principal axis) has the wrong shape, NaN/Inf or a non-unit axis."""


# --- carmkin.analytic.single_axis ----------------------------------------------------------------


class TableIKError(CarmkinError):
    """Bad request to the single-axis closed form (unknown or non-translational active joint)."""


# --- carmkin.analytic.dls ------------------------------------------------------------------------


class NumericalIKError(CarmkinError):
    """Bad input to the damped-least-squares solver (seed shape or values, unknown frame)."""


# --- carmkin.qp.options --------------------------------------------------------------------------


class QPIKError(CarmkinError):
    """Bad input to the QP IK (unsupported model, unknown backend, bad option, bad target)."""


# --- carmkin.qp.tasks ----------------------------------------------------------------------------


class TaskError(CarmkinError):
    """A task is ill-defined (unknown frame, zero direction, empty distance range, bad weight)."""


# --- carmkin.singularity -------------------------------------------------------------------------


class SingularityError(CarmkinError):
    """The request needs what the system does not offer (e.g. a square 6×6 Jacobian)."""


# --- carmkin.studies.workspace -------------------------------------------------------------------


class WorkspaceStudyError(CarmkinError):
    """A workspace-study grid or translation list is empty or not finite."""


# --- carmkin.studies.table_workspace -------------------------------------------------------------


class TableWorkspaceError(CarmkinError):
    """Bad request to the generalised workspace study (unknown model, N < 1, system lacks joints)."""


# --- carmkin.imaging.camera ----------------------------------------------------------------------


class ImagingError(CarmkinError):
    """Bad input to the imaging geometry (shape, non-finite value, point behind the source, ...)."""


# --- carmkin.panorama ----------------------------------------------------------------------------


class PanoramaError(CarmkinError):
    """Bad input to the panorama planner (principal point, length, overlap, direction, ...)."""


# --- carmkin.reposition.pattern ------------------------------------------------------------------


class PatternError(CarmkinError):
    """Bad marker-board or mount parameters."""


# --- carmkin.reposition.camera -------------------------------------------------------------------


class CameraError(CarmkinError):
    """Bad camera input (intrinsics, image size, noise level)."""


# --- carmkin.reposition.pose ---------------------------------------------------------------------


class PoseError(CarmkinError):
    """Bad input to pose estimation (shapes, too few points, non-finite values) or no solution."""


# --- carmkin.reposition.model -------------------------------------------------------------------


class RepositionModelError(CarmkinError):
    """Bad input to the model from a measured pose (system, pose, joint readings, covariance)."""


# --- carmkin.reposition.calibration, carmkin.calibration ------------------------------------------


class CalibrationError(CarmkinError):
    """Bad calibration data: for the table calibration, shapes, too few positions, displacements along one
    direction only; for :mod:`carmkin.calibration`, joint readings and measured projection matrices that are
    mis-shaped, not finite, of different counts, not rank 3, out of range, or fewer numbers than parameters."""


# --- carmkin.reposition.guidance -----------------------------------------------------------------


class GuidanceError(CarmkinError):
    """No guidance possible: the reference pose has no collision-free IK solution, bad options, ..."""


# --- carmkin.reposition.world --------------------------------------------------------------------


class SimulationError(CarmkinError):
    """Bad simulation settings (noise levels, counts)."""


# --- carmkin.reproduce ----------------------------------------------------------------------------


class UnreachablePanoramaError(SimulationError):
    """A planned image of a simulated panorama needs joints beyond their ranges, or leaves a marker in no
    image: the procedure draws another first position (carmkin.reproduce.stitching, .chapter3)."""


# --- carmkin.interop.simulators ------------------------------------------------------------------


class SimulatorConventionError(CarmkinError):
    """A simulator's model cannot represent the given geometry (e.g. a1 ≠ 0 for DeepDRR's MobileCArm)."""


# --- carmkin.interop.dicom -----------------------------------------------------------------------


class DicomGeometryError(CarmkinError):
    """A DICOM geometry value is out of range or a dataset lacks what a conversion needs."""


class DicomAttributeError(DicomGeometryError):
    """A dataset's attribute is missing, empty, of the wrong type, not finite or outside the standard's range:
    the message names the attribute's keyword and tag (``keyword`` and ``tag`` hold them)."""

    def __init__(self, message: str, keyword: str = "", tag: str = ""):
        super().__init__(message)
        self.keyword, self.tag = keyword, tag


# --- carmkin.interop.drr -------------------------------------------------------------------------


class RenderingError(CarmkinError):
    """Rendering is not available (torch/nanodrr/CT missing) or got bad input."""


# --- carmkin.model.motion (joint speeds, move durations) ----------------------------------------


class MotionError(InvalidParameterError):
    """A joint speed or acceleration that no machine has (zero, negative, not finite), or a move or path of
    the wrong shape for the joints' speeds."""


class MotionPlanError(MotionError):
    """A motion cannot be planned as asked: an end out of range or in collision (which end, the closest pair),
    a time budget, margin or planner that is not one, a goal the system cannot hold. A search that finds no
    path in time is not an error: its :class:`carmkin.motion.Trajectory` says so."""


# --- carmkin.sweeps (3D sweeps) ------------------------------------------------------------------


class SweepError(CarmkinError):
    """A sweep cannot be planned or exported as asked (bad arc, joint, target, export argument)."""


# --- carmkin.viz (the browser viewer) -----------------------------------------------------------------


class VisualizationError(CarmkinError):
    """The viewer cannot do what was asked (no browser, no server, bad scene argument, ...)."""


class ServerError(VisualizationError):
    """The loopback meshcat server could not start or stop."""


class BrowserNotFoundError(VisualizationError):
    """No headless Chromium/Chrome executable to render a page with."""


# --- carmkin.commands._common --------------------------------------------------------------------


class UsageError(CarmkinError):
    """A command-line option has a value the command cannot use (names the option and what it expects)."""


class NotApplicableError(UsageError):
    """The command's mathematics does not apply to this system; the message names the alternative."""


# --- carmkin.patient ------------------------------------------------------------------------------


class PatientModelError(CarmkinError):
    """A patient model is ill-defined (height, mass, position code, origin, CT volume) or overlaps the table."""


# --- carmkin.views -------------------------------------------------------------------------------


class ViewError(CarmkinError):
    """A view is ill-defined (angles, target, direction, segment, distance, roll) or a view name is unknown."""


# --- carmkin.views.anatomy / metrics / optimal -----------------------------------------------------------


class AnatomyError(ViewError):
    """Anatomy given to the views is ill-defined (base of the centreline, plane and placement errors)."""


class CentrelineError(AnatomyError):
    """A vessel centreline or its radii are unusable: fewer than 2 points, NaN, repeated points (a segment of
    zero length), negative radii, or a size no vessel has (units)."""


class PlaneError(AnatomyError):
    """A plane (valve annulus) cannot be fitted: fewer than 3 points, NaN, collinear or coincident points."""


class AnatomyPlacementError(AnatomyError):
    """The anatomy lies outside the CT it came from or outside the patient it belongs to."""


# --- carmkin.datasets ----------------------------------------------------------------------------


class DatasetError(CarmkinError):
    """A dataset request is ill-defined (prior, count, size, output folder) or a prior cannot be met."""


# --- carmkin.biplane -----------------------------------------------------------------------------


class BiplaneError(CarmkinError):
    """A biplane is ill-defined: its planes do not share one table or one isocentre, they intersect at rest, a
    biplane joint vector has the wrong length, or a biplane preset names a plane or key that is not there."""


# --- carmkin.dose --------------------------------------------------------------------------------


class DoseError(CarmkinError):
    """A skin-dose request is ill-defined: an irradiation event (kerma, kVp, filter, field) outside what the
    tables cover, a patient the dose cannot be computed on, or a dose report (RDSR) whose event lacks the
    geometry the map needs (named, never dropped)."""
