"""Pinhole geometry of the X-ray source: projection, homographies (eq. 3.1/4.17), metric measurement (eq. 3.17)
and the errata of docs/errata/panorama.md."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from strategies import finite, poses, rotations

import carmkin
from carmkin import imaging

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")
K = SYSTEM.carm.intrinsics()


def pixels_of(X_cam: np.ndarray) -> np.ndarray:
    """Hand-written pinhole projection u = fx x/z + u0, v = fy y/z + v0 (no code under test)."""
    fx, fy, u0, v0 = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    return np.column_stack((fx * X_cam[:, 0] / X_cam[:, 2] + u0, fy * X_cam[:, 1] / X_cam[:, 2] + v0))


def unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


@st.composite
def planes(draw):
    """A plane nᵀX = d in front of a camera at the origin, and points on it seen by that camera."""
    n = unit([draw(st.floats(-0.5, 0.5, **finite)), draw(st.floats(-0.5, 0.5, **finite)), 1.0])
    d = draw(st.floats(0.2, 1.0, **finite))
    e1 = unit(np.cross(n, [1.0, 0.0, 0.0]))
    e2 = np.cross(n, e1)
    coords = np.array([[draw(st.floats(-0.05, 0.05, **finite)) for _ in range(2)] for _ in range(6)])
    return n, d, d * n + coords @ np.vstack((e1, e2))


@st.composite
def small_rotations(draw, max_angle: float = 0.3) -> np.ndarray:
    axis = unit([draw(st.floats(-1, 1, **finite)) for _ in range(3)] + np.array([0, 0, 1e-3]))
    angle = draw(st.floats(-max_angle, max_angle, **finite))
    Kx = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * Kx + (1 - np.cos(angle)) * Kx @ Kx


def test_intrinsics_match_detector():
    """K from the SDD, the pixel spacing and the 800×600 image: f/spacing and the image centre."""
    assert K[0, 0] == pytest.approx(0.98 / (0.23 / 800))
    assert K[1, 1] == pytest.approx(0.98 / (0.23 / 600))
    assert (K[0, 2], K[1, 2]) == (399.5, 299.5)


@given(poses(), st.lists(st.floats(-0.1, 0.1, **finite), min_size=2, max_size=2), st.floats(0.1, 2.0, **finite))
def test_project_matches_pinhole(T, xy, z):
    X_cam = np.array([[xy[0], xy[1], z]])
    X_world = T[:3, :3] @ X_cam[0] + T[:3, 3]
    np.testing.assert_allclose(imaging.project(K, T, X_world), pixels_of(X_cam), rtol=1e-9, atol=1e-7)


def test_project_rejects_points_behind():
    with pytest.raises(imaging.ImagingError, match="behind"):
        imaging.project(K, np.eye(4), [0.0, 0.0, -1.0])


@given(planes(), small_rotations(), st.lists(st.floats(-0.1, 0.1, **finite), min_size=3, max_size=3))
def test_eq_4_17_maps_image_2_onto_image_1(plane, R, t):
    """Eq. 4.17 with R, t the pose of view 2 in view 1 (X1 = R X2 + t) and the plane in view 2."""
    n, d, X2 = plane
    X1 = X2 @ R.T + np.asarray(t)
    H = imaging.plane_homography(K, R, t, n, d)
    np.testing.assert_allclose(imaging.apply_homography(H, pixels_of(X2)), pixels_of(X1), rtol=0, atol=1e-6)


@given(planes(), small_rotations(), st.lists(st.floats(0.03, 0.1, **finite), min_size=3, max_size=3))
def test_erratum_eq_3_1_read_as_camera_motion_fails(plane, R, t):
    """Eq. 3.1 read literally ("R, t of the camera", plane in the world = view 1, H: image 1 → image 2)
    holds only when R, t are the coordinate change X2 = R X1 + t, not the camera's motion (its pose)."""
    n, d, X1 = plane
    t = np.asarray(t)
    H = K @ R @ np.linalg.inv(K) + K @ np.outer(t, n) @ np.linalg.inv(K) / d
    extrinsic = X1 @ R.T + t              # X2 = R X1 + t
    motion = (X1 - t) @ R                 # camera moved by (R, t): X1 = R X2 + t
    np.testing.assert_allclose(imaging.apply_homography(H, pixels_of(X1)), pixels_of(extrinsic), atol=1e-6)
    errors = np.linalg.norm(imaging.apply_homography(H, pixels_of(X1)) - pixels_of(motion), axis=1)
    assert errors.max() > 1.0


@given(poses(), rotations(), planes())
def test_pure_rotation_homography_is_independent_of_the_plane(T1, R, plane):
    """Same source position: the plane-induced homography equals K R K⁻¹ for every plane (eq. 4.17, t=0)."""
    n, d, _ = plane
    T2 = T1.copy()
    T2[:3, :3] = T1[:3, :3] @ R
    n_world = T1[:3, :3] @ n
    H_plane = imaging.homography_between(K, T1, T2, n_world, d + n_world @ T1[:3, 3])
    H_rot = imaging.rotation_homography(K, R)
    np.testing.assert_allclose(H_plane / H_plane[2, 2], H_rot / H_rot[2, 2], rtol=1e-9, atol=1e-9)


@given(small_rotations(0.5), st.lists(st.floats(-0.2, 0.2, **finite), min_size=3, max_size=3),
       st.lists(st.floats(0.2, 1.0, **finite), min_size=5, max_size=5))
def test_rotation_homography_aligns_points_at_any_depth(R, xyz, depths):
    """Points along one ray of view 2 at different depths all map to their pixel in view 1."""
    ray = unit(np.array(xyz) + [0.0, 0.0, 1.0])
    X2 = np.outer(depths, ray)
    X1 = X2 @ R.T
    assume_front = X1[:, 2] > 0.05
    if not assume_front.all():
        return
    mapped = imaging.apply_homography(imaging.rotation_homography(K, R), pixels_of(X2))
    np.testing.assert_allclose(mapped, pixels_of(X1), atol=1e-6)


@given(planes())
def test_metric_measurement_recovers_distances(plane):
    """Eq. 3.17: distances between points of a known plane, from their pixels, to 1e-9 relative."""
    n, d, X = plane
    m = pixels_of(X)
    true = np.linalg.norm(X[:3] - X[3:], axis=1)
    measured = imaging.measure_distance(K, m[:3], m[3:], n, d)
    np.testing.assert_allclose(measured, true, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(imaging.back_project(K, m, n, d), X, rtol=1e-9, atol=1e-12)


@given(st.lists(st.floats(-1, 1, **finite), min_size=3, max_size=3),
       st.lists(st.floats(-1, 1, **finite), min_size=3, max_size=3))
def test_rotation_between_is_the_minimal_rotation(a, b):
    a, b = np.array(a), np.array(b)
    if np.linalg.norm(a) < 1e-3 or np.linalg.norm(b) < 1e-3:
        return
    R = imaging.rotation_between(a, b)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R @ unit(a), unit(b), atol=1e-12)
    angle = np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))
    assert angle == pytest.approx(np.arccos(np.clip(unit(a) @ unit(b), -1, 1)), abs=1e-6)


def test_rotation_between_antiparallel():
    R = imaging.rotation_between([0, 0, 1], [0, 0, -1])
    np.testing.assert_allclose(R @ [0, 0, 1], [0, 0, -1], atol=1e-15)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-15)


def test_bad_planes_are_refused():
    with pytest.raises(imaging.ImagingError, match="unit"):
        imaging.plane_homography(K, np.eye(3), [0, 0, 0], [0, 0, 2.0], 1.0)
    with pytest.raises(imaging.ImagingError, match="d = 0"):
        imaging.plane_homography(K, np.eye(3), [0, 0, 0], [0, 0, 1.0], 0.0)
    with pytest.raises(imaging.ImagingError, match="parallel"):
        imaging.back_project(K, [[399.5, 299.5]], [1.0, 0, 0], 0.5)


def test_image_border_and_in_image():
    border = imaging.image_border(800, 600, 4)
    assert border.shape == (17, 2)
    np.testing.assert_array_equal(border[0], border[-1])
    assert imaging.in_image(border, 800, 600).all()
    assert not imaging.in_image([[-0.6, 10.0], [10.0, 599.6]], 800, 600).any()
