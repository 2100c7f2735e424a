"""Rigid-transform helpers: group axioms of inverse and DH matrices, pose error, angle wrapping, skew,
the slab test, the projection onto SE(3), and the minimal rotation between two directions (orthonormal up to
antiparallel)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from strategies import finite, poses, rotations

from carmkin.errors import InvalidPoseError
from carmkin.transforms import (
    NEARLY_RIGID_TOLERANCE,
    check_rigid_transform,
    dh_matrix,
    inverse,
    nearest_rigid,
    pose_error,
    rotation_angle,
    rotation_between,
    segment_box_interval,
    segment_hits_box,
    skew,
    wrap_angle,
)

vectors = st.lists(st.floats(-1, 1, **finite), min_size=3, max_size=3).map(np.array).filter(
    lambda v: np.linalg.norm(v) > 1e-3)


def _check(a, b, tol: float = 1e-12):
    R = rotation_between(a, b)
    assert np.abs(R @ R.T - np.eye(3)).max() <= 1e-14
    assert abs(np.linalg.det(R) - 1.0) <= 1e-14
    assert np.abs(R @ (a / np.linalg.norm(a)) - b / np.linalg.norm(b)).max() <= tol


@given(vectors, vectors)
def test_rotation_between_random_directions(a, b):
    _check(a, b)


@given(vectors, st.floats(-1e-6, 1e-6, **finite))
def test_rotation_between_nearly_antiparallel_directions(a, eps):
    # the axis a x b is only known to ~1e-16 / |a x b| here, which bounds how exactly R maps a onto b;
    # orthonormality stays at machine precision
    b = -a + eps * np.array([0.3, -0.2, 0.5])
    s = np.linalg.norm(np.cross(a / np.linalg.norm(a), b / np.linalg.norm(b)))
    _check(a, b, tol=1e-12 + 1e-14 / max(s, 1e-300))


def test_rotation_between_the_example_that_broke_the_1_over_1_plus_c_formula():
    _check(np.array([0.71875, 0.09375, 0.109375]), np.array([-1.0, -0.125, -0.15625]))
    _check(np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0]))


# --- group axioms ------------------------------------------------------------------------------------------
pose_stacks = st.lists(poses(), min_size=1, max_size=5).map(np.array)
any_float = st.floats(-1e3, 1e3, **finite)


@given(pose_stacks)
def test_inverse_times_pose_is_the_identity_batched(T):
    assert np.abs(inverse(T) @ T - np.eye(4)).max() <= 1e-12
    assert np.abs(T @ inverse(T) - np.eye(4)).max() <= 1e-12


@given(poses(), poses())
def test_inverse_of_a_product_is_the_reversed_product_of_inverses(A, B):
    assert np.abs(inverse(A @ B) - inverse(B) @ inverse(A)).max() <= 1e-12


@given(any_float, any_float, any_float, any_float)
def test_dh_matrix_is_rigid_for_any_input(theta, d, a, alpha):
    check_rigid_transform(dh_matrix(theta, d, a, alpha))


@given(poses(), poses())
def test_pose_error_is_zero_on_equal_poses_and_symmetric(A, B):
    assert pose_error(A, A) == (0.0, pytest.approx(0.0, abs=1e-14))
    dp, angle = pose_error(A, B)
    dp2, angle2 = pose_error(B, A)
    assert dp == pytest.approx(dp2, abs=1e-15) and angle == pytest.approx(angle2, abs=1e-12)
    assert dp == pytest.approx(np.linalg.norm(A[:3, 3] - B[:3, 3]), abs=1e-15)


@given(rotations(), st.floats(0.0, math.pi, **finite), st.lists(st.floats(-1, 1, **finite), min_size=3,
                                                                  max_size=3).filter(lambda v: np.linalg.norm(v) > 0.1))
def test_rotation_angle_recovers_a_known_angle_over_the_whole_range(R, angle, axis):
    u = np.asarray(axis) / np.linalg.norm(axis)
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])  # independent of skew()
    Q = np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K
    assert rotation_angle(R, R @ Q) == pytest.approx(angle, abs=1e-12)


@given(pose_stacks, pose_stacks)
def test_pose_error_batched_equals_pair_by_pair(A, B):
    n = min(len(A), len(B))
    dp, angle = pose_error(A[:n], B[:n])
    for k in range(n):
        assert (dp[k], angle[k]) == pytest.approx(pose_error(A[k], B[k]), abs=1e-15)


@given(st.floats(-1e4, 1e4, **finite))
def test_wrap_angle_lands_in_the_half_open_interval_and_is_idempotent(a):
    w = wrap_angle(a)
    assert -math.pi < w <= math.pi
    assert wrap_angle(w) == w
    assert math.cos(w) == pytest.approx(math.cos(a), abs=1e-9) and math.sin(w) == pytest.approx(math.sin(a), abs=1e-9)
    assert wrap_angle(np.array([a]))[0] == pytest.approx(w, abs=1e-12)


def test_wrap_angle_maps_minus_pi_to_pi():
    assert wrap_angle(-math.pi) == math.pi and wrap_angle(math.pi) == math.pi
    assert list(wrap_angle(np.array([-math.pi, 3 * math.pi]))) == pytest.approx([math.pi, math.pi])


@given(st.lists(any_float, min_size=3, max_size=3), st.lists(any_float, min_size=3, max_size=3))
def test_skew_is_the_cross_product(v, w):
    assert np.abs(skew(v) @ w - np.cross(v, w)).max() <= 1e-9 * (1 + np.abs(v).max() * np.abs(w).max())
    assert np.array_equal(skew(v), -skew(v).T)


# --- slab test ------------------------------------------------------------------------------------------------
points = st.lists(st.floats(-2, 2, **finite), min_size=3, max_size=3).map(np.array)


@given(points, points, points, st.lists(st.floats(0.05, 2, **finite), min_size=3, max_size=3))
def test_slab_test_agrees_with_dense_sampling_of_the_segment(p0, p1, center, size):
    half = 0.5 * np.asarray(size)
    t = np.linspace(0.0, 1.0, 2001)[:, None]
    inside = np.all(np.abs(p0 + t * (p1 - p0) - center) <= half, axis=1)
    hit = segment_hits_box(p0, p1, center, size)
    if inside.any():  # a sampled point inside: the segment meets the box
        assert hit
    interval = segment_box_interval(p0, p1 - p0, center, size)
    assert (interval is not None) == hit
    if hit:  # the reported entry and exit points lie on the box (to round-off)
        for tt in interval:
            assert np.all(np.abs(p0 + tt * (p1 - p0) - center) <= half + 1e-9)


def test_slab_test_parallel_segment_outside_and_inside():
    assert not segment_hits_box(np.array([0, 2.0, 0]), np.array([1, 2.0, 0]), (0, 0, 0), (1, 1, 1))
    assert segment_hits_box(np.array([-2, 0.1, 0]), np.array([2, 0.1, 0]), (0, 0, 0), (1, 1, 1))
    assert segment_box_interval((-2, 0, 0), (1, 0, 0), (0, 0, 0), (1, 1, 1), -np.inf, np.inf) == (1.5, 2.5)


# --- nearest rigid transform -------------------------------------------------------------------------------
@given(poses())
def test_nearest_rigid_is_exact_on_rigid_input_and_idempotent(T):
    P, correction = nearest_rigid(T)
    assert correction <= 1e-14 and np.abs(P - T).max() <= 1e-14
    P2, correction2 = nearest_rigid(P)
    assert correction2 <= 1e-14 and np.abs(P2 - P).max() <= 1e-15


@given(poses(), st.lists(st.floats(-1, 1, **finite), min_size=9, max_size=9), st.floats(1e-9, 1e-4, **finite))
def test_nearest_rigid_moves_a_perturbed_rotation_back_within_the_perturbation(T, noise, scale):
    E = scale * np.asarray(noise).reshape(3, 3)
    bent = T.copy()
    bent[:3, :3] += E
    P, correction = nearest_rigid(bent)
    check_rigid_transform(P)
    eps = float(np.linalg.norm(E))
    assert correction <= eps + 1e-12  # the nearest rotation is no farther than the one we perturbed
    assert np.linalg.norm(P[:3, :3] - T[:3, :3]) <= 2 * eps + 1e-12
    assert np.array_equal(P[:3, 3], T[:3, 3])


def test_nearest_rigid_projects_a_pose_rounded_to_four_decimals_and_a_float32_pose():
    c, s = math.cos(0.3), math.sin(0.3)
    T = np.array([[c, -s, 0, 0.1], [s, c, 0, 0.2], [0, 0, 1, 0.3], [0, 0, 0, 1]])
    for bent in (np.round(T, 4), T.astype(np.float32)):
        P, correction = nearest_rigid(bent)
        check_rigid_transform(P)
        assert 0.0 < correction <= 2e-4


def test_nearest_rigid_refuses_what_is_not_nearly_rigid():
    with pytest.raises(InvalidPoseError, match="not nearly rigid"):
        nearest_rigid(np.diag([1.0, 1.0, 1.0 + 10 * NEARLY_RIGID_TOLERANCE, 1.0]))
    with pytest.raises(InvalidPoseError, match="reflection"):
        nearest_rigid(np.diag([1.0, 1.0, -1.0, 1.0]))
    with pytest.raises(InvalidPoseError, match="shape"):
        nearest_rigid(np.eye(3))
    with pytest.raises(InvalidPoseError, match="NaN"):
        nearest_rigid(np.full((4, 4), np.nan))
    with pytest.raises(InvalidPoseError, match="real"):
        nearest_rigid(np.eye(4) * 1j)
