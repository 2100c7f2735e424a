"""The imaging geometry: the pinhole model of the X-ray source and detector (:mod:`.camera`) and the
projection matrix of a configuration (:mod:`.projection`), numpy only. The panorama planner that uses them is
a planner of its own, :mod:`carmkin.panorama`.
"""

from .camera import (
    ImagingError,
    apply_homography,
    back_project,
    dehomogenize,
    homogeneous,
    homography_between,
    image_border,
    in_image,
    measure_distance,
    plane_homography,
    plane_in_frame,
    project,
    relative_pose,
    rotation_between,
    rotation_homography,
)
from .projection import (
    intrinsics,
    patient_pose,
    pose_from_projection,
    projection_from_pose,
    projection_matrices,
    projection_matrix,
)

__all__ = [
    "ImagingError", "apply_homography", "back_project", "dehomogenize", "homogeneous", "homography_between",
    "image_border", "in_image", "measure_distance", "plane_homography", "plane_in_frame", "project",
    "relative_pose", "rotation_between", "rotation_homography",
    "intrinsics", "patient_pose", "pose_from_projection", "projection_from_pose", "projection_matrices",
    "projection_matrix",
]
