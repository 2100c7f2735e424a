"""Foreshortening, overlap, plane angle and separation against independent computations (issue 29).

The oracles here are written from the definitions in docs/views.md (a loop over views and points, the
pinhole written out by hand), not from carmkin.views.metrics' helpers.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import carmkin
from carmkin.imaging import intrinsics
from carmkin.interop.dicom import pose_from_xa_angles
from carmkin.views import metrics

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")
K, _ = intrinsics(SYSTEM)
#: Agreement asked by the issue.
TOLERANCE = 1e-9


def random_rotation(rng):
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def random_views(rng, target, n, distance=0.625):
    poses = np.zeros((n, 4, 4))
    for k in range(n):
        R = random_rotation(rng)
        poses[k, :3, :3] = R
        poses[k, :3, 3] = target - distance * R[:, 2]
        poses[k, 3, 3] = 1.0
    return poses


def random_polyline(rng, centre, n, step=0.004):
    return centre + np.cumsum(rng.normal(scale=step, size=(n, 3)), axis=0) - step * n / 4


def pinhole(point, pose):
    """Normalised image coordinates (x/z, y/z) and depth of a table-frame point seen from ``pose``."""
    pose = [list(row) for row in pose]
    c = [sum(pose[i][j] * (point[i] - pose[i][3]) for i in range(3)) for j in range(3)]
    return c[0] / c[2], c[1] / c[2], c[2]


def oracle_foreshortening(points, pose, distance):
    proj = [pinhole(p, pose)[:2] for p in points]
    total2, total3, worst = 0.0, 0.0, -math.inf
    for k in range(len(points) - 1):
        l2 = math.dist(proj[k], proj[k + 1])
        l3 = math.dist(points[k], points[k + 1])
        total2 += l2
        total3 += l3
        worst = max(worst, 1 - distance * l2 / l3)
    return 1 - distance * total2 / total3, worst


def oracle_overlap(points, others, radius, pose, counts):
    """Pixels of the samples of the projected centreline; covered when the pixel centre lies in the 2D capsule
    (radius r / mean end depth) about a projected segment of another vessel."""
    fx, s, u0, fy, v0 = K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2]

    def to_px(p):
        x, y, _ = pinhole(p, pose)
        return fx * x + s * y + u0, fy * y + v0

    pixels = set()
    for k in range(len(points) - 1):
        a, b = to_px(points[k]), to_px(points[k + 1])
        for i in range(counts[k]):
            t = i / counts[k]
            u, v = a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])
            pixels.add((math.floor(u + 0.5), math.floor(v + 0.5)))
    last = to_px(points[-1])
    pixels.add((math.floor(last[0] + 0.5), math.floor(last[1] + 0.5)))
    capsules = []
    for line in others:
        for k in range(len(line) - 1):
            xa, ya, za = pinhole(line[k], pose)
            xb, yb, zb = pinhole(line[k + 1], pose)
            capsules.append(((xa, ya), (xb, yb), radius / ((za + zb) / 2)))
    covered = 0
    for iu, iv in pixels:
        y = (iv - v0) / fy
        x = (iu - u0 - s * y) / fx
        for (xa, ya), (xb, yb), r in capsules:
            dx, dy = xb - xa, yb - ya
            L2 = dx * dx + dy * dy
            t = 0.0 if L2 == 0 else min(1.0, max(0.0, ((x - xa) * dx + (y - ya) * dy) / L2))
            if (x - xa - t * dx) ** 2 + (y - ya - t * dy) ** 2 <= r * r:
                covered += 1
                break
    return covered / len(pixels)


@pytest.mark.parametrize("seed", range(6))
def test_foreshortening_matches_an_independent_computation(seed):
    rng = np.random.default_rng(seed)
    target = rng.uniform(-0.05, 0.05, 3)
    points = random_polyline(rng, target, int(rng.integers(2, 30)))
    poses = random_views(rng, target, 25)
    distance = rng.uniform(0.4, 0.9, 25)
    F, worst = metrics.foreshortening(points, poses, distance)
    for k, pose in enumerate(poses):
        f, w = oracle_foreshortening(points.tolist(), pose.tolist(), distance[k])
        assert abs(F[k] - f) < TOLERANCE and abs(worst[k] - w) < TOLERANCE


@pytest.mark.parametrize("seed", range(5))
def test_overlap_matches_an_independent_computation(seed):
    rng = np.random.default_rng(100 + seed)
    target = rng.uniform(-0.05, 0.05, 3)
    points = random_polyline(rng, target, int(rng.integers(2, 15)))
    # other vessels through points of the centreline, so that they cross it in many views
    others = [random_polyline(rng, points[int(rng.integers(len(points)))], int(rng.integers(2, 10)))
              for _ in range(int(rng.integers(1, 4)))]
    poses = random_views(rng, target, 12)
    radius = float(rng.uniform(0.5e-3, 3e-3))
    counts = metrics.subdivisions(points, poses, K)
    O = metrics.overlap(points, others, poses, K, radius, counts=counts)
    expected = [oracle_overlap(points.tolist(), [o.tolist() for o in others], radius, pose.tolist(), counts.tolist())
                for pose in poses]
    assert np.max(np.abs(O - expected)) < TOLERANCE
    assert np.any(np.array(expected) > 0)  # the test sees overlaps


def test_subdivisions_keep_samples_within_the_spacing():
    rng = np.random.default_rng(7)
    points = random_polyline(rng, np.zeros(3), 20)
    poses = random_views(rng, np.zeros(3), 10)
    counts = metrics.subdivisions(points, poses, K)
    for pose in poses:
        for k in range(len(points) - 1):
            (xa, ya, _), (xb, yb, _) = pinhole(points[k], pose), pinhole(points[k + 1], pose)
            step = math.hypot(K[0, 0] * (xb - xa) + K[0, 1] * (yb - ya), K[1, 1] * (yb - ya)) / counts[k]
            assert step <= metrics.SAMPLE_SPACING_PX + 1e-12


def test_xa_poses_are_the_dicom_poses():
    rng = np.random.default_rng(3)
    p, s = rng.uniform(-180, 180, 20), rng.uniform(-90, 90, 20)
    target = rng.uniform(-0.1, 0.1, 3)
    frame = carmkin.imaging.patient_pose("FFDL")
    T = metrics.xa_poses(p, s, target, 0.7, frame[:3, :3])
    for k in range(20):
        assert np.allclose(T[k], pose_from_xa_angles(p[k], s[k], target, 0.7, frame), atol=1e-12)


def test_straight_segment_is_not_foreshortened_across_the_beam():
    rng = np.random.default_rng(11)
    for _ in range(10):
        target = rng.uniform(-0.1, 0.1, 3)
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        points = target + np.linspace(-0.03, 0.03, 7)[:, None] * axis
        e1 = np.cross(axis, rng.normal(size=3))
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(axis, e1)
        poses = []
        for phi in np.linspace(0, 2 * np.pi, 36, endpoint=False):
            z = math.cos(phi) * e1 + math.sin(phi) * e2   # every beam of the perpendicular family
            x = axis
            pose = np.eye(4)
            pose[:3, :3] = np.column_stack((x, np.cross(z, x), z))
            pose[:3, 3] = target - 0.625 * z
            poses.append(pose)
        F, worst = metrics.foreshortening(points, np.array(poses), 0.625)
        assert np.max(np.abs(F)) < 1e-12 and np.max(np.abs(worst)) < 1e-12


@pytest.mark.parametrize("theta_deg", [5.0, 30.0, 60.0, 85.0])
def test_straight_segment_tends_to_one_minus_cos_theta(theta_deg):
    """Off the perpendicular family by θ: F → 1 − cos θ as the source recedes (parallel projection)."""
    theta = math.radians(theta_deg)
    axis = np.array([1.0, 0.0, 0.0])
    target = np.array([0.01, -0.02, 0.03])
    points = target + np.linspace(-0.02, 0.02, 5)[:, None] * axis
    z = np.array([math.sin(theta), 0.0, math.cos(theta)])  # θ from the plane across the segment
    x = np.cross(np.array([0.0, 1.0, 0.0]), z)
    errors = []
    for distance in (1.0, 10.0, 100.0, 1000.0):
        pose = np.eye(4)
        pose[:3, :3] = np.column_stack((x, np.cross(z, x), z))
        pose[:3, 3] = target - distance * z
        F, _ = metrics.foreshortening(points, pose[None], distance)
        errors.append(abs(F[0] - (1 - math.cos(theta))))
    assert all(b < a for a, b in zip(errors, errors[1:])) or errors[-1] < 1e-12
    assert errors[-1] < 1e-6


def test_plane_angle_and_separation():
    rng = np.random.default_rng(5)
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    expected = [math.asin(min(1.0, abs(float(v @ normal)))) for v in d]
    assert np.allclose(metrics.plane_angle(normal, d), expected, atol=1e-15)
    cusps = rng.uniform(-0.02, 0.02, (3, 3))
    poses = random_views(rng, np.zeros(3), 8)
    gaps = metrics.separation(cusps, poses, 0.625)
    for k, pose in enumerate(poses):
        proj = [pinhole(c, pose)[:2] for c in cusps.tolist()]
        want = min(math.dist(proj[i], proj[j]) for i in range(3) for j in range(i + 1, 3)) * 0.625
        assert abs(gaps[k] - want) < 1e-12


# --- the same oracles over hypothesis-drawn polylines and views ------------------------------------------------
@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 12), m=st.integers(2, 8), others=st.integers(0, 3),
       radius_mm=st.floats(0.5, 4.0))
def test_metrics_match_the_oracles_on_drawn_polylines(seed, n, m, others, radius_mm):
    rng = np.random.default_rng(seed)
    target = rng.uniform(-0.05, 0.05, 3)
    points = random_polyline(rng, target, n)
    if np.min(np.linalg.norm(np.diff(points, axis=0), axis=1)) < 1e-6:
        return
    vessels = [random_polyline(rng, points[int(rng.integers(n))], m) for _ in range(others)]
    poses = random_views(rng, target, 4, distance=float(rng.uniform(0.4, 1.0)))
    distance = np.linalg.norm(poses[:, :3, 3] - target, axis=1)
    F, worst = metrics.foreshortening(points, poses, distance)
    counts = metrics.subdivisions(points, poses, K)
    O = metrics.overlap(points, vessels, poses, K, radius_mm / 1000, counts=counts)
    for k, pose in enumerate(poses):
        f, w = oracle_foreshortening(points.tolist(), pose.tolist(), distance[k])
        assert abs(F[k] - f) < TOLERANCE and abs(worst[k] - w) < TOLERANCE
        o = oracle_overlap(points.tolist(), [v.tolist() for v in vessels], radius_mm / 1000, pose.tolist(),
                           counts.tolist())
        assert abs(O[k] - o) < TOLERANCE
