"""The simulated §4.6.2 experiment: a few tasks end repositioned, collision-free, with finite errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

import carmkin
from carmkin.reposition import experiment
from carmkin.reposition.world import OperatorModel, SimulationError, World

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")


def test_a_few_tasks_are_repositioned_within_the_thresholds():
    results = experiment.run_experiment(SYSTEM, experiment.ExperimentConfig(), tasks=3, seed=2)
    assert all(r.success for r in results), [r.reason for r in results]
    for r in results:
        assert r.min_clearance > 0.0 and r.steps >= 1
        assert r.image_errors.shape == (16,) and np.all(np.isfinite(r.image_errors))
        assert 0.0 <= r.translation < 0.05 and 0.0 <= r.rotation < math.radians(2.0)


def test_exact_measurements_and_operator_end_on_the_reference():
    config = experiment.ExperimentConfig(corner_noise_px=0.0, operator=OperatorModel(0.0, 0.0, 0.0),
                                         calibration="exact")
    results = experiment.run_experiment(SYSTEM, config, tasks=2, seed=4)
    for r in results:
        assert r.success
        assert r.translation < 1e-6 and r.rotation < 1e-6 and r.image_errors.max() < 1e-3
        assert r.steps <= SYSTEM.nq  # each joint at most once


def test_table_and_sensitivity_print_the_seed_numbers():
    stats = experiment.summary(experiment.run_experiment(SYSTEM, experiment.ExperimentConfig(), tasks=2, seed=1))
    table = experiment.format_table(stats)
    assert "5.20 ± 2.60" in table and "4.60 ± 1.50" in table and "0.37 ± 0.16" in table
    rows = experiment.sensitivity(SYSTEM, tasks=1, rows=experiment.SENSITIVITY_ROWS[:2])
    text = experiment.format_sensitivity(rows)
    assert "baseline" in text and "no corner noise" in text


def test_rotation_error_is_the_mean_of_the_three_axes():
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("xyz", [0.01, -0.02, 0.03]).as_matrix()
    assert experiment.rotation_error(np.eye(3), R) == pytest.approx(0.02)


@pytest.mark.parametrize("changes, match", [
    ({"table_shift": -1.0}, "table_shift"),
    ({"max_steps": 0}, "max_steps"),
    ({"calibration": "magic"}, "calibration"),
])
def test_bad_settings_raise(changes, match):
    with pytest.raises(SimulationError, match=match):
        experiment.ExperimentConfig(**changes)


def test_bad_noise_and_operator_raise():
    with pytest.raises(SimulationError, match="corner noise"):
        World.create(SYSTEM, np.random.default_rng(0), corner_noise_px=-1.0)
    with pytest.raises(SimulationError, match="relative"):
        OperatorModel(relative=float("nan"))
    with pytest.raises(SimulationError, match="tasks"):
        experiment.run_experiment(SYSTEM, tasks=0)


def test_a_motorized_table_task_goes_through_the_one_solve():
    motorized = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
    results = experiment.run_experiment(motorized, experiment.ExperimentConfig(), tasks=1, seed=3)
    assert results[0].success, results[0].reason
    assert results[0].translation < 0.05
