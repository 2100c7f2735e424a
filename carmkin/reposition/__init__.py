"""Radiation-free C-arm repositioning (§3.3.1–3.3.3, §4.5, §4.6.2, eq. 4.3).

A camera whose optical centre coincides with the X-ray source (same intrinsics ``K``) sees a planar square
marker pattern fixed under the table; its pose in the marker frame is estimated with OpenCV
(:mod:`.pose`); the marker→table rotation is calibrated from table translations (:mod:`.calibration`);
the 6-DOF model is built from one measured pose and the joint readings (:mod:`.model`, eq. 4.3); and the
operator is guided joint by joint back to a reference pose (:mod:`.guidance`). :mod:`.experiment`
simulates the §4.6.2 repositioning experiment.

Modules: :mod:`.pattern` (the board and its mount), :mod:`.camera` (ideal/noisy corner lists),
:mod:`.render` (synthetic images), :mod:`.pose` (with :mod:`.reprojection`, the LM), :mod:`.calibration`, :mod:`.model`, :mod:`.guidance`,
:mod:`.world` (the simulation's truth: room, camera noise, operator) and :mod:`.experiment`. OpenCV (``pip install "carmkin[reposition]"``) is imported on first use only.

Contract (``../shared/DESIGN.md``)::

    estimate_pose(object_points, image_points, K) -> (4, 4) camera (= X-ray source) pose in the marker frame
    calibrate_table(camera_positions_marker, camera_displacements_table) -> (3, 3) tRm, P_table = tRm P_marker

One call away, with what they know of their own quality (issue 19): :func:`solve_pose` returns a
:class:`PoseEstimate` (pose, residuals, covariance, condition) and :func:`calibrate` a :class:`Calibration`
(rotation and residuals); all four raise a typed error rather than return what they cannot stand behind.
"""

from .calibration import Calibration, CalibrationError, calibrate, calibrate_table
from .pose import PoseError, PoseEstimate, estimate_pose, solve_pose

__all__ = ["Calibration", "CalibrationError", "PoseError", "PoseEstimate", "calibrate", "calibrate_table",
           "estimate_pose", "solve_pose"]
