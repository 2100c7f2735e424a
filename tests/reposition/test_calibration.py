"""Marker→table calibration (§3.3.3): exact recovery for any rotation, accuracy under noise, degeneracy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from strategies import rotations

from carmkin.reposition import CalibrationError, calibrate_table
from carmkin.reposition.calibration import METHODS, calibrate, calibration_moves, residual_rms
from carmkin.reposition.calibration import rotation_angle as angle
from carmkin.reposition.world import random_rotation

finite = dict(allow_nan=False, allow_infinity=False)
#: Issue 14: ≤ 0.1° with 0.2 mm noise on ≥ 6 positions (checked on the 95th percentile of 200 draws).
NOISY_LIMIT_DEG = 0.1
NOISE = 0.0002


@given(rotations(), st.integers(3, 12), st.floats(0.05, 0.5, **finite),
       st.sampled_from([(2, 1), (2, 0), (0, 1), (2, 1, 0)]), st.sampled_from(METHODS),
       st.tuples(*(st.floats(-1, 1, **finite),) * 3))
def test_noise_free_translations_recover_any_rotation(R, positions, span, axes, method, start):
    moves = calibration_moves(max(positions, len(axes) + 1), span, axes)
    camera_positions = moves @ R + np.array(start)  # p_marker = tRmᵀ p_table, first position anywhere
    estimate = calibrate_table(camera_positions, moves, method=method)
    assert angle(estimate, R) <= 1e-9
    assert residual_rms(estimate, camera_positions, moves) <= 1e-9


@given(rotations(), st.lists(st.tuples(*(st.floats(-0.3, 0.3, **finite),) * 3), min_size=3, max_size=10))
def test_svd_accepts_arbitrary_displacements(R, rows):
    moves = np.vstack(([0.0, 0.0, 0.0], np.array(rows)))
    s = np.linalg.svd(moves - moves.mean(axis=0), compute_uv=False)
    assume(s[1] > 1e-2 * s[0] and s[1] > 1e-3)  # well spread; the degenerate case is tested below
    assert angle(calibrate_table(moves @ R, moves), R) <= 1e-9


@pytest.mark.parametrize("method", METHODS)
def test_six_positions_with_0_2_mm_noise_recover_the_rotation_to_0_1_deg(method):
    rng = np.random.default_rng(11)
    moves = calibration_moves(6, 0.4, axes=(2, 1, 0))  # 0.4 m along the translation, height and lateral
    errors = []
    for _ in range(200):
        R = random_rotation(rng, rng.uniform(0.0, math.pi))
        measured = moves @ R + rng.normal(0.0, NOISE, moves.shape)
        errors.append(math.degrees(angle(calibrate_table(measured, moves, method=method), R)))
    assert np.percentile(errors, 95) <= NOISY_LIMIT_DEG


def test_moves_along_one_direction_are_degenerate():
    moves = np.array([[0, 0, 0], [0, 0, 0.1], [0, 0, 0.2], [0, 0, 0.3]], float)
    with pytest.raises(CalibrationError, match="two directions"):
        calibrate_table(moves, moves)


@pytest.mark.parametrize("positions, moves, match", [
    (np.zeros((2, 3)), np.zeros((2, 3)), "at least 3"),
    (np.zeros((4, 2)), np.zeros((4, 2)), "shape"),
    (np.zeros((4, 3)), np.zeros((5, 3)), "shape"),
    (np.full((4, 3), np.inf), np.eye(4, 3), "finite"),
])
def test_bad_calibration_input_raises(positions, moves, match):
    with pytest.raises(CalibrationError, match=match):
        calibrate_table(positions, moves)


def test_lines_needs_moves_along_single_axes():
    moves = np.array([[0, 0, 0], [0.1, 0.1, 0], [0, 0.2, 0], [0, 0, 0.2]], float)
    with pytest.raises(CalibrationError, match="single table axis"):
        calibrate_table(moves, moves, method="lines")
    with pytest.raises(CalibrationError, match="method"):
        calibrate_table(moves, moves, method="kabsch")


def test_calibration_moves_plan():
    moves = calibration_moves(7, 0.3, axes=(2, 1))
    assert np.array_equal(moves[0], np.zeros(3))
    assert np.count_nonzero(moves[:, 2]) == 3 and np.count_nonzero(moves[:, 1]) == 3
    assert moves.max() == pytest.approx(0.3)
    with pytest.raises(CalibrationError):
        calibration_moves(2, 0.3)
    with pytest.raises(CalibrationError):
        calibration_moves(6, 0.3, axes=(2,))


def test_a_still_marker_is_refused_not_the_identity():
    """Issue 19: the camera saw no move (a marker out of view, a stale pose) while the table moved."""
    moves = calibration_moves(6, 0.2)
    still = np.tile([0.1, -0.2, -0.4], (6, 1))
    for measured in (still, still + np.random.default_rng(1).normal(0.0, 0.001, still.shape)):
        for method in METHODS:
            with pytest.raises(CalibrationError, match="camera_positions_marker"):
                calibrate_table(measured, moves, method=method)


@given(rotations(), st.sampled_from([0.5, 0.9, 1.1, 2.0]))
def test_displacements_of_the_wrong_length_are_refused(R, factor):
    moves = calibration_moves(6, 0.2)
    with pytest.raises(CalibrationError, match="moved .* mm from the first position"):
        calibrate_table(factor * moves @ R, moves)


def test_camera_moving_along_one_line_only_is_refused():
    moves = calibration_moves(6, 0.2)
    along_one = np.outer(np.linalg.norm(moves, axis=1), [0.0, 0.6, 0.8])  # right lengths, one direction
    with pytest.raises(CalibrationError, match="one line only"):
        calibrate_table(along_one, moves)


def test_displacements_no_rotation_explains_are_refused():
    """Right lengths, but a reflection of the moves: no rotation maps one set onto the other."""
    moves = calibration_moves(6, 0.2, axes=(2, 1, 0))
    with pytest.raises(CalibrationError, match="no rotation maps"):
        calibrate_table(moves * (1.0, 1.0, -1.0), moves)


@given(rotations(), st.floats(0.0, 0.002, **finite))
def test_calibrate_returns_the_residuals(R, sigma):
    rng = np.random.default_rng(5)
    moves = calibration_moves(8, 0.3, axes=(2, 1, 0))
    measured = moves @ R + rng.normal(0.0, sigma, moves.shape)
    result = calibrate(measured, moves)
    # independent: the residual of each position from the definition, with the returned rotation
    expected = np.array([result.tRm @ (p - measured[0]) - (d - moves[0]) for p, d in zip(measured, moves)])
    np.testing.assert_allclose(result.residuals, expected, atol=1e-12)
    assert result.rms == pytest.approx(math.sqrt(np.mean(np.sum(expected**2, axis=1))))
    assert np.array_equal(result.tRm, calibrate_table(measured, moves))


def _siremobile():
    from carmkin.presets import load_preset

    return load_preset("siremobile-iso-c3d")


def _noisy_calibration_run(corner_noise_px: float, seed: int):
    """Six camera estimates of a §3.3.3 run on the Siremobile preset at ``corner_noise_px`` per estimate."""
    from carmkin.reposition.world import World

    system = _siremobile()
    rng = np.random.default_rng(seed)
    world = World.create(system, rng, mount_error=math.radians(2.0), corner_noise_px=corner_noise_px)
    moves, T0 = calibration_moves(6, 0.2), system.fk(np.zeros(system.nq))
    estimates = []
    for d in moves:
        T = T0.copy()
        T[:3, 3] += d
        estimates.append(world.measure_marker(T, rng))
    return world, moves, np.array([e.T[:3, 3] for e in estimates]), np.array([e.covariance[3:, 3:] for e in estimates])


@pytest.mark.parametrize("corner_noise_px", [1.0, 1.5])
def test_realistic_corner_noise_is_not_refused(corner_noise_px):
    """Issue 31: at 1 px corner noise the fixed 5 mm tolerance refused the grid's first room (position 3
    moved 210.81 mm for 200 mm). With the estimator's covariances the same runs calibrate (the grid's
    corner noise, filtered over five frames as the experiments read it), within 5° of the truth (the noise's
    own scale: 1–4° at 1.5 px, docs/fidelity.md)."""
    from carmkin.reproduce.error_model import ErrorModel
    from carmkin.reproduce.measure import filtered_noise
    from carmkin.reproduce.repositioning import make_room

    for seed in range(3):  # the fit's grid uses seed 0
        room = make_room(_siremobile(), ErrorModel(corner_noise_px=corner_noise_px), np.random.default_rng(seed))
        assert angle(room.world.tRm, room.world.T_table_marker[:3, :3]) < math.radians(5.0)
    refused_fixed = 0
    for seed in range(20):
        world, moves, P, C = _noisy_calibration_run(filtered_noise(corner_noise_px, 5), seed)
        result = calibrate(P, moves, covariances=C)
        assert angle(result.tRm, world.T_table_marker[:3, :3]) < math.radians(5.0)
        try:
            calibrate(P, moves)
        except CalibrationError:
            refused_fixed += 1
    assert refused_fixed >= (1 if corner_noise_px == 1.5 else 0)  # the old rule refused 7 of these 20 at 1.5 px


def test_with_covariances_a_still_marker_or_wrong_lengths_are_still_refused():
    world, moves, P, C = _noisy_calibration_run(0.5, 0)
    still = np.tile(P[0], (6, 1))
    with pytest.raises(CalibrationError, match="camera_positions_marker"):
        calibrate(still, moves, covariances=C)
    with pytest.raises(CalibrationError):
        calibrate(P[0] + 1.5 * (P - P[0]), moves, covariances=C)


def test_one_gross_outlier_is_left_out_and_named():
    world, moves, P, C = _noisy_calibration_run(0.5, 1)
    P = P.copy()
    P[4] += [0.0, 0.0, 0.08]  # 80 mm off: a flipped pose estimate
    with pytest.raises(CalibrationError):
        calibrate(P, moves)
    result = calibrate(P, moves, covariances=C)
    assert result.outlier == 4
    keep = np.arange(6) != 4
    assert angle(result.tRm, calibrate(P[keep], moves[keep], covariances=C[keep]).tRm) < 1e-12


def test_covariances_are_checked():
    moves = calibration_moves(6, 0.2)
    for bad in (np.zeros((5, 3, 3)), -np.tile(np.eye(3), (6, 1, 1)), np.full((6, 3, 3), np.nan)):
        with pytest.raises(CalibrationError, match="covariances"):
            calibrate(moves, moves, covariances=bad)
