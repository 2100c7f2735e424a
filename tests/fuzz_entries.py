"""Fuzz entry points of the geometry layer: transforms, validation kinds, imaging, simulators, panorama.

Each ``make(rng) -> Case`` draws valid (often degenerate) input with an oracle from an independent route,
and lets :func:`fuzz_engine.maybe_junk` replace one argument by junk.
"""

from __future__ import annotations

import math

import fuzz_geometry as g
import numpy as np
from fuzz_engine import Case, maybe_junk

import carmkin
from carmkin import imaging, transforms, validation
from carmkin.panorama import planner as panorama
from carmkin.interop import simulators as sim

PRESET = carmkin.load_preset("siremobile-iso-c3d")


def _rt_inverse(T):
    R, p = T[:3, :3], T[:3, 3]
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = R.T, -R.T @ p
    return out


# --- transforms ----------------------------------------------------------------------------------------
def inverse(rng):
    T = g.pose(rng)
    return maybe_junk(rng, Case(transforms.inverse, (T,), check=lambda r: g.close(r @ T, np.eye(4), atol=1e-9 * max(
        1, np.abs(T).max()))), ("T",))


def _hat(v):
    v = v / np.abs(v).max()
    return v / np.linalg.norm(v)


def rotation_between(rng):
    a = g.unit(rng) * rng.choice([1e-200, 1e-6, 1.0, 1e6])
    b = rng.choice([a, -a, g.unit(rng), a + 1e-9 * g.unit(rng)]) * rng.choice([1e-100, 1.0, 1e5])

    def check(R):
        return g.is_rotation(R) and g.close(R @ _hat(a), _hat(b), atol=1e-6)
    return maybe_junk(rng, Case(transforms.rotation_between, (a, b), check=check), ("a", "b"))


def wrap_angle(rng):
    x = float(rng.choice([rng.uniform(-10, 10), np.pi, -np.pi, 1e6 * rng.uniform(-1, 1), 0.0, 2 * np.pi]))
    arg = x if rng.random() < 0.5 else np.array([x, -x])

    def check(w):
        w = np.atleast_1d(w)
        xs = np.atleast_1d(arg)
        k = (xs - w) / (2 * np.pi)
        return np.all((w > -np.pi) & (w <= np.pi)) and np.allclose(k, np.round(k), atol=1e-9 * max(1, abs(x)))
    case = maybe_junk(rng, Case(transforms.wrap_angle, (arg,), check=check), ("angle",))
    value = case.args[0]
    if case.junk and isinstance(value, np.ndarray) and value.dtype == float and not np.any(np.isinf(value)):
        nan = np.isnan(value)  # documented: NaN passes through as NaN (an IK branch without a solution)
        return Case(transforms.wrap_angle, (value,), check=lambda w: bool(np.all(np.isnan(w) == nan)))
    return case


def pose_error(rng):
    Ta, Tb = g.pose(rng), g.pose(rng)

    def check(r):
        from scipy.spatial.transform import Rotation

        angle = Rotation.from_matrix(Ta[:3, :3].T @ Tb[:3, :3]).magnitude()
        return abs(r[0] - np.linalg.norm(Ta[:3, 3] - Tb[:3, 3])) <= 1e-9 * max(1, np.abs(Ta).max()) and abs(
            r[1] - angle) <= 1e-7
    case = maybe_junk(rng, Case(transforms.pose_error, (Ta, Tb), check=check), ("Ta", "Tb"))
    bad = [a for a in case.args if isinstance(a, np.ndarray) and a.dtype == float and a.shape == (4, 4)
           and not np.all(np.isfinite(a[:3]))]  # the last row is not read
    if case.junk and not bad and all(isinstance(a, np.ndarray) and a.dtype == float and a.shape == (4, 4)
                                     for a in case.args):  # only the unread last row is off: the normal oracle
        return Case(transforms.pose_error, case.args, check=check)
    if case.junk and bad:  # documented: a non-finite pose gives a non-finite error (never a finite number)
        return Case(transforms.pose_error, case.args, check=lambda r: not np.all(np.isfinite(r)))
    return case


def nearest_rigid(rng):
    T = g.pose(rng)
    eps = rng.choice([0.0, 1e-12, 1e-6, 1e-4])
    noisy = T.copy()
    noisy[:3, :3] += eps * rng.normal(size=(3, 3))

    def check(r):
        out, corr = r
        return g.is_rotation(out[:3, :3]) and np.allclose(out[:3, 3], T[:3, 3]) and corr <= 10 * eps + 1e-12
    return maybe_junk(rng, Case(transforms.nearest_rigid, (noisy,), check=check), ("T",))


def skew(rng):
    v, w = rng.normal(size=3) * rng.choice(g.SCALES), rng.normal(size=3)
    return maybe_junk(rng, Case(transforms.skew, (v,), check=lambda S: g.close(S @ w, np.cross(v, w))), ("v",))


def dh_matrix(rng):
    theta, d, a, alpha = rng.uniform(-4, 4), rng.normal() * rng.choice(g.SCALES), rng.normal(), rng.uniform(-4, 4)

    def check(M):
        def rz(t):
            return np.array([[np.cos(t), -np.sin(t), 0, 0], [np.sin(t), np.cos(t), 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])

        def rx(t):
            return np.array([[1, 0, 0, 0], [0, np.cos(t), -np.sin(t), 0], [0, np.sin(t), np.cos(t), 0], [0, 0, 0, 1]])
        tz, tx = np.eye(4), np.eye(4)
        tz[2, 3], tx[0, 3] = d, a
        return g.close(M, rz(theta) @ tz @ tx @ rx(alpha), atol=1e-12 * max(1, abs(d), abs(a)))
    return maybe_junk(rng, Case(transforms.dh_matrix, (theta, d, a, alpha), check=check), ("theta", "d", "a", "alpha"))


def segment_box(rng):
    p0, p1 = rng.normal(size=3), rng.normal(size=3) * rng.choice([1.0, 1e-9, 3.0])
    p1 = p0 + rng.choice([p1, p1 * np.array([1, 0, 0])])
    center, size = rng.normal(size=3) * 0.5, rng.uniform(0, 2, 3)

    def check(hit):
        t = np.linspace(0, 1, 2001)
        X = p0 + t[:, None] * (p1 - p0)
        step = np.linalg.norm(p1 - p0) / 2000
        loose = np.all(np.abs(X - center) <= size / 2 + step + 1e-9, axis=1)
        strictly = np.all(np.abs(X - center) < size / 2 - 1e-9, axis=1)
        return (hit or not strictly.any()) and (not hit or loose.any())
    return maybe_junk(rng, Case(transforms.segment_hits_box, (p0, p1, center, size), check=check),
                      ("p0", "p1", "center", "size"))


# --- validation kinds --------------------------------------------------------------------------------
def v_rotation(rng):
    R = g.rotation(rng)
    bad = rng.integers(0, 4)
    M = [R, 1.01 * R, R @ np.diag([1, 1, -1]), np.zeros((3, 3))][bad]
    return maybe_junk(rng, Case(validation.rotation, (M, "R"), check=lambda r: bad == 0 and g.close(r, R)), ("R",))


def v_intrinsics(rng):
    K = g.intrinsics(rng)
    bad = rng.integers(0, 4)
    M = [K, 5.0 * K, np.diag([0.0, 1.0, 1.0]), K.T][bad]
    return maybe_junk(rng, Case(validation.intrinsics, (M,), check=lambda r: bad == 0 and g.close(r, K)), ("K",))


def v_distance(rng):
    x = float(rng.choice([1e-6, 1e-3, 1.0, 10.0, 0.0, -1.0, 1e300, 1e-320, 11.0]))
    ok = 1e-6 <= x <= 10.0
    return maybe_junk(rng, Case(validation.distance, (x, "length"), check=lambda r: ok and r == x), ("length",))


def v_joint_index(rng):
    nq = int(rng.choice([6, 11]))
    i = int(rng.integers(-3, 20))
    return maybe_junk(rng, Case(validation.joint_index, (i, "joint", nq), check=lambda r: 0 <= i < nq and r == i),
                      ("joint",))


# --- imaging ---------------------------------------------------------------------------------------------
def project(rng):
    K, T = g.intrinsics(rng), g.pose(rng)
    X = g.points_in_front(rng, T)

    def check(m):
        Xc = (np.linalg.inv(T) @ np.column_stack((X, np.ones(len(X)))).T)[:3].T
        expected = np.array([[K[0, 0] * x / z + K[0, 1] * y / z + K[0, 2], K[1, 1] * y / z + K[1, 2]]
                             for x, y, z in Xc])
        return g.close(m, expected, rtol=1e-6, atol=1e-6)
    return maybe_junk(rng, Case(imaging.project, (K, T, X), check=check), ("K", "T", "X"))


def back_project(rng):
    K = g.intrinsics(rng)
    m = g.edge_pixels(rng, (2000, 2000), int(rng.integers(1, 6)))
    n = g.unit(rng)
    n = n if n[2] > 0.2 else np.array([0.0, 0.0, 1.0])
    d = float(rng.choice([1e-3, 0.5, 10.0]))

    def check(P):
        return g.close(P @ n, np.full(len(m), d), rtol=1e-6) and g.close(
            (P @ K.T)[:, :2] / (P @ K.T)[:, 2:], m, rtol=1e-6, atol=1e-5)
    return maybe_junk(rng, Case(imaging.back_project, (K, m, n, d), check=check), ("K", "m", "n", "d"))


def plane_homography(rng):
    K, Trel = g.intrinsics(rng), g.pose(rng, scale=float(rng.choice([0.0, 1e-3, 0.1])))
    n, d = np.array([0.0, 0.0, 1.0]), float(rng.choice([1e-3, 1.0, 5.0]))
    X2 = np.column_stack((rng.normal(size=(4, 2)) * d * 0.2, np.full(4, d)))  # on n.X2 = d, in front

    def check(H):
        X1 = X2 @ Trel[:3, :3].T + Trel[:3, 3]
        if np.any(X1[:, 2] <= 1e-9 * d):
            return True  # behind the first view: nothing to compare
        m2, m1 = X2 @ K.T, X1 @ K.T
        mapped = m2 @ H.T
        return g.close(mapped[:, :2] / mapped[:, 2:], m1[:, :2] / m1[:, 2:], rtol=1e-5, atol=1e-4)
    return maybe_junk(rng, Case(imaging.plane_homography, (K, Trel[:3, :3], Trel[:3, 3], n, d), check=check),
                      ("K", "R", "t", "n", "d"))


def rotation_homography(rng):
    K, R = g.intrinsics(rng), g.rotation(rng)
    return maybe_junk(rng, Case(imaging.rotation_homography, (K, R),
                                check=lambda H: g.close(H @ K, K @ R, rtol=1e-9, atol=1e-9 * K[0, 0])), ("K", "R"))


def apply_homography(rng):
    H = rng.normal(size=(3, 3))
    m = g.edge_pixels(rng, (1000, 800), 5)

    def check(out):
        expected = [(H[:2] @ (u, v, 1)) / (H[2] @ (u, v, 1)) for u, v in m]
        return g.close(out, np.array(expected), rtol=1e-8, atol=1e-8)
    return maybe_junk(rng, Case(imaging.apply_homography, (H, m), check=check), ("H", "m"))


def relative_pose(rng):
    T1, T2 = g.pose(rng), g.pose(rng)
    return maybe_junk(rng, Case(imaging.relative_pose, (T1, T2), check=lambda r: g.close(
        T1 @ r, T2, atol=1e-9 * max(1, np.abs(T2).max()))), ("T1", "T2"))


def in_image(rng):
    w, h = int(rng.integers(1, 3000)), int(rng.integers(1, 3000))
    m = g.edge_pixels(rng, (w, h), 6) + rng.choice([0.0, 1e-9, -1e-9, 5.0])
    expected = (m[:, 0] >= -0.5) & (m[:, 0] <= w - 0.5) & (m[:, 1] >= -0.5) & (m[:, 1] <= h - 0.5)
    return maybe_junk(rng, Case(imaging.in_image, (m, w, h), check=lambda r: np.array_equal(r, expected)),
                      ("m", "columns", "rows"))


def projection_round_trip(rng):
    K, T = g.intrinsics(rng), g.pose(rng)
    scale = float(rng.choice([1.0, -1.0, 1e-8, 1e8, -3.5]))
    P = scale * np.hstack((K, np.zeros((3, 1)))) @ _rt_inverse(T)
    if rng.random() < 0.2:
        P[rng.integers(0, 3), rng.integers(0, 4)] = rng.choice([1e150, -1e200, 1e300])

    def check(r):
        K2, T2 = r
        again = np.hstack((K2, np.zeros((3, 1)))) @ _rt_inverse(T2)
        s = (P.ravel() @ again.ravel()) / (again.ravel() @ again.ravel())
        return g.close(s * again, P, rtol=1e-6, atol=1e-6 * np.abs(P).max())
    return maybe_junk(rng, Case(imaging.pose_from_projection, (P,), check=check), ("P",))


def projection_from_pose(rng):
    K, T = g.intrinsics(rng), g.pose(rng)
    X = g.points_in_front(rng, T)

    def check(P):
        m = np.column_stack((X, np.ones(len(X)))) @ P.T
        return g.close(m[:, :2] / m[:, 2:], imaging.project(K, T, X), rtol=1e-6, atol=1e-6)
    return maybe_junk(rng, Case(imaging.projection_from_pose, (K, T), check=check), ("K", "T"))


def patient_pose(rng):
    code = str(rng.choice(list(imaging.projection.PATIENT_POSITIONS) + ["hfs", " FFP ", "XYZ", ""]))
    origin = rng.normal(size=3)
    valid = code.strip().upper() in imaging.projection.PATIENT_POSITIONS

    def check(T):
        cols = np.array(imaging.projection.PATIENT_POSITIONS[code.strip().upper()], dtype=float).T
        return valid and g.close(T[:3, :3], cols) and g.close(T[:3, 3], origin) and g.is_rotation(T[:3, :3])
    return maybe_junk(rng, Case(imaging.patient_pose, (code, origin), check=check), ("position", "origin"))


# --- simulators ----------------------------------------------------------------------------------------
def detector_round_trip(rng):
    K = g.intrinsics(rng)
    size = (int(rng.integers(1, 4000)), int(rng.integers(1, 4000)))
    sdd = float(rng.choice([1.0, 300.0, 1200.0, 10000.0]))
    which = rng.integers(0, 2)
    make, back = [(sim.nanodrr_detector, sim.intrinsics_from_nanodrr),
                  (sim.diffdrr_detector, sim.intrinsics_from_diffdrr)][which]
    if rng.random() < 0.2:  # a K whose last row is not (0, 0, 1): must be refused (was dropped)
        K = K.copy()
        K[2, 2] = 5.0
        return Case(make, (K, size, sdd), junk="K (last row)")
    return maybe_junk(rng, Case(make, (K, size, sdd), check=lambda det: g.close(back(det), K, rtol=1e-12, atol=1e-9)),
                      ("K", "size", "sdd_mm"))


def deepdrr_round_trip(rng):
    K, T = g.intrinsics(rng), g.pose(rng, scale=float(rng.choice([1.0, 1000.0])))

    def check(r):
        K2, T2 = sim.from_deepdrr_camera_projection(*r)
        return g.close(K2, K, rtol=1e-12, atol=1e-9) and g.close(T2, T, atol=1e-9 * max(1, np.abs(T).max()))
    return maybe_junk(rng, Case(sim.deepdrr_camera_projection, (K, T), check=check), ("K", "T_mm"))


def xvr_round_trip(rng):
    T = g.pose(rng, scale=float(rng.choice([1.0, 1000.0])))
    orientation = ["AP", None][int(rng.integers(0, 2))]
    iso = rng.uniform(-200, 200, 3)

    def check(r):
        return g.close(sim.from_xvr_pose(*r, orientation, iso), T, atol=1e-9 * max(1.0, float(np.abs(T).max())))
    return maybe_junk(rng, Case(sim.xvr_pose, (T, orientation, iso), check=check), ("T_mm", "orientation?", "isocenter_mm"))


def flashdrr_view(rng):
    T = g.pose(rng, scale=float(rng.choice([1.0, 1000.0])))
    return maybe_junk(rng, Case(sim.flashdrr_view_matrix, (T,),
                                check=lambda M: g.close(sim.from_flashdrr_view_matrix(M), T, atol=1e-9)), ("T_mm",))


def flashdrr_carm(rng):
    sid, ap, lat, si = rng.uniform(1, 2000), rng.uniform(-89, 89), rng.uniform(-89, 89), rng.uniform(-500, 500)
    centre = rng.uniform(-300, 300, 3)

    def check(T):
        back = sim.flashdrr_carm_parameters(T, centre)
        return g.close(np.array(back), np.array([sid, ap, lat, si]), atol=1e-6 * max(1.0, sid))
    return maybe_junk(rng, Case(sim.flashdrr_carm_pose, (sid, ap, lat, centre, si), check=check),
                      ("sid_mm", "ap_deg", "lat_deg", "center_ras_mm", "table_si_mm"))


def flashdrr_fov(rng):
    fov, size = rng.uniform(1, 120), (int(rng.integers(2, 3000)), int(rng.integers(2, 3000)))
    K = sim.intrinsics_from_flashdrr(fov, size)
    return maybe_junk(rng, Case(sim.flashdrr_fov_deg, (K, size), check=lambda r: abs(r - fov) <= 1e-9 * fov),
                      ("K", "size"))


def millimetres(rng):
    T = g.pose(rng)
    return maybe_junk(rng, Case(sim.to_millimetres, (T,), check=lambda r: g.close(sim.to_metres(r), T, atol=1e-12)),
                      ("T",))


def diffdrr_pose(rng):
    T = g.pose(rng, scale=1000.0)
    return maybe_junk(rng, Case(sim.diffdrr_pose, (T,), check=lambda r: g.close(sim.diffdrr_pose(r), T, atol=1e-9)),
                      ("T_mm",))


# --- panorama --------------------------------------------------------------------------------------
PLANNER = None


def _planner():
    global PLANNER
    if PLANNER is None:
        PLANNER = panorama.PanoramaPlanner(PRESET)
    return PLANNER


def direction_from_pixels(rng):
    p = _planner()
    du, dv = (float(rng.choice([0.0, 1.0, -3.0, 1e-300, 1e5, 1e6]) * rng.uniform(0.5, 2)) for _ in range(2))

    def check(d):
        e = np.array([du / p.K[0, 0], dv / p.K[1, 1], 0.0])
        e = e / np.abs(e).max()
        return abs(np.linalg.norm(d) - 1) < 1e-12 and g.close(d, e / np.linalg.norm(e), atol=1e-12)
    return maybe_junk(rng, Case(p.direction_from_pixels, (du, dv), check=check), ("du", "dv"))


def rotation_for(rng):
    p = _planner()
    pp = g.edge_pixels(rng, p.size, 1)[0] * rng.choice([1.0, 1.0, 100.0])

    def check(r):
        V, R = r
        ray = p.K_inv @ (pp[0], pp[1], 1.0)
        return g.close(V, ray / np.linalg.norm(ray)) and g.is_rotation(R) and g.close(R @ (0, 0, 1.0), V)
    return maybe_junk(rng, Case(p.rotation_for, (pp,), check=check), ("principal_point",))


ENTRIES = {
    "transforms.inverse": (inverse, 2), "transforms.rotation_between": (rotation_between, 2),
    "transforms.wrap_angle": (wrap_angle, 2), "transforms.pose_error": (pose_error, 2),
    "transforms.nearest_rigid": (nearest_rigid, 2), "transforms.skew": (skew, 1),
    "transforms.dh_matrix": (dh_matrix, 2), "transforms.segment_hits_box": (segment_box, 2),
    "validation.rotation": (v_rotation, 1), "validation.intrinsics": (v_intrinsics, 1),
    "validation.distance": (v_distance, 1), "validation.joint_index": (v_joint_index, 1),
    "imaging.project": (project, 3), "imaging.back_project": (back_project, 3),
    "imaging.plane_homography": (plane_homography, 2), "imaging.rotation_homography": (rotation_homography, 2),
    "imaging.apply_homography": (apply_homography, 2), "imaging.relative_pose": (relative_pose, 2),
    "imaging.in_image": (in_image, 2), "imaging.pose_from_projection": (projection_round_trip, 3),
    "imaging.projection_from_pose": (projection_from_pose, 2), "imaging.patient_pose": (patient_pose, 1),
    "simulators.nanodrr/diffdrr_detector": (detector_round_trip, 2),
    "simulators.deepdrr_camera_projection": (deepdrr_round_trip, 2),
    "simulators.to_millimetres": (millimetres, 1), "simulators.diffdrr_pose": (diffdrr_pose, 1),
    "panorama.direction_from_pixels": (direction_from_pixels, 1), "panorama.rotation_for": (rotation_for, 1),
    "simulators.xvr_pose": (xvr_round_trip, 2), "simulators.flashdrr_view_matrix": (flashdrr_view, 1),
    "simulators.flashdrr_carm_pose": (flashdrr_carm, 2), "simulators.flashdrr_fov_deg": (flashdrr_fov, 1),
}
