"""§4.6.3 (Table 4.6): parallax-free panoramas of a planar phantom, under the one error model.

One procedure, as the seed describes it, in a room of :mod:`.repositioning`:

* the **phantom**: spherical markers (their centres) on a 440 × 80 mm plane "parallel to the marker pattern"
  at a distance from it that is "measured manually" (the error model's ``plane_distance``); the markers sit
  every :data:`SPACING` along the length in five rows 20 mm apart (assumption: the seed gives the size,
  not the layout); the long side along the table;
* the **first X-ray image** at a random configuration around the planner's reference (§4.4.4 step 1): the
  model is built there (eq. 4.3) from the camera reading and the joint read-out; the panorama frame is that
  image, ``P_ref`` the camera reading;
* the **other two images**: the §4.4.4 algorithm (:class:`carmkin.panorama.PanoramaPlanner` on the
  model: principal points along the phantom's line, ``R``, ``H = K R K⁻¹``, target ``P_ref [R 0; 0 1]``), goal
  joints by the model's closed-form IK, reached by the guided manual moves of
  :func:`~.repositioning.guide`; each image is warped into the panorama with its planned ``H``;
* the **measurement**: marker centroids extracted in each X-ray image (true pose, sag, extraction noise,
  :func:`~.measure.xray_points`), mapped into the panorama (a marker seen by several images: the first);
* the **ground truth**: ``P = K[R|t]`` from the centroids of the first image and the phantom's geometry
  (PnP, :func:`carmkin.reposition.pose.solve_pose`); all markers projected by it; markers of the first image
  excluded from the image error;
* **metric measurements**: panorama points back-projected (eq. 3.17) onto the phantom plane known from
  the camera's reading of the pattern and the measured distance; five distances of 360 mm and five angles
  of 90° between markers.

Lengths in m, angles in rad inside; tables in px, mm and degrees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import CarmkinError, SimulationError, UnreachablePanoramaError
from carmkin.seed import SEED_TABLE_4_6

from .error_model import ErrorModel
from .measure import xray_points
from .repositioning import build_model, check_room, guide, repeat, statistics

#: Phantom: 440 × 80 mm (source: §4.6.3); marker spacing along it and across (assumption).
LENGTH, WIDTH, SPACING, ROWS = 0.44, 0.08, 0.02, 5
#: Distance of the phantom plane above the pattern (m): the table top (60 mm, preset) plus 10 mm (assumption).
PHANTOM_ABOVE_PATTERN = 0.07
#: The measured distances and angles: 360 mm (18 spacings) and 90° (source: §4.6.3).
DISTANCE = 0.36
#: The first image's nominal configuration (assumption: the C-arm low, beam up under the phantom, so the
#: camera sees enough of the pattern) and its random spread (assumption).
REFERENCE_NOMINAL = {"table_translation": 0.0, "vertical": 0.12, "horizontal": 0.1, "wigwag": 0.0,
                     "angular": 0.0, "orbital": 0.0}
REFERENCE_SPREAD = {"table_translation": 0.05, "vertical": 0.03, "horizontal": 0.03,
                    "wigwag": math.radians(3), "angular": math.radians(10), "orbital": math.radians(10)}


#: First configurations tried per procedure before giving up (one whose panorama needs joints beyond
#: their ranges is replaced: the surgeon would position the C-arm elsewhere).
ATTEMPTS = 20


@dataclass
class Procedure:
    """One panorama: ``image_errors`` (px) of the markers outside the first image, ``distance_errors`` (m),
    ``angle_errors`` (rad), ``success`` and ``reason``, ``images`` taken."""

    success: bool
    reason: str | None = None
    image_errors: np.ndarray = None
    distance_errors: np.ndarray = None
    angle_errors: np.ndarray = None
    images: int = 0


def reference_configuration(system, rng: np.random.Generator) -> np.ndarray:
    """The first image's true joints: :data:`REFERENCE_NOMINAL` plus :data:`REFERENCE_SPREAD`, in range
    (a motorized table's extra joints at mid-range)."""
    q = 0.5 * (system.lower + system.upper)
    for name, value in REFERENCE_NOMINAL.items():
        if name in system.joint_names:
            q[system.joint_names.index(name)] = value + rng.uniform(-1, 1) * REFERENCE_SPREAD[name]
    return np.clip(q, system.lower, system.upper)


#: Largest overlap of neighbouring shots (fraction of the inner one's interval): at 1 a shot adds nothing and the
#: panorama would never reach its length.
MAX_OVERLAP = 0.9


def check_overlap(overlap) -> float:
    """``overlap`` as a fraction in [0, :data:`MAX_OVERLAP`], else :class:`SimulationError` naming it."""
    from carmkin.validation import real_scalar

    return real_scalar(overlap, "overlap", error=SimulationError, low=0.0, high=MAX_OVERLAP)


def outward_aims(planner, direction, distance: float, half_length: float, overlap: float) -> list[float]:
    """Aims (m along ``direction`` at ``distance``) of the shots beside the first image (aim 0), placed
    outwards on both sides, each overlapping its inner neighbour by ``overlap`` of that one's interval,
    until ``±half_length`` is covered (the §4.4.4 planner's :meth:`extent` on the model)."""
    from scipy.optimize import brentq

    aims = []
    for side in (1.0, -1.0):
        s, (lo, hi) = 0.0, planner.extent(0.0, direction, distance)
        while (hi if side > 0 else -lo) < half_length:
            edge = hi - overlap * (hi - lo) if side > 0 else lo + overlap * (hi - lo)
            k = 0 if side > 0 else 1

            def gap(a, edge=edge, k=k):
                return planner.extent(a, direction, distance)[k] - edge
            s = brentq(gap, s, s + side * 4 * (hi - lo), xtol=1e-12)
            lo, hi = planner.extent(s, direction, distance)
            aims.append(s)
    return aims


def phantom_frame(room, T_first) -> np.ndarray:
    """The phantom's pose (4, 4) in the table frame: its plane parallel to the true pattern at
    :data:`PHANTOM_ABOVE_PATTERN` towards the table top, centred where the first image's axis meets it, its
    x axis along the table (Z0) projected on the plane."""
    M = room.world.T_table_marker
    n = M[:3, 2] * np.sign(M[:3, 2] @ np.array([0.0, -1.0, 0.0]))  # towards the table top (−Y0, up)
    origin = M[:3, 3] + PHANTOM_ABOVE_PATTERN * n
    p, axis = T_first[:3, 3], T_first[:3, 2]
    centre = p + ((origin - p) @ n) / (axis @ n) * axis
    x = np.array([0.0, 0.0, 1.0]) - n[2] * n
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(n, x), n, centre
    return T


#: Largest phantom side (m) and most markers of :func:`phantom_points` (a table-top phantom; metres read as
#: millimetres would ask for millions).
MAX_PHANTOM_SIZE = 10.0
MAX_PHANTOM_MARKERS = 1_000_000


def phantom_points(length: float = LENGTH, spacing: float = SPACING, rows: int = ROWS, width: float = WIDTH) -> np.ndarray:
    """Marker centres (N, 3) in the phantom frame (m): columns every ``spacing`` along x, ``rows`` across.
    ``length`` > 0, ``spacing`` in (0, ``length``], ``width`` ≥ 0 (m), ``rows`` ≥ 1 (≥ 2 when ``width`` > 0);
    else :class:`SimulationError` naming the argument (issue 41: zero or negative sizes gave an empty or
    degenerate phantom, ``spacing=0`` a ZeroDivisionError)."""
    from carmkin.validation import integer, real_scalar

    length = real_scalar(length, "length", error=SimulationError, low=0.0, high=MAX_PHANTOM_SIZE, unit="m")
    spacing = real_scalar(spacing, "spacing", error=SimulationError, low=0.0, high=MAX_PHANTOM_SIZE, unit="m")
    width = real_scalar(width, "width", error=SimulationError, low=0.0, high=MAX_PHANTOM_SIZE, unit="m")
    rows = integer(rows, "rows", low=1, high=MAX_PHANTOM_MARKERS, error=SimulationError)
    if length <= 0 or spacing <= 0 or spacing > length:
        raise SimulationError(f"length and spacing must be > 0 with spacing <= length (m), got length {length:g}, "
                              f"spacing {spacing:g}")
    if rows * (length / spacing + 1) > MAX_PHANTOM_MARKERS:
        raise SimulationError(f"spacing {spacing:g} m over length {length:g} m and rows {rows} give more than "
                              f"{MAX_PHANTOM_MARKERS} markers")
    if (rows == 1) != (width == 0):
        raise SimulationError(f"rows and width must agree: one row has width 0, several a width > 0 (m), got rows "
                              f"{rows}, width {width:g}")
    xs = np.arange(0.0, length + 1e-12, spacing) - length / 2
    ys = np.linspace(-width / 2, width / 2, rows)
    return np.array([(x, y, 0.0) for y in ys for x in xs])


def measurement_sets(points: np.ndarray, seen, count: int = 5, distance: float = DISTANCE):
    """``count`` marker pairs ``distance`` apart along a row and ``count`` right-angle triples (a, b, c:
    the angle at b between b→a along a row and b→c to the next row), among the markers ``seen`` (N,)
    bool in the panorama, middle rows first; as index arrays (k, 2) and (k, 3)."""
    rows = np.unique(np.round(points[:, 1], 9))
    order = sorted(range(len(points)), key=lambda k: (abs(points[k, 1]), points[k, 0]))
    pairs, triples = [], []
    for a in order:
        b = [k for k in range(len(points)) if seen[a] and seen[k] and abs(points[k, 0] - points[a, 0] - distance) < 1e-9
             and abs(points[k, 1] - points[a, 1]) < 1e-9]
        if not b:
            continue
        if len(pairs) < count:
            pairs.append((a, b[0]))
        row = int(np.argmin(np.abs(rows - points[b[0], 1])))
        for step in (1, -1):
            if 0 <= row + step < len(rows):
                c = [k for k in range(len(points)) if seen[k] and abs(points[k, 0] - points[b[0], 0]) < 1e-9
                     and abs(points[k, 1] - rows[row + step]) < 1e-9]
                if c and len(triples) < count:
                    triples.append((a, b[0], c[0]))
                    break
    return np.array(pairs, dtype=int).reshape(-1, 2), np.array(triples, dtype=int).reshape(-1, 3)


def _in_image(system, T, points) -> np.ndarray:
    from carmkin.imaging import in_image, project

    depth = (points - T[:3, 3]) @ T[:3, 2]
    return in_image(project(system.carm.intrinsics(), T, points, allow_behind=True),
                    system.carm.detector_columns, system.carm.detector_rows) & (depth > 0)


def acquire(room, rng: np.random.Generator, q_first, principal_points_of, vdp: bool = False):
    """The X-ray images of one panorama: the first at the true joints ``q_first``, then one per principal
    point returned by ``principal_points_of(planner, reading)`` (the first image's camera reading), each reached by guided moves. Returns
    ``(planner, reading, images)`` with ``images`` a list of (true pose, planned ``H``) or raises
    :class:`SimulationError` when a move is not completed."""
    from carmkin.imaging import rotation_homography
    from carmkin.panorama import PanoramaPlanner
    from carmkin.reposition.guidance import read_joints

    system = room.system
    built, readout, reading = build_model(room, q_first, rng)
    planner = PanoramaPlanner(built, q_reference=readout, P_ref=reading.T)
    images, q, q_last, goals = [(system.fk(q_first), np.eye(3))], q_first, readout, []
    for p in principal_points_of(planner, reading):  # planned beforehand (§4.4.4), on the model
        _, R = planner.rotation_for(p)
        goals.append((R, read_joints(built, planner.target_pose(R), q_last, system.split(q)[1])))
        q_last = goals[-1][1]
        if np.any(q_last < built.lower) or np.any(q_last > built.upper):
            raise UnreachablePanoramaError(f"image {len(goals) + 1} needs joints beyond their ranges")
    q_last = readout
    for R, q_goal in goals:
        moves = guide(room, built, q_goal, q, q_last, rng)
        if not moves.done:
            raise SimulationError(f"image {len(images) + 1}: {moves.reason}")
        q, q_last = moves.q, q_goal
        images.append((system.fk(q), rotation_homography(planner.K, R)))
    return planner, reading, images


def stitched(system, images, points, rng: np.random.Generator, model: ErrorModel, vdp: bool = False):
    """(panorama pixels (N, 2), index of the first image seeing each marker, −1 when none) of ``points``
    (table frame) extracted in each image and warped by its ``H``; NaN where no image sees a marker."""
    from carmkin.imaging import apply_homography

    out, first = np.full((len(points), 2), np.nan), np.full(len(points), -1)
    for k, (T, H) in enumerate(images):
        seen = _in_image(system, T, points) & (first < 0)
        if seen.any():
            m = xray_points(system, T, points[seen], rng, model.xray_noise_px, model.sag, vdp)
            out[seen] = apply_homography(H, m)
            first[seen] = k
    return out, first


def plane_in_panorama(room, reading, offset: float) -> tuple[np.ndarray, float]:
    """(n, d) of the plane ``offset`` (m) above the pattern towards the table top, in the panorama (first
    source) frame as the system knows it: the calibrated pattern seen in the camera reading ``reading``."""
    M = room.world.measured_mount
    n = M[:3, 2] * np.sign(M[:3, 2] @ np.array([0.0, -1.0, 0.0]))
    o = M[:3, 3] + offset * n
    R, p = reading.T[:3, :3], reading.T[:3, 3]
    return R.T @ n, float(n @ (o - p))


def run_procedure(room, rng: np.random.Generator, overlap: float = 0.1) -> Procedure:
    """One §4.6.3 procedure in ``room`` (see the module docstring); ``overlap`` in [0, :data:`MAX_OVERLAP`]."""
    from carmkin.imaging import back_project, project
    from carmkin.reposition.pose import solve_pose

    check_room(room, rng)
    overlap = check_overlap(overlap)

    system, model = room.system, room.model
    measured_offset = PHANTOM_ABOVE_PATTERN + model.plane_distance * rng.normal()

    def principal_points_of(planner, reading):
        n, d = plane_in_panorama(room, reading, measured_offset)
        distance = d / n[2]  # along the first image's axis to the phantom plane
        direction = planner.default_direction()
        aims = outward_aims(planner, direction, distance, LENGTH / 2, overlap)
        return [planner.principal_point_of(s, direction, distance) for s in aims]

    for _ in range(ATTEMPTS):
        q_first = reference_configuration(system, rng)
        T_phantom = phantom_frame(room, system.fk(q_first))
        local = phantom_points()
        points = local @ T_phantom[:3, :3].T + T_phantom[:3, 3]
        try:
            planner, reading, images = acquire(room, rng, q_first, principal_points_of)
            break
        except UnreachablePanoramaError:
            continue
        except CarmkinError as exc:
            return Procedure(False, str(exc))
    else:
        return Procedure(False, f"no first configuration in {ATTEMPTS} draws has its panorama within the ranges")
    pano, first = stitched(system, images, points, rng, model)
    in_first = first == 0
    if in_first.sum() < 4:
        return Procedure(False, "fewer than 4 markers in the first image")
    try:
        estimate = solve_pose(local[in_first], pano[in_first], planner.K, sigma_px=model.xray_noise_px)
    except CarmkinError as exc:
        return Procedure(False, f"ground truth: {exc}")
    truth = project(planner.K, estimate.T, local)  # the synthetic ground-truth panorama, P = K[R|t]
    image_errors = np.linalg.norm(pano - truth, axis=1)[(first > 0)]
    n, d = plane_in_panorama(room, reading, measured_offset)
    world = np.full((len(points), 3), np.nan)
    ok = first >= 0
    world[ok] = back_project(planner.K, pano[ok], n, d)
    pairs, triples = measurement_sets(local, ok)
    distances = np.linalg.norm(world[pairs[:, 1]] - world[pairs[:, 0]], axis=1) - DISTANCE
    u, v = world[triples[:, 0]] - world[triples[:, 1]], world[triples[:, 2]] - world[triples[:, 1]]
    cos = np.sum(u * v, axis=1) / (np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1))
    angles = np.arccos(np.clip(cos, -1.0, 1.0)) - math.pi / 2
    return Procedure(True, None, image_errors, np.abs(distances), np.abs(angles), len(images))


def run(system, model: ErrorModel = ErrorModel(), procedures: int = 5, seed: int = 0, guidance=None) -> list[Procedure]:
    """``procedures`` panoramas in one room (numpy seed ``seed``; ``guidance`` as in :func:`~.repositioning.make_room`)."""
    return repeat(run_procedure, system, model, procedures, seed, guidance, "procedures")


def table(procedures: list[Procedure]) -> dict:
    """Table 4.6's rows per procedure and overall: (image mean, std px, markers, distance mean, std mm,
    angle mean, std deg); failed procedures are listed with NaN."""
    out, ok = {}, [p for p in procedures if p.success]
    for k, p in enumerate(procedures, 1):
        out[f"#{k}"] = _row([p]) if p.success else (math.nan,) * 7
    out["overall"] = _row(ok) if ok else (math.nan,) * 7
    return out


def _row(ps) -> tuple:
    image = np.concatenate([p.image_errors for p in ps])
    dist = 1e3 * np.concatenate([p.distance_errors for p in ps])
    angle = np.degrees(np.concatenate([p.angle_errors for p in ps]))
    return (statistics(image)[0], statistics(image)[1], int(image.size), statistics(dist)[0], statistics(dist)[1],
            statistics(angle)[0], statistics(angle)[1])


def format_table(rows: dict, seed: dict = SEED_TABLE_4_6) -> str:
    """Table 4.6 simulated beside the seed's, row by row."""
    lines = [f"{'Table 4.6':<9}{'image error px (markers)':>32}{'360 mm distances, mm':>30}{'90° angles, deg':>28}",
             f"{'':<9}{'simulated':>16}{'seed':>16}{'simulated':>15}{'seed':>15}{'simulated':>14}{'seed':>14}"]
    for key, r in rows.items():
        s = seed.get(key, seed["overall"] if key == "overall" else (math.nan,) * 7)
        lines.append(f"{key:<9}{r[0]:6.1f} ± {r[1]:3.1f} ({r[2]:3.0f}){s[0]:5.1f} ± {s[1]:3.1f} ({s[2]:3d})"
                     f"{r[3]:8.2f} ± {r[4]:4.2f}{s[3]:8.2f} ± {s[4]:4.2f}{r[5]:7.2f} ± {r[6]:4.2f}{s[5]:7.2f} ± {s[6]:4.2f}")
    return "\n".join(lines)
