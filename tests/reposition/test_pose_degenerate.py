"""Pose estimation on degenerate-but-valid boards with exact corners: the right pose or a typed error (issue 19).

Truth is the pose the corners were projected from (``degenerate.case``); "right" means within
:data:`EXACT` in rotation (rad) and position (m).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from degenerate import KINDS, WIDE_K, XRAY_K, case
from hypothesis import assume, given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import carmkin
from carmkin.reposition import camera, estimate_pose, pose
from carmkin.reposition.calibration import rotation_angle

#: Issue 19: exact corners give the true pose to 1e-9 (m and rad), or a typed error.
EXACT = 1e-9
#: Boards per kind in the acceptance run (4 kinds: 1000 boards).
BOARDS_PER_KIND = 250
finite = dict(allow_nan=False, allow_infinity=False)


def _right(T, T_true) -> bool:
    return rotation_angle(T[:3, :3], T_true[:3, :3]) <= EXACT and np.linalg.norm(T[:3, 3] - T_true[:3, 3]) <= EXACT


def _fronto_parallel_grid(angle: float, distance: float, K, columns=7, rows=5, pitch=0.022):
    x, y = np.meshgrid(np.arange(columns) * pitch, np.arange(rows) * pitch)
    X = np.column_stack((x.ravel(), y.ravel(), np.zeros(x.size)))
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("z", angle).as_matrix()
    T[:3, 3] = X.mean(axis=0) - distance * T[:3, 2]
    return X, camera.project_points(K, T, X)[0], T


@pytest.mark.parametrize("K", [XRAY_K, WIDE_K], ids=["xray", "wide"])
@pytest.mark.parametrize("distance", [0.4, 1.07, 1.83])
def test_fronto_parallel_grid_rotated_180_deg_is_solved(K, distance):
    """The reported defect: IPPE's candidates degenerate but finite, LM from them 0.24 m / 12° off (or metres)."""
    X, pixels, T_true = _fronto_parallel_grid(math.pi, distance, K)
    estimate = pose.solve_pose(X, pixels, K)
    assert _right(estimate.T, T_true)
    assert estimate.rms_px <= 1e-9
    assert _right(estimate_pose(X, pixels, K), T_true)


def _mirror(T: np.ndarray) -> np.ndarray:
    """The mirror pose of a planar board (Z = 0): every camera coordinate negated — the same pixels, every
    point behind the camera. Marker-to-camera ``R' = −R diag(1, 1, −1)``, ``t' = −t`` (a proper rotation)."""
    R, t = T[:3, :3].T, -T[:3, :3].T @ T[:3, 3]
    R2, t2 = -R @ np.diag([1.0, 1.0, -1.0]), -t
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = R2.T, -R2.T @ t2
    return M


def test_the_mirror_pose_is_never_returned():
    X, pixels, T_true = _fronto_parallel_grid(0.3, 0.8, WIDE_K)
    tilt = np.eye(4)
    tilt[:3, :3] = Rotation.from_rotvec([0.3, -0.2, 0.0]).as_matrix()
    T_true = T_true @ tilt  # an oblique view, rotated about the camera centre
    pixels, depth = camera.project_points(WIDE_K, T_true, X)
    assert np.all(depth > 0)
    mirror = _mirror(T_true)
    assert np.all(camera.project_points(WIDE_K, mirror, X)[1] < 0)
    np.testing.assert_allclose(camera.project_points(WIDE_K, mirror, X)[0], pixels, atol=1e-9)  # same pixels
    estimate = pose.solve_pose(X, pixels, WIDE_K, T_previous=mirror)  # even offered as the tracking start
    assert _right(estimate.T, T_true)
    assert np.all(camera.project_points(WIDE_K, estimate.T, X)[1] > 0)


def test_points_only_explained_from_behind_are_refused():
    """Non-planar points behind the camera: the exact fit has every depth negative (and no rigid pose in
    front fits), so the estimate is refused, never returned."""
    rng = np.random.default_rng(4)
    X = rng.uniform(-0.1, 0.1, (12, 3)) + (0.0, 0.0, 0.8)
    pixels, _ = camera.project_points(WIDE_K, np.eye(4), X)
    with pytest.raises(pose.PoseError, match="in front|no pose explains"):
        pose.solve_pose(-X, pixels, WIDE_K)


def test_acceptance_degenerate_boards_right_or_refused():
    """≥ 1000 exactly fronto-parallel, mirrored, nearly collinear and 4-point boards with exact corners: the
    right pose to 1e-9 or a typed error, never a wrong pose. Prints the counts."""
    rng = np.random.default_rng(19)
    counts = {kind: {"right": 0, "refused": 0, "wrong": 0} for kind in KINDS}
    wrong = []
    for i in range(BOARDS_PER_KIND * len(KINDS)):
        kind = KINDS[i % len(KINDS)]
        X, pixels, K, T_true = case(kind, rng)
        try:
            T = estimate_pose(X, pixels, K)
        except carmkin.CarmkinError:
            counts[kind]["refused"] += 1
            continue
        if _right(T, T_true):
            counts[kind]["right"] += 1
        else:
            counts[kind]["wrong"] += 1
            wrong.append((kind, rotation_angle(T[:3, :3], T_true[:3, :3]), np.linalg.norm(T[:3, 3] - T_true[:3, 3])))
    print(f"\n{'board':<12}{'right':>8}{'refused':>9}{'wrong':>7}")
    for kind, c in counts.items():
        print(f"{kind:<12}{c['right']:>8}{c['refused']:>9}{c['wrong']:>7}")
    total = {k: sum(c[k] for c in counts.values()) for k in ("right", "refused", "wrong")}
    print(f"{'all':<12}{total['right']:>8}{total['refused']:>9}{total['wrong']:>7}")
    assert total["wrong"] == 0, wrong[:5]
    # the refusals are the nearly collinear boards whose points do not determine the pose; the rest is solved
    assert all(counts[kind]["refused"] == 0 for kind in ("fronto", "mirrored", "four"))


@st.composite
def boards_and_poses(draw):
    """A random grid board, a random pose from which every point is in front, and one of two cameras."""
    columns, rows = draw(st.integers(2, 8)), draw(st.integers(2, 8))
    pitch = draw(st.floats(0.005, 0.05, **finite))
    x, y = np.meshgrid(np.arange(columns) * pitch, np.arange(rows) * pitch)
    X = np.column_stack((x.ravel(), y.ravel(), np.zeros(x.size)))
    K = draw(st.sampled_from([XRAY_K, WIDE_K]))
    rotvec = np.array([draw(st.floats(-math.pi, math.pi, **finite)) for _ in range(3)])
    R = Rotation.from_rotvec(rotvec).as_matrix()
    distance = draw(st.floats(0.1, 3.0, **finite))
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = X.mean(axis=0) - distance * R[:, 2]
    return X, K, T


@given(boards_and_poses())
def test_noise_free_pose_is_the_truth_or_refused_when_ill_conditioned(board):
    """Random boards and poses, exact corners: the truth to 1e-9; a refusal only for an ill-conditioned view
    (a board seen edge-on, or tiny for its distance)."""
    X, K, T_true = board
    pixels, depth = camera.project_points(K, T_true, X)
    assume(np.all(depth > 0.02))  # every point at least 2 cm in front (a wide board seen close may not be)
    try:
        estimate = pose.solve_pose(X, pixels, K)
    except pose.PoseError:
        J = pose.reprojection_jacobian(K, T_true, X)
        assert np.linalg.cond(J / np.linalg.norm(J, axis=0)) > pose.ILL_CONDITIONED
        return
    assert _right(estimate.T, T_true)
    assert not np.any(estimate.residuals_px > 1e-6)
