"""Simulate and reconstruct a planned sweep with RTK on the CPU (the ``cbct`` extra: ``pip install
'carmkin[cbct]'``), and the perturbation study: what the kinematic model's errors do to the volume.

* **Reconstruction frame** (:func:`reconstruction_frame`): RTK's FDK cosine weights and Parker short-scan
  weights read the *gantry angle*, RTK's rotation about its world Y axis. The geometry is therefore handed
  to RTK in a frame with its origin at the target and Y along the sweep's rotation axis (Z towards the
  source at mid-arc); the volume's axes are that frame's, in mm.
* **Simulation**: RTK's voxelised Shepp–Logan (``DrawSheppLoganFilter``, ``phantom_mm`` the scale) is
  forward-projected along the frames with the Joseph projector (``JosephForwardProjectionImageFilter``).
* **Reconstruction**: Parker weighting (``ParkerShortScanImageFilter``) and FDK
  (``FDKConeBeamReconstructionFilter``, ramp filter, no apodisation); the error is the RMSE against the
  drawn phantom over the voxels inside the field of view's inscribed cylinder.
* **Perturbations** (:func:`perturbation_study`): projections simulated with the *true* geometry,
  reconstruction with the *nominal* one — joint encoder noise (σ per joint), a table setup error of the size
  §4.6.2 measures (0.37°, 4.6 mm: the table frame of the model is off by that rigid transform), and the
  plain orbital rotation of a non-isocentric C-arm reconstructed as the ideal circle (its isocentre drift).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from carmkin.errors import SweepError
from carmkin.transforms import inverse, skew

from . import export
from .trajectory import rotation_axis

#: The voxel size, phantom scale and field of view used unless told otherwise (mm).
DEFAULT_VOLUME_MM = 140.0
DEFAULT_PHANTOM_MM = 60.0
#: RTK detector layout of the simulation: v along the rotation axis (FDK filters along u).
LAYOUT = "rotation"
#: Joint encoder noise of the study (1 σ): 0.1° on revolute, 0.5 mm on prismatic joints (assumption).
ENCODER_SIGMA = (math.radians(0.1), 0.0005)


def with_detector(system, columns: int, rows: int):
    """The system with a detector of ``columns`` × ``rows`` pixels over the same physical area."""
    return system.replace(carm=replace(system.carm, detector_columns=int(columns), detector_rows=int(rows),
                                       principal_point=None))


def reconstruction_frame(sweep) -> np.ndarray:
    """Pose (4, 4) of the reconstruction frame in the table frame: origin at the target, Y along the sweep's
    rotation axis (turning positively about it), Z towards the source of the middle frame."""
    mid = sweep.n_views // 2
    R = sweep.poses[mid, :3, :3]
    y = R @ rotation_axis(sweep.system, sweep.q_plain[mid], sweep.weights)
    z = sweep.poses[mid, :3, 3] - sweep.target
    z = z - (z @ y) * y
    z /= np.linalg.norm(z)
    T = np.eye(4)
    T[:3, :3] = np.column_stack((np.cross(y, z), y, z))
    T[:3, 3] = sweep.target
    return T


def in_frame(sweep, T_frame: np.ndarray, poses: np.ndarray | None = None):
    """The sweep with its poses (or ``poses``) expressed in the frame ``T_frame`` (4, 4, in the table frame)."""
    poses = sweep.poses if poses is None else poses
    from carmkin.imaging.projection import projection_from_pose

    local = inverse(T_frame)[None] @ poses
    K = sweep.system.carm.intrinsics()
    return replace(sweep, poses=local, P=np.array([projection_from_pose(K, T) for T in local]),
                   target=np.zeros(3))


def _itk():
    return export._rtk()


def _image(size, spacing, origin, value=0.0):
    itk, rtk = _itk()
    source = rtk.ConstantImageSource[itk.Image[itk.F, 3]].New()
    source.SetSize([int(v) for v in size])
    source.SetSpacing([float(v) for v in spacing])
    source.SetOrigin([float(v) for v in origin])
    source.SetConstant(float(value))
    source.Update()
    return source.GetOutput()


@dataclass(frozen=True)
class Volume:
    """A cubic volume: ``size`` voxels per side over ``extent_mm``, centred at the frame's origin."""

    size: int = 128
    extent_mm: float = DEFAULT_VOLUME_MM

    @property
    def spacing(self) -> float:
        return self.extent_mm / self.size

    @property
    def origin(self) -> float:
        return -0.5 * (self.size - 1) * self.spacing

    def empty(self):
        return _image([self.size] * 3, [self.spacing] * 3, [self.origin] * 3)

    def mask(self) -> np.ndarray:
        """(z, y, x) voxels inside the cylinder of radius 0.45 extent about Y (the reconstructable region)."""
        c = (np.arange(self.size) - 0.5 * (self.size - 1)) * self.spacing
        z, _, x = np.meshgrid(c, c, c, indexing="ij")
        return np.broadcast_to(x ** 2 + z ** 2 <= (0.45 * self.extent_mm) ** 2, (self.size,) * 3)


def phantom(volume: Volume, scale_mm: float = DEFAULT_PHANTOM_MM):
    """RTK's 3D Shepp–Logan drawn into ``volume`` (an itk image)."""
    itk, rtk = _itk()
    draw = rtk.DrawSheppLoganFilter[itk.Image[itk.F, 3], itk.Image[itk.F, 3]].New()
    draw.SetInput(volume.empty())
    draw.SetPhantomScale(float(scale_mm))
    draw.Update()
    return draw.GetOutput()


def forward_project(sweep, volume_image):
    """Joseph projections (itk image: columns × rows × frames) of ``volume_image`` along ``sweep`` (its
    poses in the volume's frame, mm)."""
    itk, rtk = _itk()
    geometry = export.rtk_geometry(sweep, layout=LAYOUT)
    origin, spacing, size = export.rtk_projection_grid(sweep, layout=LAYOUT)
    stack = _image(size, spacing, origin)
    joseph = rtk.JosephForwardProjectionImageFilter[itk.Image[itk.F, 3], itk.Image[itk.F, 3]].New()
    joseph.SetInput(0, stack)
    joseph.SetInput(1, volume_image)
    joseph.SetGeometry(geometry)
    joseph.Update()
    return joseph.GetOutput()


def fdk(sweep, projections, volume: Volume) -> np.ndarray:
    """Parker-weighted FDK of ``projections`` with the geometry of ``sweep`` → (z, y, x) float array."""
    itk, rtk = _itk()
    geometry = export.rtk_geometry(sweep, layout=LAYOUT)
    image = itk.Image[itk.F, 3]
    parker = rtk.ParkerShortScanImageFilter[image].New()
    parker.SetInput(projections)
    parker.SetGeometry(geometry)
    parker.InPlaceOff()
    reco = rtk.FDKConeBeamReconstructionFilter[image].New()
    reco.SetInput(0, volume.empty())
    reco.SetInput(1, parker.GetOutput())
    reco.SetGeometry(geometry)
    reco.GetRampFilter().SetTruncationCorrection(0.0)
    reco.GetRampFilter().SetHannCutFrequency(0.0)
    reco.Update()
    return np.array(itk.GetArrayFromImage(reco.GetOutput()), dtype=np.float64)


@dataclass(frozen=True)
class Reconstruction:
    """One reconstruction: ``volume`` (z, y, x) and ``rmse`` against ``phantom`` (inside the mask)."""

    label: str
    volume: np.ndarray
    phantom: np.ndarray
    rmse: float
    mask: np.ndarray

    def profile(self, axis: int = 2) -> tuple[np.ndarray, np.ndarray]:
        """``(reconstructed, phantom)`` values along the central line of ``axis`` (0 z, 1 y, 2 x)."""
        c = self.volume.shape[0] // 2
        index = [c, c, c]
        index[axis] = slice(None)
        return self.volume[tuple(index)], self.phantom[tuple(index)]


def simulate_and_reconstruct(sweep, volume: Volume = Volume(), true_poses: np.ndarray | None = None,
                             label: str = "nominal", phantom_mm: float = DEFAULT_PHANTOM_MM,
                             frame: np.ndarray | None = None) -> Reconstruction:
    """Forward-project the phantom along ``true_poses`` (default: the sweep's poses; table frame) and
    reconstruct with the sweep's (nominal) geometry, both in the reconstruction ``frame`` (default
    :func:`reconstruction_frame`)."""
    itk, _ = _itk()
    if sweep.n_views < 2:
        raise SweepError("a reconstruction needs at least 2 frames")
    frame = reconstruction_frame(sweep) if frame is None else frame
    drawn = phantom(volume, phantom_mm)
    nominal = in_frame(sweep, frame)
    true = nominal if true_poses is None else in_frame(sweep, frame, true_poses)
    projections = forward_project(true, drawn)
    recon = fdk(nominal, projections, volume)
    ref = np.array(itk.GetArrayFromImage(drawn), dtype=np.float64)
    mask = volume.mask()
    return Reconstruction(label, recon, ref, float(np.sqrt(np.mean((recon - ref)[mask] ** 2))), mask)


def perturbation_study(sweep, volume: Volume = Volume(), seed: int = 0, non_isocentric=(0.03, 0.02),
                       phantom_mm: float = DEFAULT_PHANTOM_MM) -> list[Reconstruction]:
    """Reconstructions of ``sweep`` (planned on an isocentric or compensated trajectory): nominal, joint
    encoder noise (:data:`ENCODER_SIGMA`), the §4.6.2 table setup error, and — on the system with offsets
    ``non_isocentric`` = (a1, a2) m — the plain orbital rotation reconstructed as the ideal circle."""
    from carmkin.seed import SEED_RESULTS

    system = sweep.system
    frame = reconstruction_frame(sweep)
    rng = np.random.default_rng(seed)
    out = [simulate_and_reconstruct(sweep, volume, label="nominal", phantom_mm=phantom_mm, frame=frame)]
    sigma = np.where(system.prismatic, ENCODER_SIGMA[1], ENCODER_SIGMA[0])
    noisy = system.fk(sweep.q + rng.normal(size=sweep.q.shape) * sigma)
    out.append(simulate_and_reconstruct(sweep, volume, noisy, "encoder noise", phantom_mm, frame))
    angle = math.radians(SEED_RESULTS["rotation (deg)"][0])
    shift = SEED_RESULTS["translation (mm)"][0] / 1e3
    axis, direction = rng.normal(size=3), rng.normal(size=3)
    W = skew(axis / np.linalg.norm(axis))
    E = np.eye(4)
    E[:3, :3] = np.eye(3) + math.sin(angle) * W + (1.0 - math.cos(angle)) * W @ W  # Rodrigues
    E[:3, 3] = shift * direction / np.linalg.norm(direction)
    from carmkin.model.params import TableSetup

    true_system = system.replace(setup=TableSetup.from_pose(inverse(system.carm_base_pose) @ E))
    out.append(simulate_and_reconstruct(sweep, volume, true_system.fk(sweep.q), "table setup error (§4.6.2)",
                                        phantom_mm, frame))
    a1, a2 = non_isocentric
    offset = system.replace(carm=replace(system.carm, a1=float(a1), a2=float(a2)))
    from .plan import plan_sweep

    ideal = plan_sweep(offset, sweep.target, math.degrees(sweep.arc), sweep.n_views, joint=sweep._joint_spec(),
                       compensate=True, distance=sweep.distance, margin=0.0)
    plain = offset.fk(ideal.q_plain)
    recon = simulate_and_reconstruct(ideal, volume, plain, f"plain rotation, a1 = {a1 * 1e3:.0f} mm, "
                                     f"a2 = {a2 * 1e3:.0f} mm (drift max {ideal.drift.max() * 1e3:.1f} mm)",
                                     phantom_mm, frame)
    out.append(recon)
    return out
