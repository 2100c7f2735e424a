"""Synthetic marker phantom and the simulated stitching check of parallax (§3.4, Fig. 3.7).

The phantom: spherical markers (their centres) on three planes parallel to the table top, 8 cm apart, on
the patient side of the table top where the reference principal axis leaves it. The check projects the
markers at the planned poses (FK of the planned joints, i.e. after the IK/FK round trip), maps each image
into the panorama with its homography and compares with where the reference view sees each marker:

* parallax-free: the shots of a :class:`~carmkin.panorama.Plan`, stitched with ``H = K R K⁻¹``;
* one-plane: shots taken by translating the source parallel to the reference image plane to the same aim
  points (for the default direction that is the table translation d0 alone), stitched with the
  plane-induced homography (eq. 4.17) of the middle marker plane;
* pose noise: the planned poses perturbed by Gaussian rotations (σ deg per axis) and translations
  (σ mm per axis) in the source frame, stitched with the planned homographies.

Lengths in m, angles in rad, discrepancies in pixels of the panorama (reference image) frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from carmkin import imaging
from carmkin.transforms import check_rigid_transform
from carmkin.validation import MAX_DISTANCE, distance, integer, real_array, real_scalar

from .planner import PanoramaError, PanoramaPlanner, Plan

#: Most markers one phantom may hold (bounds the cost of a call: ``length / spacing`` is checked against it).
MAX_MARKERS = 100_000
#: Most marker planes of a phantom.
MAX_PLANES = 100
#: Most trials per noise level of :func:`noise_propagation`.
MAX_TRIALS = 10_000


def _planner(planner) -> PanoramaPlanner:
    if not isinstance(planner, PanoramaPlanner):
        raise PanoramaError(f"planner must be a carmkin.panorama.PanoramaPlanner, got {planner!r}")
    return planner


def _plan(plan) -> Plan:
    if not isinstance(plan, Plan):
        raise PanoramaError(f"plan must be a carmkin.panorama.Plan, got {plan!r}")
    return plan


@dataclass(frozen=True)
class Phantom:
    """Marker centres ``points`` (N, 3) (table frame, m), their plane index ``plane`` (N,), the unit
    plane ``normal`` (3,) and the planes' offsets ``offsets`` (k,) (m): plane j is ``normal·X = offsets[j]``."""

    points: np.ndarray
    plane: np.ndarray
    normal: np.ndarray
    offsets: np.ndarray


def marker_phantom(planner, length: float = 0.4, spacing: float = 0.04, lateral=(-0.015, 0.0, 0.015),
                   planes: int = 3, gap: float = 0.08, lift: float = 0.02) -> Phantom:
    """Markers on ``planes`` planes ``gap`` (m) apart, parallel to the table top (table X0–Z0 plane).

    The first plane is ``lift`` (m) above the table-top surface the reference axis leaves (patient side).
    Along Z0 the markers span the cone of the reference source over ``length`` (m) at the first plane,
    scaled with depth, every ``spacing`` (m); across, at the ``lateral`` X0 offsets (m) around the axis.
    """
    P_ref = _planner(planner).P_ref
    length = distance(length, "length", error=PanoramaError)
    spacing = distance(spacing, "spacing", error=PanoramaError)
    lateral = real_array(lateral, "lateral", (None,), error=PanoramaError, unit="m")
    planes = integer(planes, "planes", low=1, high=MAX_PLANES, error=PanoramaError)
    gap = distance(gap, "gap", error=PanoramaError)
    lift = real_scalar(lift, "lift", error=PanoramaError, low=0.0, high=MAX_DISTANCE, unit="m")
    if not 1 <= len(lateral) * planes * (length / spacing + 1) <= MAX_MARKERS:
        raise PanoramaError(f"a phantom holds 1 to {MAX_MARKERS} markers: length {length:g} m every {spacing:g} m "
                            f"at {len(lateral)} lateral offsets on {planes} planes is too many or none")
    axis = P_ref[:3, 2]
    normal = np.array([0.0, 1.0, 0.0])
    if abs(axis @ normal) < 1e-6:
        raise PanoramaError("the reference principal axis is parallel to the table top: no phantom")
    sign = np.sign(axis @ normal)  # the planes lie further along the axis than the table top
    exit_point = P_ref[:3, 3] + planner.default_object_distance() * axis
    base = exit_point + sign * lift * normal
    points, index, offsets = [], [], []
    depth0 = np.linalg.norm(base - P_ref[:3, 3])
    for j in range(planes):
        centre = base + sign * j * gap * normal
        # the point of this plane on the reference axis
        t = (normal @ (centre - P_ref[:3, 3])) / (normal @ axis)
        on_axis = P_ref[:3, 3] + t * axis
        half = 0.5 * length * t / depth0
        for z in np.arange(-half, half + 1e-12, spacing):
            for x in lateral:
                points.append(on_axis + np.array([x, 0.0, z]))
                index.append(j)
        offsets.append(float(normal @ centre))
    return Phantom(np.array(points), np.array(index), normal, np.array(offsets))


def _stitch_errors(K, size, poses, homographies, P_ref, points) -> np.ndarray:
    """Per marker (N,): max over the shots that see it of |H_i m_i − m_ref| (px); NaN when none sees it."""
    m_ref = imaging.project(K, P_ref, points)
    worst = np.full(len(points), np.nan)
    for T, H in zip(poses, homographies):
        m = imaging.project(K, T, points, allow_behind=True)
        depth = (points - T[:3, 3]) @ T[:3, 2]
        seen = imaging.in_image(m, *size) & (depth > 0)
        if not seen.any():
            continue
        err = np.linalg.norm(imaging.apply_homography(H, m[seen]) - m_ref[seen], axis=1)
        worst[seen] = np.fmax(worst[seen], err)
    return worst


def _pair_errors(K, size, poses, homographies, points) -> tuple[float, int]:
    """``(max, count)``: max |H_i m_i − H_j m_j| (px) over the ``count`` (marker, shot pair) with the marker
    seen in both shots i, j (NaN when no marker is shared)."""
    mapped = []
    for T, H in zip(poses, homographies):
        m = imaging.project(K, T, points, allow_behind=True)
        depth = (points - T[:3, 3]) @ T[:3, 2]
        seen = imaging.in_image(m, *size) & (depth > 0)
        out = np.full((len(points), 2), np.nan)
        out[seen] = imaging.apply_homography(H, m[seen])
        mapped.append(out)
    worst, count = np.nan, 0
    for i in range(len(mapped)):
        for j in range(i + 1, len(mapped)):
            both = ~np.isnan(mapped[i][:, 0]) & ~np.isnan(mapped[j][:, 0])
            if both.any():
                count += int(both.sum())
                worst = np.fmax(worst, float(np.max(np.linalg.norm(mapped[i][both] - mapped[j][both], axis=1))))
    return float(worst), count


@dataclass
class ParallaxReport:
    """Discrepancies (px) of the stitched markers, per phantom plane (index j of ``per_plane_*``).

    ``parallax_free``/``one_plane``: max over the markers of plane j seen by some shot;
    ``parallax_free_pairs``/``one_plane_pairs``: (max, count) over markers shared by two shots of the
    distance between their two stitched positions (NaN, 0 when none is shared); ``seen``: markers seen per plane; ``stitch_plane``: the plane of
    the one-plane homography.
    """

    parallax_free: np.ndarray
    one_plane: np.ndarray
    parallax_free_pairs: tuple[float, int]
    one_plane_pairs: tuple[float, int]
    seen: np.ndarray
    stitch_plane: int

    def describe(self) -> str:
        lines = ["plane  markers  parallax-free max (px)  one-plane max (px)"]
        for j, (a, b, n) in enumerate(zip(self.parallax_free, self.one_plane, self.seen)):
            mark = " (stitching plane)" if j == self.stitch_plane else ""
            lines.append(f"{j:5d}  {n:7d}  {a:22.3e}  {b:18.3f}{mark}")
        (a, na), (b, nb) = self.parallax_free_pairs, self.one_plane_pairs
        free = f"max {a:.3e} px ({na} pairs)" if na else "none shared"
        one = f"max {b:.3f} px ({nb} pairs)" if nb else "none shared"
        lines.append(f"markers seen by two shots: parallax-free {free}, one-plane {one}")
        return "\n".join(lines)


def translation_poses(planner, plan) -> list[np.ndarray]:
    """Poses of one-plane stitching: the reference pose translated by ``s·direction`` (reference frame)."""
    planner, plan = _planner(planner), _plan(plan)
    poses = []
    for s in plan.aims:
        M = np.eye(4)
        M[:3, 3] = s * plan.direction
        poses.append(planner.P_ref @ M)
    return poses


def parallax_check(planner, plan, phantom: Phantom, stitch_plane: int = 1) -> ParallaxReport:
    """Stitch the phantom's markers for the plan (parallax-free) and for translated shots (one-plane)."""
    system, K, size = _planner(planner).system, planner.K, planner.size
    plan = _plan(plan)
    if not isinstance(phantom, Phantom):
        raise PanoramaError(f"phantom must be a Phantom (marker_phantom), got {phantom!r}")
    stitch_plane = integer(stitch_plane, "stitch_plane", low=0, high=len(phantom.offsets) - 1, error=PanoramaError)
    if any(not np.all(np.isfinite(s.q)) for s in plan.shots):
        raise PanoramaError("a shot of the plan has no joint solution")
    poses = [system.fk(s.q, check_units=False) for s in plan.shots]  # IK → FK round trip
    free_H = [s.H for s in plan.shots]
    shifted = translation_poses(planner, plan)
    n, d = phantom.normal, phantom.offsets[stitch_plane]
    plane_H = [imaging.homography_between(K, planner.P_ref, T, n, d) for T in shifted]
    free = _stitch_errors(K, size, poses, free_H, planner.P_ref, phantom.points)
    one = _stitch_errors(K, size, shifted, plane_H, planner.P_ref, phantom.points)
    planes = np.unique(phantom.plane)

    def per_plane(err):
        values = [err[phantom.plane == j] for j in planes]
        return np.array([np.nanmax(v) if np.any(~np.isnan(v)) else np.nan for v in values])

    seen = np.array([int(np.sum(~np.isnan(free[phantom.plane == j]))) for j in planes])
    return ParallaxReport(per_plane(free), per_plane(one), _pair_errors(K, size, poses, free_H, phantom.points),
                          _pair_errors(K, size, shifted, plane_H, phantom.points), seen, stitch_plane)


def perturb(T: np.ndarray, rng: np.random.Generator, sigma_m: float, sigma_rad: float) -> np.ndarray:
    """``T · [exp(ω) δ; 0 1]`` with ω ~ N(0, σ_rad² I₃) and δ ~ N(0, σ_m² I₃) in the source frame."""
    T = check_rigid_transform(T, "T")
    if not isinstance(rng, np.random.Generator):
        raise PanoramaError(f"rng must be a numpy.random.Generator, got {rng!r}")
    sigma_m = real_scalar(sigma_m, "sigma_m", error=PanoramaError, low=0.0, high=MAX_DISTANCE, unit="m")
    sigma_rad = real_scalar(sigma_rad, "sigma_rad", error=PanoramaError, low=0.0, high=np.pi, unit="rad")
    M = np.eye(4)
    M[:3, :3] = Rotation.from_rotvec(rng.normal(0.0, sigma_rad, 3)).as_matrix()
    M[:3, 3] = rng.normal(0.0, sigma_m, 3)
    return T @ M


def noise_propagation(planner, plan, phantom: Phantom, sigmas, trials: int = 50, seed: int = 0) -> list[dict]:
    """For each ``(σ_mm, σ_deg)`` of ``sigmas``: RMS and max stitching discrepancy (px) of the
    parallax-free plan when the achieved poses carry Gaussian noise, and the first-order predictions
    ``f·σ_rad`` (rotation) and ``f·σ_m / z`` (translation, z = depth of the middle plane), f = K[0, 0]."""
    planner, plan = _planner(planner), _plan(plan)
    if not isinstance(phantom, Phantom):
        raise PanoramaError(f"phantom must be a Phantom (marker_phantom), got {phantom!r}")
    sigmas = real_array(sigmas, "sigmas", (None, 2), error=PanoramaError, unit="mm, deg")
    if np.any(sigmas < 0) or np.any(sigmas[:, 0] > MAX_DISTANCE * 1e3) or np.any(sigmas[:, 1] > 180.0):
        raise PanoramaError(f"sigmas must be (σ_mm, σ_deg) pairs within [0, {MAX_DISTANCE * 1e3:g}] mm and "
                            f"[0, 180] deg, got {sigmas.tolist()}")
    trials = integer(trials, "trials", low=1, high=MAX_TRIALS, error=PanoramaError)
    rng = np.random.default_rng(integer(seed, "seed", low=0, error=PanoramaError))
    poses = [planner.system.fk(s.q, check_units=False) for s in plan.shots]
    H = [s.H for s in plan.shots]
    depth = float(np.median((phantom.points - planner.P_ref[:3, 3]) @ planner.P_ref[:3, 2]))
    f = planner.K[0, 0]
    rows = []
    for sigma_mm, sigma_deg in sigmas:
        errors = []
        for _ in range(trials):
            noisy = [perturb(T, rng, sigma_mm * 1e-3, np.radians(sigma_deg)) for T in poses]
            err = _stitch_errors(planner.K, planner.size, noisy, H, planner.P_ref, phantom.points)
            errors.append(err[~np.isnan(err)])
        errors = np.concatenate(errors)
        rows.append(dict(sigma_mm=sigma_mm, sigma_deg=sigma_deg, rms_px=float(np.sqrt(np.mean(errors ** 2))),
                         max_px=float(errors.max()), rotation_px=float(f * np.radians(sigma_deg)),
                         translation_px=float(f * sigma_mm * 1e-3 / depth)))
    return rows
