"""How the simulated CamC system measures: the filtered camera stream and the X-ray images.

**Camera.** The video camera sits at the X-ray source (mirror construction, §2.2.2.1) up to the error
model's calibration residual ``T_source_camera``; the system believes the camera pose *is* the source pose.
One reading of the "continuous guidance" is the mean of ``frames`` pose estimates, simulated as one
estimate (:meth:`carmkin.reposition.world.World.measure_marker`) from corners with the filtered noise
``σ / √frames`` (:func:`filtered_noise`), mapped to the table frame with the calibrated mount. Its
covariance is the one the estimator reports, over (ω, δp) in the table frame (``R = exp([ω]) R̂``,
``p = p̂ + δp``).

**X-ray.** Points project with the source's true pose and the system's ``K``; the detector sags: it
shifts in its plane by ``sag · (g⊥(T) − g⊥(T_cal))`` (m), ``g⊥`` the gravity direction (table +Y0) across
the beam in the source frame, ``T_cal`` the calibrated pose (the zero joints, beam vertical); every
image point moves by the opposite shift in pixels. Extraction adds Gaussian noise of ``xray_noise_px``.
**Virtual Detector Plane** (§2.2.2.1): four markers on the back of the mirror, fixed to the source, are
extracted in every image and the homography that takes them to their positions in the calibrated pose's
image is applied to the image's points (OpenCV's ``findHomography`` on the four points).

Lengths in m, angles in rad, pixels in px.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Distance of the mirror (and its four VDP markers) from the source along the beam (m): the seed's
#: mirror is 70 cm from the intensifier (§2.2.2.1) and the preset's SID is 980 mm (assumption).
MIRROR_DEPTH = 0.28
#: Pixels where the four mirror markers appear in the calibrated pose's image (assumption: near the corners).
MIRROR_PIXELS = ((80.0, 60.0), (720.0, 60.0), (720.0, 540.0), (80.0, 540.0))
#: Gravity in the table frame (Y0 points down, the preset's convention).
GRAVITY_TABLE = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class CameraReading:
    """One displayed camera reading: ``T`` (4, 4) the source pose in the table frame as the system sees it;
    ``covariance`` (6, 6) over (ω rad, δp m) in the table frame, as the estimator reports it for the mean."""

    T: np.ndarray
    covariance: np.ndarray


def camera_reading(world, T_table_source, T_source_camera, rng: np.random.Generator) -> CameraReading:
    """The displayed camera reading at the true source pose ``T_table_source`` (see the module docstring);
    ``T_source_camera`` (4, 4): the camera's true pose in the source frame. The world's corner noise is
    the filtered stream's (:func:`filtered_noise`)."""
    from carmkin.reposition.model import to_table_frame

    T_camera = np.asarray(T_table_source, dtype=float) @ np.asarray(T_source_camera, dtype=float)
    estimate = world.measure_marker(T_camera, rng)
    return CameraReading(world.measured_mount @ estimate.T, to_table_frame(estimate.covariance, world.tRm))


def filtered_noise(corner_noise_px: float, frames: int) -> float:
    """Corner noise (px) of one estimate equivalent to the mean of ``frames`` estimates: ``σ / √frames``.

    The estimator is linear in the corner noise at these levels (a Gauss–Newton step from the truth), so
    the mean of ``frames`` estimates from independent corners has the distribution, to first order, of one
    estimate from corners averaged over the frames; simulating it so costs one pose solve per reading.
    """
    return float(corner_noise_px) / np.sqrt(int(frames))


def pose_difference(T_a, T_b) -> np.ndarray:
    """(ω, δp) (6,) with ``R_b = exp([ω]) R_a``, ``p_b = p_a + δp``: the coordinates of the covariance."""
    from scipy.spatial.transform import Rotation

    T_a, T_b = np.asarray(T_a, dtype=float), np.asarray(T_b, dtype=float)
    omega = Rotation.from_matrix(T_b[:3, :3] @ T_a[:3, :3].T).as_rotvec()
    return np.concatenate((omega, T_b[:3, 3] - T_a[:3, 3]))


def sag_shift_px(system, T_table_source, sag: float) -> np.ndarray:
    """Pixel shift (2,) of every X-ray image point caused by the detector's sag at the source pose
    ``T_table_source`` (relative to the calibrated pose, the zero joints)."""
    carm = system.carm
    T_cal = system.fk(np.zeros(system.nq))
    across = (np.asarray(T_table_source)[:3, :3].T @ GRAVITY_TABLE)[:2] - (T_cal[:3, :3].T @ GRAVITY_TABLE)[:2]
    pixel = np.array([carm.detector_width / carm.detector_columns, carm.detector_height / carm.detector_rows])
    return -sag * across / pixel


def mirror_markers(system) -> np.ndarray:
    """The four VDP markers (4, 3) in the source frame (m), at :data:`MIRROR_DEPTH` on the rays of
    :data:`MIRROR_PIXELS`."""
    K_inv = np.linalg.inv(system.carm.intrinsics())
    rays = np.column_stack((np.asarray(MIRROR_PIXELS), np.ones(4))) @ K_inv.T
    return MIRROR_DEPTH * rays / rays[:, 2:]


def xray_points(system, T_table_source, points, rng: np.random.Generator, noise_px: float = 0.0, sag: float = 0.0,
                vdp: bool = False) -> np.ndarray:
    """Extracted pixels (N, 2) of the table-frame ``points`` (N, 3) in the X-ray image taken at the true
    source pose ``T_table_source``: sagged detector, extraction noise, then the VDP warp when ``vdp``."""
    import cv2

    from carmkin.imaging import apply_homography, project

    K = system.carm.intrinsics()
    shift = sag_shift_px(system, T_table_source, sag) if sag else np.zeros(2)
    measured = project(K, T_table_source, points) + shift + rng.normal(0.0, noise_px, (len(points), 2))
    if not vdp:
        return measured
    mirror = project(K, np.eye(4), mirror_markers(system)) + shift + rng.normal(0.0, noise_px, (4, 2))
    H, _ = cv2.findHomography(mirror, np.asarray(MIRROR_PIXELS, dtype=float), 0)  # float64 four-point DLT
    return apply_homography(H, measured)
