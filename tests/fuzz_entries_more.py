"""More fuzz entry points: the rest of imaging (homographies between poses, borders, distances, projection
matrices of a configuration), DeepDRR's MobileCArm, singularity maps and classification, panorama shots,
phantom noise, the validity report, DICOM XA angles, and the repositioning camera.
"""

from __future__ import annotations

import math

import fuzz_geometry as g
import numpy as np
from fuzz_engine import Case, maybe_junk
from fuzz_entries_systems import MOTORIZED, PRESET, _q, _system

from carmkin import imaging
from carmkin import singularity as sing
from carmkin.interop import simulators as sim


def homography_between(rng):
    K = g.intrinsics(rng)
    T1 = g.pose(rng, scale=0.5)
    T2 = T1.copy()
    T2[:3, :3] = T1[:3, :3] @ g.rotation(rng) if rng.random() < 0.5 else T1[:3, :3]
    T2[:3, 3] += rng.normal(size=3) * rng.choice([0.0, 1e-3, 0.05])
    n = T1[:3, 2]
    d = float(n @ T1[:3, 3] + rng.choice([0.3, 1.0, 5.0]))  # a plane in front of view 1
    pure = rng.random() < 0.3 and np.allclose(T1[:3, 3], T2[:3, 3])
    X = np.array([T1[:3, 3] + (d - n @ T1[:3, 3]) * n + 0.05 * np.cross(n, g.unit(rng)) for _ in range(4)])

    def check(H):
        d1 = (X - T1[:3, 3]) @ T1[:3, 2]
        d2 = (X - T2[:3, 3]) @ T2[:3, 2]
        if np.any(d1 <= 1e-6) or np.any(d2 <= 1e-6):
            return True  # not seen by both views: nothing to compare
        m1, m2 = imaging.project(K, T1, X), imaging.project(K, T2, X)
        mapped = np.column_stack((m2, np.ones(len(m2)))) @ H.T
        return g.close(mapped[:, :2] / mapped[:, 2:], m1, rtol=1e-5, atol=1e-4 * max(1, np.abs(m1).max()))
    args = (K, T1, T2) if pure else (K, T1, T2, n, d)
    return maybe_junk(rng, Case(imaging.homography_between, args, check=check), ("K", "T1", "T2", "n", "d")[:len(args)])


def dehomogenize(rng):
    m = rng.normal(size=(int(rng.integers(1, 6)), 3)) * rng.choice([1e-3, 1.0, 1e5])
    expected = m[:, :2] / m[:, 2:]
    return maybe_junk(rng, Case(imaging.dehomogenize, (m,), check=lambda r: g.close(r, expected, rtol=1e-12)), ("m",))


def image_border(rng):
    w, h, k = int(rng.integers(1, 5000)), int(rng.integers(1, 5000)), int(rng.integers(1, 40))

    def check(b):
        on_edge = (np.isclose(b[:, 0], -0.5) | np.isclose(b[:, 0], w - 0.5) | np.isclose(b[:, 1], -0.5)
                   | np.isclose(b[:, 1], h - 0.5))
        return b.shape == (4 * k + 1, 2) and bool(np.all(on_edge)) and np.array_equal(b[0], b[-1])
    return maybe_junk(rng, Case(imaging.image_border, (w, h, k), check=check), ("columns", "rows", "per_edge"))


def measure_distance(rng):
    K = g.intrinsics(rng)
    d = float(rng.choice([1e-3, 0.5, 5.0]))
    a = np.array([rng.normal() * 0.1 * d, rng.normal() * 0.1 * d, d])
    b = a + np.array([rng.normal(), rng.normal(), 0.0]) * rng.choice([1e-6, 1e-3, 0.1]) * d
    m1, m2 = imaging.project(K, np.eye(4), a), imaging.project(K, np.eye(4), b)
    n = np.array([0.0, 0.0, 1.0])
    return maybe_junk(rng, Case(imaging.measure_distance, (K, m1, m2, n, d), check=lambda r: abs(
        r[0] - np.linalg.norm(a - b)) <= 1e-6 * d), ("K", "m1", "m2", "n", "d"))


def projection_of_configuration(rng):
    system = _system(rng)
    q = _q(rng, system)
    patient = str(rng.choice(list(imaging.projection.PATIENT_POSITIONS)))
    X = g.points_in_front(rng, system.fk(q), 4)

    def check(P):
        T_patient = imaging.patient_pose(patient)
        Xp = (X - T_patient[:3, 3]) @ T_patient[:3, :3]  # the same points in the patient frame
        m = np.column_stack((Xp, np.ones(len(Xp)))) @ P.T
        expected = imaging.project(system.carm.intrinsics(), system.fk(q), X)
        return g.close(m[:, :2] / m[:, 2:], expected, rtol=1e-6, atol=1e-5)
    return maybe_junk(rng, Case(imaging.projection_matrix, (system, q, patient), check=check),
                      ("system", "q", "patient?"))


def mobile_carm(rng):
    system = _system(rng)
    q = _q(rng, system)

    def check(state):
        T = sim.mobile_carm_source_pose(state)
        return g.close(sim.to_metres(T), system.fk(q), atol=1e-9)
    return maybe_junk(rng, Case(sim.deepdrr_mobile_carm, (system, q), check=check), ("system", "q"))


def classify(rng):
    q = _q(rng, PRESET)
    near = float(rng.choice([0.0, 1e-9, math.radians(5)]))

    def check(r):
        b = abs(math.cos(q[4]))
        return ("b" in r.singular_cases) == (math.asin(min(b, 1.0)) <= 1e-9) and r.rank <= 6
    return maybe_junk(rng, Case(sing.classify, (PRESET, q), {"near": near}, check=check), ("system", "q"))


def measure_map(rng):
    system = _system(rng)
    q = _q(rng, system)
    pair = tuple(rng.choice(system.nq, 2, replace=False).tolist())
    n = int(rng.integers(2, 6))
    columns = [system.joint_names.index(name) for name in sing.JOINT_NAMES]

    def check(r):
        from fuzz_entries_systems import _pin_jacobian

        x, y, values = r
        i, j = rng.integers(0, n, 2)
        qq = q.copy()
        qq[pair[0]], qq[pair[1]] = x[j], y[i]
        return abs(values[i, j] - abs(np.linalg.det(_pin_jacobian(system, qq)[:, columns]))) < 1e-9
    return maybe_junk(rng, Case(sing.measure_map, (system, q, pair, n), check=check), ("system", "q", "pair", "n"))


SHOT_PLANNER = None


def panorama_shot(rng):
    global SHOT_PLANNER
    from carmkin.panorama import PanoramaPlanner

    SHOT_PLANNER = SHOT_PLANNER or PanoramaPlanner(PRESET)
    p = SHOT_PLANNER
    pp = g.edge_pixels(rng, p.size, 1)[0]

    def check(shot):
        if not shot.valid:
            return True
        return g.close(shot.target, p.P_ref @ np.block([[shot.R, np.zeros((3, 1))], [np.zeros((1, 3)), 1.0]]),
                       atol=1e-12) and g.close(PRESET.fk(shot.q, check_units=False), shot.target, atol=1e-7)
    return maybe_junk(rng, Case(p.shot, (pp,), {"fallback": False}, check=check), ("principal_point",))


def perturb(rng):
    from carmkin.panorama.phantom import perturb as fn

    T = g.pose(rng)
    zero = rng.random() < 0.3
    sm, sr = (0.0, 0.0) if zero else (float(rng.choice([1e-6, 1e-3])), float(rng.choice([1e-6, 0.01])))
    return maybe_junk(rng, Case(fn, (T, np.random.default_rng(1), sm, sr), check=lambda r: g.is_rotation(r[:3, :3])
                                and (not zero or g.close(r, T, atol=1e-15))), ("T", "rng", "sigma_m", "sigma_rad"))


def validity(rng):
    from carmkin.model.params import JOINT_RANGE_TOLERANCE
    from carmkin.robot import validity as v

    system = _system(rng)
    q = _q(rng, system) + rng.choice([0.0, 1e-3, -1e-3, 2 * JOINT_RANGE_TOLERANCE]) * rng.integers(0, 2, system.nq)
    out = (q < system.lower - JOINT_RANGE_TOLERANCE) | (q > system.upper + JOINT_RANGE_TOLERANCE)
    return maybe_junk(rng, Case(v.check, (system, q), check=lambda r: sorted(system.joint_names.index(j.name)
                                for j in r.joints) == sorted(np.flatnonzero(out).tolist())), ("system", "q"))


def xa_angles(rng):
    from carmkin.interop import dicom

    primary, secondary = rng.uniform(-179, 179), rng.uniform(-89, 89)
    patient = str(rng.choice(list(imaging.projection.PATIENT_POSITIONS)))
    T = dicom.pose_from_xa_angles(primary, secondary, rng.normal(size=3) * 0.1, 0.7, patient)
    return maybe_junk(rng, Case(dicom.xa_angles, (T, patient), check=lambda r: abs(r[0] - primary) < 1e-7 and abs(
        r[1] - secondary) < 1e-7), ("T_source", "patient"))


def project_points(rng):
    from carmkin.reposition import camera

    K, T = g.intrinsics(rng), g.pose(rng)
    X = g.points_in_front(rng, T)
    return maybe_junk(rng, Case(camera.project_points, (K, T, X), check=lambda r: g.close(
        r[0], imaging.project(K, T, X), rtol=1e-9, atol=1e-6)), ("K", "T_frame_camera", "points"))


def view_from_angles(rng):
    from carmkin.interop import dicom
    from carmkin.views import View

    p, s = float(rng.uniform(-180, 180)), float(rng.choice([rng.uniform(-89, 89), 0.0, 45.0]))
    target = rng.normal(size=3) * 0.2
    position = str(rng.choice(["HFS", "FFP", "HFDL", "FFDR"]))
    rotation = None if rng.random() < 0.5 else float(rng.uniform(-180, 180))

    def check(view):
        p2, s2 = view.angles(position)
        ok = abs((p2 - p + 180) % 360 - 180) < 1e-7 and abs(s2 - s) < 1e-7 and g.close(view.target, target)
        if rotation is not None:  # the pose of the view's axes reads back the rotation
            T = np.eye(4)
            x, z = np.array(view.x_axis), view.axis
            T[:3, :3] = np.column_stack((x, np.cross(z, x), z))
            r2 = dicom.xa_angles(T, position)[2]
            ok = ok and abs((r2 - rotation + 180) % 360 - 180) < 1e-7 and abs(x @ z) < 1e-12
        return ok
    return maybe_junk(rng, Case(View.from_angles, (p, s, target, position, None, "", rotation), check=check),
                      ("primary_deg", "secondary_deg", "target", "position"))


def view_from_pose(rng):
    from carmkin.views import View

    T, d = g.pose(rng), float(rng.uniform(0.05, 2.0))

    def check(view):
        return (g.close(view.axis, T[:3, 2]) and g.close(view.x_axis, T[:3, 0])
                and g.close(view.target, T[:3, 3] + d * T[:3, 2]) and view.distance == d)
    return maybe_junk(rng, Case(View.from_pose, (T, d), check=check), ("T_source", "distance"))


def plan_a_view(rng):
    from carmkin.views import View, plan_view
    from carmkin.views.plan import world_for

    view = View.from_angles(float(rng.uniform(-90, 90)), float(rng.uniform(-45, 45)), rng.normal(size=3) * 0.05)
    margin = float(rng.choice([0.0, 0.02, 0.1]))

    def check(plan):
        if not plan.success:
            return bool(plan.reason)
        T = PRESET.fk(plan.q)
        w = np.array(view.target) - T[:3, 3]
        return (g.close(T[:3, 2], view.axis) and float(np.linalg.norm(w - (w @ T[:3, 2]) * T[:3, 2])) < 1e-9
                and world_for(PRESET, None).clearance(plan.q)[0] >= margin)
    return maybe_junk(rng, Case(plan_view, (PRESET, view), {"margin": margin, "nearest": False}, check=check),
                      ("system", "view"))


def sample_some_poses(rng):
    from carmkin import datasets

    prior = ["standard-views", "joint-uniform"][int(rng.integers(0, 2))]
    n, seed = int(rng.integers(1, 20)), int(rng.integers(0, 1000))
    system = [PRESET, MOTORIZED][int(rng.integers(0, 2))]
    kwargs = {"views": ["ap", "lao-30"], "sd_deg": float(rng.uniform(0, 5))} if prior == "standard-views" else {}

    def check(s):
        return (s.q.shape == (n, system.nq) and bool(np.all(s.clearance_m >= datasets.DEFAULT_MARGIN))
                and bool(np.all((s.q >= system.lower - 1e-9) & (s.q <= system.upper + 1e-9))))
    case = Case(datasets.sample_poses, (system, prior, n, seed), kwargs, check=check)
    if prior == "standard-views" and rng.random() < 0.15:  # junk prior parameters
        choices = {"views": [5, "ap", ["nope"], [1]], "sd_deg": [-1.0, "2", np.nan, 1e9]}
        key = ("views", "sd_deg")[int(rng.integers(0, 2))]
        bad = {key: choices[key][int(rng.integers(0, 4))]}
        return Case(datasets.sample_poses, case.args, {**kwargs, key: bad[key]}, None, key)
    return maybe_junk(rng, case, ("system", "prior", "n", "seed"))


def dose_event(rng):
    from carmkin.dose import Event

    q = rng.normal(size=int(rng.integers(1, 12)))
    kvp, kerma = float(rng.uniform(50.0, 150.0)), float(rng.choice([0.0, 1e-6, 1e-3, 1.0]))
    field_mm = tuple(float(v) for v in rng.uniform(1.0, 500.0, size=2))

    def check(e):
        return (e.q == tuple(q.tolist()) and e.kvp == kvp and e.k_irp_gy == kerma and e.field_mm == field_mm
                and e.filter == {"Cu": 0.0, "Al": 0.0})
    return maybe_junk(rng, Case(Event, (q, kvp, kerma, field_mm), check=check), ("q", "kvp", "k_irp_gy", "field_mm"))


def dose_water_thickness(rng):
    from carmkin.dose import water_thickness
    from carmkin.patient import ParametricPatient

    patient = ParametricPatient.on_table(PRESET)
    start, end = rng.normal(scale=0.5, size=3), rng.normal(scale=0.5, size=3)

    def check(t):  # a chord of the segment, at most the densest segment's density (the head's 1110) over water's
        return math.isfinite(t) and 0.0 <= t <= 1.11 * float(np.linalg.norm(end - start)) + 1e-12
    return maybe_junk(rng, Case(water_thickness, (patient, start, end), check=check), ("patient", "start", "end"))


def dose_from_surface(rng):
    from scipy.spatial import ConvexHull

    from carmkin.dose import from_surface

    points = rng.normal(scale=0.2, size=(int(rng.integers(4, 40)), 3))
    hull = ConvexHull(points)
    vertices, faces = points, hull.simplices.copy()
    centre = points[hull.vertices].mean(axis=0)
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    inward = np.einsum("ij,ij->i", np.cross(b - a, c - a), a - centre) < 0
    faces[inward] = faces[inward][:, ::-1]
    if rng.random() < 0.5:
        faces = faces[:, ::-1]  # wound inward everywhere: the signed volume turns the normals out

    def check(skin):  # convex: every cell's normal points away from the hull's centre, unit length
        return (len(skin.points) == len(hull.vertices)
                and bool(np.all(np.einsum("ij,ij->i", skin.normals, skin.points - centre) > 0))
                and bool(np.allclose(np.linalg.norm(skin.normals, axis=1), 1.0)))
    return maybe_junk(rng, Case(from_surface, (vertices, faces), check=check), ("vertices", "faces"))


ENTRIES = {
    "dose.Event": (dose_event, 1), "dose.water_thickness": (dose_water_thickness, 0.5),
    "dose.from_surface": (dose_from_surface, 1),
    "views.View.from_angles": (view_from_angles, 1), "views.View.from_pose": (view_from_pose, 1),
    "views.plan_view": (plan_a_view, 0.2), "datasets.sample_poses": (sample_some_poses, 0.2),
    "imaging.homography_between": (homography_between, 2), "imaging.dehomogenize": (dehomogenize, 1),
    "imaging.image_border": (image_border, 1), "imaging.measure_distance": (measure_distance, 1),
    "imaging.projection_matrix": (projection_of_configuration, 1),
    "simulators.deepdrr_mobile_carm": (mobile_carm, 1), "singularity.classify": (classify, 1),
    "singularity.measure_map": (measure_map, 0.5), "panorama.shot": (panorama_shot, 0.2),
    "phantom.perturb": (perturb, 1), "robot.validity.check": (validity, 0.5), "dicom.xa_angles": (xa_angles, 1),
    "reposition.camera.project_points": (project_points, 1),
}
