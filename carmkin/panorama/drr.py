"""Rendered panoramas on a CT: DRRs at every shot of a parallax-free plan (§4.4,
:class:`carmkin.panorama.PanoramaPlanner`) against the same line covered by translated shots
stitched on one plane, and the misalignment of off-plane fiducials on the overlaps.

- **parallax-free**: the planned shots rotate about the source (same source position in the table frame);
  each image maps into the panorama (the reference image's frame) by ``K R K⁻¹``, exact at every depth.
- **one-plane**: the conventional alternative — the reference view translated along the panorama line (a
  table translation) to the same aim points, stitched by the homography of the planning plane (the table
  top, the planner's object plane); exact on that plane only.

Beads (fiducials) are inserted into the CT off that plane (``bead_height`` m nearer the detector, inside the
patient) on the rays through the middles of the overlaps; each is found in both images of its overlap (the
rendered difference with and without beads), mapped into the panorama by each image's homography, and the
two positions compared: the misalignment (px). The same detections, compared with ``P`` of their shot,
check the renderer against the projection matrix.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from carmkin import imaging
from carmkin.panorama.planner import PanoramaError, PanoramaPlanner
from carmkin.interop.drr import Renderer, Volume, blob_centre
from carmkin.transforms import inverse


@dataclass
class PanoramaExperiment:
    """Outcome of :func:`panorama_experiment` (pixels of the binned detector, m in the table frame).

    ``poses``: {"parallax-free", "one-plane"} → source poses (n, 4, 4); ``homographies``: the same keys →
    (n, 3, 3) image → panorama; ``images``: rendered DRRs with beads; ``beads`` (m, 3) table frame;
    ``misalignment``: key → (m,) px; ``projection_errors`` (k,) px: detected bead − P projection over every
    image; ``plane_distance`` (m); ``seconds``: time of each DRR.
    """

    poses: dict
    homographies: dict
    images: dict
    beads: np.ndarray
    misalignment: dict
    projection_errors: np.ndarray
    plane_distance: float
    K: np.ndarray
    size: tuple
    seconds: list = field(default_factory=list)

    def stitch(self, key: str):
        """``(panorama, extent)``: the images of ``key`` averaged on a common canvas (NaN outside) and the
        canvas extent ``(u_min, u_max, v_max, v_min)`` in reference-image pixels (for ``imshow``)."""
        return stitch(self.images[key], self.homographies[key], self.size)


def stitch(images, homographies, size):
    """Average of ``images`` warped by ``homographies`` (image → panorama) on the canvas that holds them."""
    from scipy.ndimage import map_coordinates

    corners = np.vstack([imaging.apply_homography(H, imaging.image_border(*size, 4)) for H in homographies])
    u0, v0 = np.floor(corners.min(axis=0)).astype(int)
    u1, v1 = np.ceil(corners.max(axis=0)).astype(int)
    vv, uu = np.mgrid[v0:v1 + 1, u0:u1 + 1]
    canvas = np.column_stack((uu.ravel(), vv.ravel()))
    total, count = np.zeros(len(canvas)), np.zeros(len(canvas))
    for image, H in zip(images, homographies):
        m = imaging.apply_homography(np.linalg.inv(H), canvas)
        inside = imaging.in_image(m, *size)
        total[inside] += map_coordinates(image, [m[inside, 1], m[inside, 0]], order=1, mode="nearest")
        count[inside] += 1
    with np.errstate(invalid="ignore", divide="ignore"):
        panorama = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    return panorama.reshape(vv.shape), (u0 - 0.5, u1 + 0.5, v1 + 0.5, v0 - 0.5)


def panorama_experiment(system, volume: Volume, T_table_ct, q_reference, length: float, overlap: float = 0.4,
                        bead_height: float = 0.12, scale: float = 0.25, n_samples: int = 400,
                        device: str | None = None) -> PanoramaExperiment:
    """Plan a parallax-free panorama of ``length`` (m) from ``q_reference``, render both series on ``volume``
    (placed by ``T_table_ct``) with beads ``bead_height`` (m) off the planning plane, and measure.

    Raises when a planned shot is not valid (its joints would not give the image).
    """
    planner = PanoramaPlanner(system, q_reference=q_reference)
    plan = planner.plan(length, overlap)
    invalid = [k for k, shot in enumerate(plan.shots) if not shot.valid]
    if invalid:
        raise PanoramaError(f"shots {invalid} of the plan are not valid: {plan.shots[invalid[0]].reasons}")
    T_ref = planner.P_ref
    z = T_ref[:3, 2]
    direction_table = T_ref[:3, :3] @ plan.direction
    plane_n, plane_d = z, float(z @ (T_ref[:3, 3] + plan.distance * z))
    poses = {"parallax-free": np.array([system.fk(shot.q, check_units=False) for shot in plan.shots])}
    translated = np.repeat(T_ref[None], len(plan.aims), axis=0)
    translated[:, :3, 3] += plan.aims[:, None] * direction_table
    poses["one-plane"] = translated
    renderer = Renderer(system, volume, T_table_ct, scale, n_samples, device)
    K, size = renderer.K, renderer.size
    homographies = {
        "parallax-free": np.array([imaging.homography_between(K, T_ref, T) for T in poses["parallax-free"]]),
        "one-plane": np.array([imaging.homography_between(K, T_ref, T, plane_n, plane_d) for T in translated]),
    }
    # Beads: on the reference rays through the overlap middles, bead_height nearer the detector than the plane.
    middles = 0.5 * (plan.extents[:-1, 1] + plan.extents[1:, 0])
    depth = plan.distance + bead_height
    beads_ref = (np.array([0.0, 0.0, plan.distance]) + middles[:, None] * plan.direction) * (depth / plan.distance)
    beads = beads_ref @ T_ref[:3, :3].T + T_ref[:3, 3]
    beads_ct_mm = volume.voxel_centre(
        (inverse(T_table_ct) @ np.column_stack((beads, np.ones(len(beads)))).T).T[:, :3] * 1000.0)
    beads = (T_table_ct @ np.column_stack((beads_ct_mm / 1000.0, np.ones(len(beads)))).T).T[:, :3]
    with_beads = Renderer(system, volume.with_fiducials(beads_ct_mm), T_table_ct, scale, n_samples, device)
    images, misalignment, errors = {}, {}, []
    for key, series in poses.items():
        plain = [renderer.render(T) for T in series]
        images[key] = [with_beads.render(T) for T in series]
        found = []  # (bead, shot) -> panorama position
        for b, X in enumerate(beads):
            positions = []
            for k in (b, b + 1):
                predicted = imaging.project(K, series[k], X)[0]
                if not imaging.in_image(predicted[None], *size)[0]:
                    raise ValueError(f"bead {b} is not seen by shot {k} of the {key} series")
                window = _window(images[key][k] - plain[k], predicted)
                detected = blob_centre(window[0]) + window[1]
                errors.append(np.linalg.norm(detected - predicted))
                positions.append(imaging.apply_homography(homographies[key][k], detected)[0])
            found.append(np.linalg.norm(positions[0] - positions[1]))
        misalignment[key] = np.array(found)
    return PanoramaExperiment(poses, homographies, images, beads, misalignment, np.array(errors), plan.distance,
                              K, size, renderer.seconds + with_beads.seconds)


def _window(image, centre, half: int = 10):
    """The part of ``image`` within ``half`` px of ``centre`` (u, v) and its top-left offset (u, v)."""
    u, v = np.round(centre).astype(int)
    v0, u0 = max(v - half, 0), max(u - half, 0)
    return image[v0:v + half + 1, u0:u + half + 1], np.array([u0, v0], dtype=float)
