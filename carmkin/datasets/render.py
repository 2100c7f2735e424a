"""Rendering a dataset's images: DRRs of a CT through nanodrr (:class:`carmkin.interop.drr.Renderer`) in
batches of poses per call, and the landmark labels projected by each image's P.

The image size must bin the detector: ``size`` (columns, rows) = the detector's times one scale (e.g. 200×150
of 800×600: 0.25), with pixel centres kept at integers (:func:`carmkin.interop.drr.scaled_intrinsics`). The CT
is placed in the table frame by the patient frame with its centre on the prior's target
(:meth:`carmkin.interop.drr.Volume.in_table`). Landmarks are points of the CT (its world, mm) projected by
the image's P: pixel (u, v) with centres at integers, ``visible`` when in front of the source and inside the
image (−0.5 … size − 0.5).
"""

from __future__ import annotations

import numpy as np

from carmkin.errors import DatasetError

#: Default landmarks: the CT's centre and points ±60 mm from it along the CT world's axes (RAS, mm).
LANDMARK_OFFSETS_MM = {"centre": (0.0, 0.0, 0.0), "right": (-60.0, 0.0, 0.0), "left": (60.0, 0.0, 0.0),
                       "posterior": (0.0, -60.0, 0.0), "anterior": (0.0, 60.0, 0.0),
                       "inferior": (0.0, 0.0, -60.0), "superior": (0.0, 0.0, 60.0)}
#: Samples per ray inside the CT (the nanodrr default is 500).
N_SAMPLES = 300
#: Poses per nanodrr call.
BATCH = 32


def parse_size(size) -> tuple[int, int]:
    """``"WxH"`` or (W, H) as two positive ints, or :class:`DatasetError`."""
    if isinstance(size, str):
        parts = size.lower().split("x")
        if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
            raise DatasetError(f"size must be WxH in pixels (e.g. 200x150), got {size!r}")
        size = tuple(int(p) for p in parts)
    from carmkin.validation import integer

    if not isinstance(size, (tuple, list)) or len(size) != 2:
        raise DatasetError(f"size must be (columns, rows) in pixels, got {size!r}")
    return integer(size[0], "size columns", low=1, error=DatasetError), integer(size[1], "size rows", low=1,
                                                                                  error=DatasetError)


def binning(system, size) -> float:
    """The scale that bins ``system``'s detector to ``size`` (columns, rows), or :class:`DatasetError`."""
    from carmkin.errors import RenderingError
    from carmkin.interop.drr import scaled_intrinsics

    columns, rows = parse_size(size)
    full = (int(system.carm.detector_columns), int(system.carm.detector_rows))
    scale = columns / full[0]
    try:
        K, binned = scaled_intrinsics(system.carm.intrinsics(), full, scale)
    except RenderingError:
        binned = None
    if binned != (columns, rows):
        raise DatasetError(f"size {columns}x{rows} px does not bin the {full[0]}x{full[1]} detector (one scale "
                           f"for both sides, whole pixels: e.g. {full[0] // 4}x{full[1] // 4})")
    return scale


def check_device(device) -> str:
    """``device`` ``"cpu"`` or ``"cuda"`` (when torch sees a GPU; None: cuda when it does, else cpu), or
    :class:`DatasetError`."""
    if device is None:
        from carmkin.extras import require

        return "cuda" if require("torch", "drr").cuda.is_available() else "cpu"
    if device not in ("cpu", "cuda"):
        raise DatasetError(f"device must be 'cpu' or 'cuda', got {device!r}")
    if device == "cuda":
        from carmkin.extras import require

        if not require("torch", "drr").cuda.is_available():
            raise DatasetError("device 'cuda': torch sees no GPU here (use --device cpu)")
    return device


def project(P, points) -> tuple[np.ndarray, np.ndarray]:
    """``(uv, depth)``: pixels (n, L, 2) and depths along the beam (n, L) of table-frame points (L, 3) (m) by
    projection matrices P (n, 3, 4) (depth = the homogeneous scale, > 0 in front of the source)."""
    X = np.column_stack((np.asarray(points, dtype=float), np.ones(len(points))))
    m = np.einsum("nij,lj->nli", P, X)
    with np.errstate(divide="ignore", invalid="ignore"):
        return m[..., :2] / m[..., 2:], m[..., 2]


def landmarks(P, points, size) -> tuple[np.ndarray, np.ndarray]:
    """Landmark labels: ``(uv (n, L, 2), visible (n, L))`` of table-frame points (L, 3) by P (n, 3, 4) for an
    image of ``size`` (columns, rows); uv is NaN behind the source."""
    uv, depth = project(P, points)
    front = depth > 0
    uv = np.where(front[..., None], uv, np.nan)
    with np.errstate(invalid="ignore"):
        inside = (uv[..., 0] >= -0.5) & (uv[..., 0] <= size[0] - 0.5) & (uv[..., 1] >= -0.5) & (uv[..., 1] <= size[1] - 0.5)
    return uv, front & inside


class ImageRenderer:
    """DRRs of ``volume`` (a :class:`carmkin.interop.drr.Volume`) placed with its centre on ``target`` (3,) m for
    the patient frame ``patient_pose`` (4, 4), at ``size`` (columns, rows), on ``device``; the landmarks are
    ``LANDMARK_OFFSETS_MM`` from the CT's centre."""

    def __init__(self, system, volume, patient_pose, target, size, device="cpu", n_samples=N_SAMPLES,
                 batch=BATCH) -> None:
        from carmkin.interop import drr

        self.T_table_ct = volume.in_table(np.asarray(patient_pose, dtype=float), target)
        self.renderer = drr.Renderer(system, volume, self.T_table_ct, binning(system, size), n_samples,
                                     check_device(device))
        self.K, self.size, self.batch = self.renderer.K, self.renderer.size, int(batch)
        ct = volume.centre + np.array(list(LANDMARK_OFFSETS_MM.values()))
        self.landmark_names = tuple(LANDMARK_OFFSETS_MM)
        self.landmark_points = (self.T_table_ct @ np.column_stack((ct / 1e3, np.ones(len(ct)))).T).T[:, :3]

    def render(self, T, progress=None) -> np.ndarray:
        """Images (n, rows, columns) float32 of source poses T (n, 4, 4), :data:`BATCH` poses per call;
        ``progress(count)`` (optional) is called with each batch's image count once it is rendered."""
        T = np.asarray(T, dtype=float)
        parts = []
        for a in range(0, len(T), self.batch):
            parts.append(self.renderer.render_batch(T[a:a + self.batch]))
            if progress is not None:
                progress(len(parts[-1]))
        return np.concatenate(parts).astype(np.float32) if parts else np.zeros((0, self.size[1], self.size[0]),
                                                                              np.float32)

    def projection_matrices(self, T) -> np.ndarray:
        """P (n, 3, 4) of the images: table-frame points (m) to pixels of this size."""
        from .samples import projection_matrices

        return projection_matrices(self.K, np.asarray(T, dtype=float))

    def labels(self, P) -> tuple[np.ndarray, np.ndarray]:
        """:func:`landmarks` of this renderer's points for P (n, 3, 4)."""
        return landmarks(P, self.landmark_points, self.size)
