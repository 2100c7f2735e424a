"""Pose estimation (§3.3.2): exact round trips, the covariance against Monte Carlo, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

import carmkin
from carmkin.reposition import camera, estimate_pose, pattern, pose, reprojection
from carmkin.reposition.calibration import rotation_angle
from carmkin.reposition.world import system_mount

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")
BOARD = pattern.MarkerBoard()
MOUNT = system_mount(SYSTEM, BOARD)
K = SYSTEM.carm.intrinsics()
SIZE = (SYSTEM.carm.detector_columns, SYSTEM.carm.detector_rows)
#: Issue 14: the pose from noise-free corners equals the truth to 1e-9 (m and rad).
EXACT = 1e-9
finite = dict(allow_nan=False, allow_infinity=False)


@st.composite
def viewing_configurations(draw):
    """C-arm configurations from which the camera sees at least 4 markers of the pattern."""
    ranges = {"vertical": (0.0, 0.15), "angular": (-0.5, 0.5), "orbital": (-0.5, 0.5)}
    q = []
    for name, joint_range in zip(SYSTEM.joint_names, SYSTEM.joint_ranges):
        low, high = ranges.get(name, (joint_range.lower, joint_range.upper))
        q.append(draw(st.floats(low, high, **finite)))
    return np.array(q)


@given(viewing_configurations(), st.sampled_from(pose.REFINERS))
def test_noise_free_corners_give_the_true_pose(q, refine):
    T_true = camera.camera_in_marker(MOUNT, SYSTEM.fk(q))
    view = camera.visible_corners(BOARD, K, SIZE, T_true)
    assume(len(view) >= 4)
    estimate = pose.pose_from_view(view, K, refine=refine)
    assert rotation_angle(estimate.T[:3, :3], T_true[:3, :3]) <= EXACT
    assert np.linalg.norm(estimate.T[:3, 3] - T_true[:3, 3]) <= EXACT
    assert estimate.rms_px <= 1e-6


@given(st.lists(st.tuples(*(st.floats(-0.2, 0.2, **finite),) * 3), min_size=6, max_size=20))
def test_non_planar_points_round_trip_through_sqpnp(offsets):
    X = np.array(offsets) + (0.0, 0.0, 0.8)  # in front of a camera at the origin of the frame
    assume(np.linalg.svd(X - X.mean(axis=0), compute_uv=False)[2] > 0.02)
    pixels, _ = camera.project_points(K, np.eye(4), X)
    T = estimate_pose(X, pixels, K)
    assert np.abs(T - np.eye(4)).max() <= EXACT


def test_estimate_pose_returns_the_camera_to_marker_transform():
    T_true = camera.camera_in_marker(MOUNT, SYSTEM.fk(np.zeros(6)))
    view = camera.visible_corners(BOARD, K, SIZE, T_true)
    T = estimate_pose(view.object_points, view.image_points, K)
    point_camera = np.array([0.01, -0.02, 0.3, 1.0])
    np.testing.assert_allclose(T @ point_camera, T_true @ point_camera, atol=EXACT)
    assert T[2, 3] < 0  # the camera is on the printed side (marker Z points into the table)


def _perturbed(T, x):
    """``R = exp([ω]) R``, ``p = p + δp`` (the convention of the Jacobian), by scipy."""
    from scipy.spatial.transform import Rotation

    out = T.copy()
    out[:3, :3] = Rotation.from_rotvec(x[:3]).as_matrix() @ T[:3, :3]
    out[:3, 3] += x[3:]
    return out


def test_jacobian_matches_finite_differences():
    T = camera.camera_in_marker(MOUNT, SYSTEM.fk(np.array([0.05, 0.1, 0.05, 0.1, 0.2, -0.3])))
    X = BOARD.corners[:40].reshape(-1, 3)
    J = reprojection.reprojection_jacobian(K, T, X)
    h = 1e-7
    for k in range(6):
        x = np.zeros(6)
        x[k] = h
        plus, _ = camera.project_points(K, _perturbed(T, x), X)
        minus, _ = camera.project_points(K, _perturbed(T, -x), X)
        np.testing.assert_allclose(J[:, k], ((plus - minus) / (2 * h)).ravel(), rtol=1e-5, atol=1e-4)


#: Monte Carlo of the covariance: 400 noisy estimates; each predicted variance must match the empirical one
#: within this factor (the sample variance of 400 draws is within ±15 % with ~99 % probability; the rest is
#: the linearisation).
COVARIANCE_FACTOR = 1.33


def _wide_board_view():
    """A 6 × 5 grid seen obliquely at 0.6 m by a wide camera (56° field of view): the other regime."""
    from scipy.spatial.transform import Rotation

    Kw = np.array([[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]])
    x, y = np.meshgrid(np.arange(6) * 0.04, np.arange(5) * 0.04)
    X = np.column_stack((x.ravel(), y.ravel(), np.zeros(x.size)))
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec([0.4, -0.3, 0.2]).as_matrix()
    T[:3, 3] = X.mean(axis=0) - 0.6 * T[:3, 2]
    return camera.CornerView(np.arange(len(X) // 4), X, camera.project_points(Kw, T, X)[0]), Kw, T


@pytest.mark.parametrize("setup", ["xray", "wide"])
def test_covariance_agrees_with_monte_carlo(setup):
    """The covariance σ² (JᵀJ)⁻¹ against the spread of 400 estimates from noisy corners (0.2 px)."""
    rng = np.random.default_rng(7)
    if setup == "xray":
        T_true = camera.camera_in_marker(MOUNT, SYSTEM.fk(np.array([0.0, 0.05, 0.0, 0.1, 0.2, -0.2])))
        view, K_used = camera.visible_corners(BOARD, K, SIZE, T_true), K
    else:
        view, K_used, T_true = _wide_board_view()
    sigma = 0.2
    samples = []
    for _ in range(400):
        estimate = pose.pose_from_view(camera.with_noise(view, sigma, rng), K_used, sigma_px=sigma)
        dR = estimate.T[:3, :3] @ T_true[:3, :3].T
        omega = np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]]) / 2  # small angles
        samples.append(np.concatenate((omega, estimate.T[:3, 3] - T_true[:3, 3])))
    empirical = np.cov(np.array(samples).T)
    ratio = np.diag(empirical) / np.diag(estimate.covariance)
    assert np.all((ratio > 1 / COVARIANCE_FACTOR) & (ratio < COVARIANCE_FACTOR)), ratio


def test_reprojection_rms_measures_the_noise():
    rng = np.random.default_rng(3)
    T_true = camera.camera_in_marker(MOUNT, SYSTEM.fk(np.zeros(6)))
    view = camera.with_noise(camera.visible_corners(BOARD, K, SIZE, T_true), 0.5, rng)
    estimate = pose.pose_from_view(view, K)
    dof = 2 * estimate.n_points - 6
    sigma = estimate.rms_px * math.sqrt(estimate.n_points / dof)  # E[SSR] = (2N − 6) σ², rms² = SSR / N
    assert 0.3 < sigma < 0.7


@pytest.mark.parametrize("obj, img, match", [
    (np.zeros((5, 2)), np.zeros((5, 2)), "object_points must have shape \\(N, 3\\)"),
    (np.zeros((5, 3)), np.zeros((4, 2)), "image_points must have shape"),
    (np.zeros((3, 3)), np.zeros((3, 2)), "at least 4"),
    (np.full((5, 3), np.nan), np.zeros((5, 2)), "finite"),
    (np.column_stack((np.arange(5.0), np.zeros(5), np.zeros(5))), np.zeros((5, 2)), "one line"),
    ("abc", np.zeros((5, 2)), "must be real numbers"),
])
def test_bad_correspondences_raise_a_typed_error(obj, img, match):
    with pytest.raises(pose.PoseError, match=match):
        estimate_pose(obj, img, K)


def test_bad_intrinsics_and_options_raise_typed_errors():
    view = camera.visible_corners(BOARD, K, SIZE, camera.camera_in_marker(MOUNT, SYSTEM.fk(np.zeros(6))))
    with pytest.raises(carmkin.CarmkinError, match="K must be"):
        estimate_pose(view.object_points, view.image_points, np.eye(2))
    with pytest.raises(pose.PoseError, match="refine"):
        pose.solve_pose(view.object_points, view.image_points, K, refine="gauss")
    with pytest.raises(pose.PoseError, match="sigma_px"):
        pose.solve_pose(view.object_points, view.image_points, K, sigma_px=-1.0)


def test_a_view_of_the_back_of_the_board_is_empty():
    T = camera.camera_in_marker(MOUNT, SYSTEM.fk(np.zeros(6)))
    flipped = T.copy()
    flipped[2, 3] = -T[2, 3]
    assert len(camera.visible_corners(BOARD, K, SIZE, flipped)) == 0
    with pytest.raises(pose.PoseError, match="too few"):
        pose.pose_from_view(camera.visible_corners(BOARD, K, SIZE, flipped), K)


def test_noisy_estimates_leak_no_warning():
    """Over random reference configurations the LM may start from a poor IPPE candidate; nothing may warn."""
    import warnings

    from carmkin.reposition import experiment
    from carmkin.reposition.world import World
    from carmkin.world import World as CollisionWorld

    rng = np.random.default_rng(12)
    world = World(SYSTEM, BOARD, MOUNT, MOUNT[:3, :3])
    scene = CollisionWorld(SYSTEM)
    config = experiment.ExperimentConfig()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for _ in range(40):
            q = experiment.sample_reference(world, config, rng, scene)
            estimate = world.measure_marker(SYSTEM.fk(q), rng)
            assert np.all(np.isfinite(estimate.T))


def test_the_zero_joint_start_looking_straight_at_the_board_is_solved():
    """§4.6.2's starting position: a fronto-parallel view, where IPPE alone returns NaN (found by hypothesis)."""
    q = np.array([0.0, 0.0, 5.96046448e-08, 0.0, 3.125e-02, 0.0])
    T_true = camera.camera_in_marker(MOUNT, SYSTEM.fk(q))
    estimate = pose.pose_from_view(camera.visible_corners(BOARD, K, SIZE, T_true), K)
    assert np.linalg.norm(estimate.T[:3, 3] - T_true[:3, 3]) <= EXACT


def test_the_estimate_carries_its_residuals():
    rng = np.random.default_rng(9)
    T_true = camera.camera_in_marker(MOUNT, SYSTEM.fk(np.zeros(6)))
    view = camera.with_noise(camera.visible_corners(BOARD, K, SIZE, T_true), 0.2, rng)
    estimate = pose.pose_from_view(view, K, sigma_px=0.2)
    projected, depth = camera.project_points(K, estimate.T, view.object_points)  # independent projection
    np.testing.assert_allclose(estimate.residuals_px, projected - view.image_points, atol=1e-9)
    assert estimate.rms_px == pytest.approx(math.sqrt(np.mean(np.sum(estimate.residuals_px**2, axis=1))))
    assert np.all(depth > 0) and estimate.condition < pose.ILL_CONDITIONED and not estimate.ill_conditioned
    assert np.all(estimate.sd > 0)


def test_corners_no_pose_explains_are_refused():
    """Shuffled correspondences, or corners noisier than the stated σ: the residual test refuses."""
    rng = np.random.default_rng(2)
    T_true = camera.camera_in_marker(MOUNT, SYSTEM.fk(np.zeros(6)))
    view = camera.visible_corners(BOARD, K, SIZE, T_true)
    shuffled = view.image_points[rng.permutation(len(view.image_points))]
    with pytest.raises(pose.PoseError, match="no pose"):
        pose.solve_pose(view.object_points, shuffled, K)
    noisy = camera.with_noise(view, 1.0, rng)
    with pytest.raises(pose.PoseError, match="stated corner noise"):
        pose.solve_pose(noisy.object_points, noisy.image_points, K, sigma_px=0.05)
    assert pose.solve_pose(noisy.object_points, noisy.image_points, K, sigma_px=1.0).rms_px < 5.0


def test_tracking_from_the_previous_pose_gives_the_same_minimum():
    rng = np.random.default_rng(3)
    T_true = camera.camera_in_marker(MOUNT, SYSTEM.fk(np.array([0.0, 0.05, 0.0, 0.1, 0.2, -0.2])))
    view = camera.with_noise(camera.visible_corners(BOARD, K, SIZE, T_true), 0.2, rng)
    alone = pose.pose_from_view(view, K)
    tracked = pose.pose_from_view(view, K, T_previous=T_true)
    np.testing.assert_allclose(tracked.T, alone.T, atol=1e-8)


def test_an_estimate_expressed_in_the_table_frame():
    from scipy.spatial.transform import Rotation

    T_true = camera.camera_in_marker(MOUNT, SYSTEM.fk(np.zeros(6)))
    estimate = pose.pose_from_view(camera.visible_corners(BOARD, K, SIZE, T_true), K, sigma_px=0.2)
    moved = estimate.expressed_in(MOUNT)
    np.testing.assert_allclose(moved.T, MOUNT @ estimate.T, atol=1e-12)
    # the variance of the table-frame position along any direction u is that of the marker-frame position
    # along R^T u (an independent check of the rotated blocks)
    u = Rotation.from_rotvec([0.3, 0.2, 0.1]).apply([0.0, 0.0, 1.0])
    v = MOUNT[:3, :3].T @ u
    assert u @ moved.covariance[3:, 3:] @ u == pytest.approx(v @ estimate.covariance[3:, 3:] @ v, rel=1e-9)
    assert u @ moved.covariance[:3, :3] @ u == pytest.approx(v @ estimate.covariance[:3, :3] @ v, rel=1e-9)
