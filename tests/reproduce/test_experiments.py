"""§4.6.3, Tables 3.1–3.2, the fit, the decomposition and the verdict: exact cases and independent checks."""

from __future__ import annotations

import math

import numpy as np
import pytest

import carmkin
from carmkin.errors import SimulationError
from carmkin.reposition.guidance import GuidanceOptions
from carmkin.reproduce import chapter3, fit, joints, repositioning, stitching, verdict
from carmkin.reproduce.error_model import ErrorModel, square_pixel_system

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")
#: The exact case: no error source, and thresholds so small the operator zeroes every joint.
EXACT_GUIDANCE = GuidanceOptions(translation_threshold=1e-12, rotation_threshold=1e-12)
#: Exact up to the IK / FK round trip, the PnP of the ground truth and the homographies (px, m, rad).
EXACT = 1e-9


def test_without_noise_the_panorama_is_exact():
    procedures = stitching.run(SYSTEM, ErrorModel.exact(), procedures=1, seed=3, guidance=EXACT_GUIDANCE)
    p = procedures[0]
    assert p.success, p.reason
    assert p.images >= 3 and p.image_errors.size > 10
    assert np.max(p.image_errors) <= EXACT
    assert p.distance_errors.size == 5 and np.max(p.distance_errors) <= EXACT
    assert p.angle_errors.size == 5 and np.max(p.angle_errors) <= EXACT


def test_without_noise_tables_3_1_and_3_2_are_exact():
    rows = chapter3.table_3_1(SYSTEM, ErrorModel.exact(), procedures=1, seed=2, guidance=EXACT_GUIDANCE)
    (without, with_) = rows["overall"]
    assert without[2] >= 6 and without[0] <= EXACT and with_[0] <= EXACT
    measured = chapter3.table_3_2(SYSTEM, ErrorModel.exact(), seed=2, guidance=EXACT_GUIDANCE)
    for method in "ABC":
        assert measured[method] == pytest.approx({"240 mm": 240.0, "120 mm": 120.0, "90 deg": 90.0,
                                                  "180 deg": 180.0}, abs=1e-6)


def test_the_measured_pairs_and_triples_are_the_seed_s_360_mm_and_90_degrees():
    points = stitching.phantom_points()
    assert np.ptp(points[:, 0]) == pytest.approx(0.44) and np.ptp(points[:, 1]) == pytest.approx(0.08)
    pairs, triples = stitching.measurement_sets(points, np.ones(len(points), bool))
    assert len(pairs) == len(triples) == 5
    assert np.allclose(np.linalg.norm(points[pairs[:, 1]] - points[pairs[:, 0]], axis=1), 0.36)
    u = points[triples[:, 0]] - points[triples[:, 1]]
    v = points[triples[:, 2]] - points[triples[:, 1]]
    assert np.allclose(np.sum(u * v, axis=1), 0.0) and np.all(np.linalg.norm(v, axis=1) > 0)
    none = stitching.measurement_sets(points, np.zeros(len(points), bool))
    assert none[0].shape == (0, 2) and none[1].shape == (0, 3)


def test_the_image_jacobian_predicts_a_small_joint_move():
    system = square_pixel_system(SYSTEM)
    q = np.array([0.05, 0.1, 0.05, 0.1, 0.2, -0.1])
    T = system.fk(q)
    points = T[:3, 3] + 0.5 * T[:3, 2] + np.random.default_rng(0).normal(0, 0.03, (8, 3))
    J = joints.image_jacobian(system, q, points)
    dq = np.array([1e-4, -1e-4, 2e-5, 1e-4, -3e-5, 2e-5])
    from carmkin.imaging import project

    K = system.carm.intrinsics()
    moved = project(K, system.fk(q + dq), points) - project(K, T, points)
    predicted = np.einsum("jnk,j->nk", J, dq)
    assert np.max(np.abs(moved - predicted)) < 1e-3 * np.max(np.abs(moved))


def test_the_decomposition_explains_the_image_error_to_first_order():
    system = SYSTEM
    tasks = repositioning.run(system, ErrorModel(corner_noise_px=0.5).with_operator_scale(0.2), tasks=3, seed=1)
    table = joints.decompose(square_pixel_system(system), tasks)
    assert table["pixels"].shape == (system.nq,) and np.all(table["sensitivity"] > 0)
    assert table["linear_residual"] < 0.1 * np.linalg.norm(table["pixels"])
    text = joints.format_decomposition(square_pixel_system(system), table)
    assert "px/mm" in text and "px/deg" in text


def test_ten_task_statistics_of_identical_tasks_have_no_spread():
    values = [(np.full(16, 3.0), 2.0, 0.5)] * 4
    stats = fit.ten_task_statistics(values, np.random.default_rng(0), resamples=20)
    assert np.allclose(stats, [3.0, 0.0, 2.0, 0.0, 0.5, 0.0])
    assert fit.seed_vector().tolist() == [5.2, 2.6, 4.6, 1.5, 0.37, 0.16]


def test_a_one_point_fit_reports_its_verdict():
    result = fit.fit(SYSTEM, corner_noise=(0.5,), operator_scale=(0.4,), tasks=4, resamples=50)
    assert result.best in result.region and result.best.chi2 == pytest.approx(float(result.best.z @ result.best.z))
    assert "REPRODUCED" in result.verdict() and "chi2" in fit.format_fit(result)


@pytest.mark.parametrize("grid", [(), (-1.0,), ("a",), (math.nan,)])
def test_a_bad_grid_is_refused_naming_it(grid):
    with pytest.raises(SimulationError, match="corner_noise"):
        fit.fit(SYSTEM, corner_noise=grid, operator_scale=(1.0,), tasks=2)


def test_judge_reproduced_not_reproduced_undetermined():
    assert verdict.judge("x", "q", 1.0, [1.0, 1.1, 0.9]).verdict == "reproduced"
    assert verdict.judge("x", "q", 5.0, [1.0, 1.1, 0.9]).verdict == "not reproduced"
    assert verdict.judge("x", "q", 5.0, [1.0, 1.1, 0.9], seed_error=3.0).verdict == "reproduced"
    assert verdict.judge("x", "q", 5.0, [math.nan]).verdict == "undetermined"
    assert verdict.judge("x", "q", 2.0, [1.0, 20.0, 35.0]).verdict == "undetermined"  # too wide to decide
    assert verdict.judge("x", "q", 2.0, [6.0, 20.0, 35.0, 33.0]).verdict == "not reproduced"  # all above it


def test_the_two_readings_of_the_rotational_error():
    """For small rotations the XYZ Euler angles are the rotation vector's components, so their mean absolute
    value is at most the rotation's angle and at least a third of it."""
    tasks = [t for t in repositioning.run(SYSTEM, ErrorModel(corner_noise_px=0.5), tasks=3, seed=4) if t.success]
    assert tasks
    for t in tasks:
        assert t.rotation_angle / 3 * (1 - 1e-3) <= t.rotation <= t.rotation_angle * (1 + 1e-3)
    axes, angle = fit.task_values(tasks, "axes"), fit.task_values(tasks, "angle")
    assert [a[2] for a in axes] == [math.degrees(t.rotation) for t in tasks]
    assert [a[2] for a in angle] == [math.degrees(t.rotation_angle) for t in tasks]
    with pytest.raises(SimulationError, match="rotation"):
        fit.task_values(tasks, "euler")
