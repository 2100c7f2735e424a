"""Chapter 3's quantitative stitching results (Tables 3.1 and 3.2), under the one error model.

**Table 3.1** (§3.4.1): the three-plane phantom of spherical markers (:func:`carmkin.panorama.phantom.
marker_phantom`, planes 40 mm apart: 8 cm deep) on the table; two X-ray images stitched parallax-free —
the first, then one rotated about the source by about 5° ("the X-ray source undergoes very limited
rotations (around 5°)") along the table, reached by guided manual moves (§4.4.4 planner on the model,
as in :mod:`.stitching`); the second warped by its planned ``H = K R K⁻¹``; the error is the distance
between corresponding centroids of the markers both images see, without and with the Virtual Detector
Plane (:func:`~.measure.xray_points`: the C-arm's sag and its correction by the four mirror markers).
Two procedures, as in the seed.

**Table 3.2** (§3.4.1): a flat pattern of spherical markers parallel to the marker pattern at a measured
distance, carrying 240 mm, 120 mm, 90° and 180° (layout, an assumption: A, B, C on a line 120 mm apart,
D 15 mm beside B: AC = 240 mm, AB = 120 mm, ∠ABD = 90°, ∠ABC = 180°). A panorama covering it is made (A)
parallax-free with VDP, (B) parallax-free without VDP and (C) by one-plane stitching: the C-arm kept in its
calibrated orientation (the zero joints of the rotations), the table translated along its axis between
images, each image warped by the homography of the phantom plane (eq. 4.17) from the two camera readings
and the measured plane. The distances and angles are measured on the panorama by back-projection onto
the plane (eq. 3.17). One procedure, as in the seed.

**Protocols** (:data:`PROTOCOLS`). ``"chapter3"``, as §3.3.4.2 states it: the operator rotates the C-arm
towards the planned view (one move per rotational joint, read on the camera; no stop threshold), then the
table is moved until the camera-measured source translation from the first image is below
:data:`COMPENSATION_THRESHOLD` (1 mm), and the image is warped by ``H = K R K⁻¹`` with ``R`` the *measured*
rotation between the two camera readings after compensation (:func:`acquire_compensated`). The preset's
table moves along one axis only: the C-arm's prismatic joints (vertical, horizontal) make the rest of the
source–table translation (the same relative motion). ``"chapter4"``: chapter 4's guidance (planner,
2 mm / 0.5° stop, planned homography, :func:`.stitching.acquire`) — the default before issue 31, kept
beside for comparison.

Lengths in m, angles in rad inside; tables in px, mm and degrees.
"""

from __future__ import annotations

import math

import numpy as np

from carmkin.errors import CarmkinError, SimulationError, UnreachablePanoramaError
from carmkin.seed import SEED_TABLE_3_1, SEED_TABLE_3_2

from .error_model import ErrorModel, count, generator
from .repositioning import build_model, check_room, make_room, statistics
from .stitching import (
    _in_image,
    acquire,
    check_overlap,
    outward_aims,
    phantom_frame,
    plane_in_panorama,
    reference_configuration,
)

#: The second image of Table 3.1 is rotated by this much about the source (source: §3.4.1 "around 5°").
ROTATION = math.radians(5.0)
#: Three-plane phantom: planes 40 mm apart (source: "8cm depth"), markers every 20 mm along, three across
#: 15 mm apart, the first plane 20 mm above the table top (assumption).
PHANTOM = dict(length=0.25, spacing=0.02, lateral=(-0.015, 0.0, 0.015), planes=3, gap=0.04, lift=0.02)
#: Table 3.2 pattern in its frame (m): A, B, C along x, D beside B; its plane's distance above the marker
#: pattern (assumption, as in :mod:`.stitching`).
METRIC_POINTS = np.array([[-0.12, 0.0, 0.0], [0.0, 0.0, 0.0], [0.12, 0.0, 0.0], [0.0, 0.015, 0.0]])
METRIC_ABOVE_PATTERN = 0.07
ATTEMPTS = 20
#: §3.3.4.2: the table is moved until the source translation the camera measures is below 1 mm (source).
COMPENSATION_THRESHOLD = 0.001
#: Camera readings (each followed by one compensating move of every prismatic joint) before a compensation
#: counts as failed.
COMPENSATION_STEPS = 100
#: The procedures of Tables 3.1 and 3.2 A/B (module docstring).
PROTOCOLS = ("chapter3", "chapter4")


def _protocol(protocol: str) -> str:
    if not isinstance(protocol, str) or protocol not in PROTOCOLS:
        raise SimulationError(f"protocol must be one of {PROTOCOLS}, got {protocol!r}")
    return protocol


def _prismatic_jacobian(built, q) -> np.ndarray:
    """(3, k) derivative of the model's source position (table frame) in its prismatic joints at ``q``:
    they are linear in the position (a central difference is exact to rounding)."""
    columns = []
    for j in np.flatnonzero(built.prismatic):
        dq = np.zeros(built.nq)
        dq[j] = 1e-3
        columns.append((built.fk(q + dq)[:3, 3] - built.fk(q - dq)[:3, 3]) / 2e-3)
    return np.column_stack(columns)


def acquire_compensated(room, rng: np.random.Generator, q_first, principal_points_of):
    """The images of one panorama by §3.3.4.2's protocol (module docstring): ``(planner, reading, images)``
    like :func:`.stitching.acquire`, each image's ``H`` from the measured rotation after compensation.
    A camera that loses the pattern on the way raises :class:`UnreachablePanoramaError` (the callers draw
    another first configuration, as for a view beyond the joint ranges)."""
    try:
        return _acquire_compensated(room, rng, q_first, principal_points_of)
    except UnreachablePanoramaError:
        raise
    except SimulationError:
        raise
    except CarmkinError as exc:  # the pattern out of the camera's view, no pose
        raise UnreachablePanoramaError(f"the camera lost the pattern: {exc}") from None


def _acquire_compensated(room, rng, q_first, principal_points_of):
    from carmkin.imaging import rotation_homography
    from carmkin.panorama import PanoramaPlanner
    from carmkin.reposition.guidance import read_joints

    from .measure import camera_reading

    system, operator = room.system, room.model.operator()
    built, readout, reading = build_model(room, q_first, rng)
    planner = PanoramaPlanner(built, q_reference=readout, P_ref=reading.T)
    images, q, q_last = [(system.fk(q_first), np.eye(3))], np.asarray(q_first, dtype=float), readout
    revolute = [j for j in room.config.guidance.move_order(built) if not system.prismatic[j]]
    for p in principal_points_of(planner, reading):
        _, R = planner.rotation_for(p)
        q_goal = read_joints(built, planner.target_pose(R), q_last, system.split(q)[1])
        if np.any(q_goal < built.lower) or np.any(q_goal > built.upper):
            raise UnreachablePanoramaError(f"image {len(images) + 1} needs joints beyond their ranges")
        for j in revolute:  # rotate towards the view, each joint read on the camera before its move
            now = camera_reading(room.world, system.fk(q), room.T_source_camera, rng)
            q_last = read_joints(built, now.T, q_last, system.split(q)[1])
            q = operator.execute(system, q, j, float(q_goal[j] - q_last[j]), rng)
        for _ in range(COMPENSATION_STEPS):  # move the table until the source translation is below 1 mm
            now = camera_reading(room.world, system.fk(q), room.T_source_camera, rng)
            delta = now.T[:3, 3] - reading.T[:3, 3]
            if np.linalg.norm(delta) < COMPENSATION_THRESHOLD:
                break
            q_last = np.clip(read_joints(built, now.T, q_last, system.split(q)[1]), built.lower, built.upper)
            move = np.linalg.lstsq(_prismatic_jacobian(built, q_last), -delta, rcond=None)[0]
            for j, m in zip(np.flatnonzero(system.prismatic), move):
                q = operator.execute(system, q, int(j), float(m), rng)
        else:
            raise SimulationError(f"image {len(images) + 1}: source translation not below "
                                  f"{1e3 * COMPENSATION_THRESHOLD:g} mm after {COMPENSATION_STEPS} compensations")
        images.append((system.fk(q), rotation_homography(planner.K, reading.T[:3, :3].T @ now.T[:3, :3])))
    return planner, reading, images


def _acquire(protocol: str):
    return acquire_compensated if _protocol(protocol) == "chapter3" else acquire


def _first_and_phantom(room, rng):
    from carmkin.panorama import PanoramaPlanner
    from carmkin.panorama.phantom import marker_phantom

    q_first = reference_configuration(room.system, rng)
    return q_first, marker_phantom(PanoramaPlanner(room.system, q_reference=q_first), **PHANTOM).points


def overlap_errors(room, rng: np.random.Generator, protocol: str = "chapter3") -> tuple[np.ndarray, np.ndarray]:
    """One Table 3.1 procedure (``protocol``: :data:`PROTOCOLS`): centroid distances (px) in the overlap,
    (without VDP, with VDP)."""
    from carmkin.imaging import apply_homography

    from .measure import xray_points

    system, model = room.system, room.model

    def second(planner, reading):
        direction = planner.default_direction()
        return [planner.K[:2, :2] @ (math.tan(ROTATION) * direction[:2]) + planner.K[:2, 2]]

    for _ in range(ATTEMPTS):
        q_first, points = _first_and_phantom(room, rng)
        try:
            _, _, images = _acquire(protocol)(room, rng, q_first, second)
            break
        except UnreachablePanoramaError:
            continue
    else:
        raise SimulationError(f"no first configuration in {ATTEMPTS} draws allows the second image")
    (T1, _), (T2, H2) = images
    both = _in_image(system, T1, points) & _in_image(system, T2, points)
    out = []
    for vdp in (False, True):
        m1 = xray_points(system, T1, points[both], rng, model.xray_noise_px, model.sag, vdp)
        m2 = apply_homography(H2, xray_points(system, T2, points[both], rng, model.xray_noise_px, model.sag, vdp))
        out.append(np.linalg.norm(m2 - m1, axis=1))
    return out[0], out[1]


def table_3_1(system, model: ErrorModel = ErrorModel(), procedures: int = 2, seed: int = 0, guidance=None,
              protocol: str = "chapter3") -> dict:
    """Table 3.1's rows: procedure -> ((mean, std, markers) without VDP, (...) with VDP), and overall."""
    protocol = _protocol(protocol)
    procedures = count(procedures, "procedures")
    rng = generator(seed)
    room = make_room(system, model, rng, guidance)
    runs, rows = [], {}
    for k in range(procedures):
        runs.append(overlap_errors(room, rng, protocol))
        rows[f"#{k + 1}"] = tuple((*statistics(e)[:2], e.size) for e in runs[-1])
    rows["overall"] = tuple((*statistics(np.concatenate([r[i] for r in runs]))[:2],
                             sum(r[i].size for r in runs)) for i in (0, 1))
    return rows


def format_table_3_1(rows: dict) -> str:
    lines = [f"{'Table 3.1':<10}{'without VDP: simulated':>26}{'seed':>22}{'with VDP: simulated':>26}{'seed':>22}"]
    for key, (without, with_) in rows.items():
        s = SEED_TABLE_3_1.get(key)
        cells = [f"{without[0]:8.2f} ± {without[1]:4.2f} ({without[2]:2d})"]
        cells.append(f"{s[0][0]:8.2f} ± {s[0][1]:4.2f} ({s[0][2]:2d})" if s else "")
        cells.append(f"{with_[0]:8.2f} ± {with_[1]:4.2f} ({with_[2]:2d})")
        cells.append(f"{s[1][0]:8.2f} ± {s[1][1]:4.2f} ({s[1][2]:2d})" if s else "")
        lines.append(f"{key:<10}{cells[0]:>26}{cells[1]:>22}{cells[2]:>26}{cells[3]:>22}")
    return "\n".join(lines)


def _measure(world_points) -> dict:
    """The four Table 3.2 values (mm, degrees) from the back-projected A, B, C, D."""
    a, b, c, d = world_points

    def angle(u, v):
        return math.degrees(math.acos(np.clip(u @ v / (np.linalg.norm(u) * np.linalg.norm(v)), -1.0, 1.0)))

    return {"240 mm": 1e3 * float(np.linalg.norm(c - a)), "120 mm": 1e3 * float(np.linalg.norm(b - a)),
            "90 deg": angle(a - b, d - b), "180 deg": angle(a - b, c - b)}


def metric_measurements(room, rng: np.random.Generator, overlap: float = 0.1, protocol: str = "chapter3") -> dict:
    """One Table 3.2 procedure: method ("A", "B", "C") -> the four measured values (mm, degrees); A and B
    by ``protocol`` (:data:`PROTOCOLS`)."""
    protocol = _protocol(protocol)
    check_room(room, rng)
    overlap = check_overlap(overlap)
    system, model = room.system, room.model
    offset = METRIC_ABOVE_PATTERN + model.plane_distance * rng.normal()

    def aims_of(planner, reading):
        n, d = plane_in_panorama(room, reading, offset)
        direction = planner.default_direction()
        aims = outward_aims(planner, direction, d / n[2], 0.14, overlap)
        return [planner.principal_point_of(s, direction, d / n[2]) for s in aims]

    for _ in range(ATTEMPTS):
        try:
            return _metric_attempt(room, rng, offset, aims_of, protocol)
        except UnreachablePanoramaError:  # a planned image beyond the joint ranges, or a marker in no image: elsewhere
            continue
    raise SimulationError(f"no first configuration in {ATTEMPTS} draws has its panoramas within the ranges")


def _metric_attempt(room, rng, offset, aims_of, protocol: str = "chapter3") -> dict:
    from carmkin.imaging import back_project, homography_between

    from .measure import camera_reading

    system, model = room.system, room.model
    q_first = reference_configuration(system, rng)
    T_pattern = phantom_frame(room, system.fk(q_first))
    T_pattern[:3, 3] += (METRIC_ABOVE_PATTERN - 0.07) * T_pattern[:3, 2]
    points = METRIC_POINTS @ T_pattern[:3, :3].T + T_pattern[:3, 3]
    planner, reading, images = _acquire(protocol)(room, rng, q_first, aims_of)
    n, d = plane_in_panorama(room, reading, offset)
    out = {}
    for method, vdp in (("A", True), ("B", False)):
        out[method] = _measure(back_project(planner.K, _panorama(system, images, points, rng, model, vdp), n, d))
    # C: one-plane stitching, the C-arm's rotations at their calibrated zero, the table translated
    q = q_first.copy()
    for name in ("wigwag", "angular", "orbital"):
        q[system.joint_names.index(name)] = 0.0
    first = camera_reading(room.world, system.fk(q), room.T_source_camera, rng)
    n1, d1 = plane_in_panorama(room, first, offset)
    M = room.world.measured_mount
    normal = M[:3, 2] * np.sign(M[:3, 2] @ np.array([0.0, -1.0, 0.0]))
    n_table, d_table = normal, float(normal @ (M[:3, 3] + offset * normal))
    step = 0.9 * (d1 / n1[2]) * system.carm.detector_width / system.carm.source_to_detector
    one_plane, d0 = [], system.joint_names.index("table_translation")
    for k in (0, 1, -1, 2, -2, 3, -3):
        qk = q.copy()
        qk[d0] = q[d0] - k * step + (model.operator_translation * rng.normal() if k else 0.0)
        now = first if k == 0 else camera_reading(room.world, system.fk(qk), room.T_source_camera, rng)
        one_plane.append((system.fk(qk), homography_between(planner.K, first.T, now.T, n_table, d_table)))
    out["C"] = _measure(back_project(planner.K, _panorama(system, one_plane, points, rng, model, False), n1, d1))
    return out


def _panorama(system, images, points, rng, model, vdp):
    """Panorama pixels (N, 2) of ``points``: each from the first image (in order) that sees it."""
    from carmkin.imaging import apply_homography

    from .measure import xray_points

    out = np.full((len(points), 2), np.nan)
    for T, H in images:
        seen = _in_image(system, T, points) & np.isnan(out[:, 0])
        if seen.any():
            out[seen] = apply_homography(H, xray_points(system, T, points[seen], rng, model.xray_noise_px,
                                                        model.sag, vdp))
    if np.isnan(out).any():
        raise UnreachablePanoramaError("a marker of the metric pattern is in no image of the panorama")
    return out


def table_3_2(system, model: ErrorModel = ErrorModel(), seed: int = 0, guidance=None, protocol: str = "chapter3") -> dict:
    """Table 3.2: method -> measured values (one procedure, as in the seed; A and B by ``protocol``)."""
    protocol = _protocol(protocol)
    rng = generator(seed)
    return metric_measurements(make_room(system, model, rng, guidance), rng, protocol=protocol)


def format_table_3_2(result: dict) -> str:
    lines = [f"{'Table 3.2':<10}" + "".join(f"{m + ' sim':>10}{m + ' seed':>10}" for m in "ABC")]
    for k, key in enumerate(SEED_TABLE_3_2):
        lines.append(f"{key:<10}" + "".join(f"{result[m][key]:10.2f}{SEED_TABLE_3_2[key][i]:10.2f}"
                                             for i, m in enumerate("ABC")))
    lines.append("A: parallax-free with VDP, B: parallax-free without VDP, C: one-plane stitching")
    return "\n".join(lines)

