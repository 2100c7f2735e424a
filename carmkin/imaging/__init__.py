"""The imaging application: the pinhole model of the X-ray source and detector (:mod:`.camera`),
parallax-free panoramas (:mod:`.panorama`) and the marker phantom (:mod:`.phantom`).

``carmkin.imaging.<name>`` reaches the camera functions directly (numpy only); the planner and the phantom
load on first use.
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
    projection_matrix,
)

__all__ = [
    "ImagingError", "apply_homography", "back_project", "dehomogenize", "homogeneous", "homography_between",
    "image_border", "in_image", "measure_distance", "plane_homography", "plane_in_frame", "project",
    "relative_pose", "rotation_between", "rotation_homography",
    "intrinsics", "patient_pose", "pose_from_projection", "projection_from_pose", "projection_matrix",
]
