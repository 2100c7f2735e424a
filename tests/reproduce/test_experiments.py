"""§4.6.3, Tables 3.1–3.2, the fit, the decomposition and the verdict: exact cases and independent checks."""

from __future__ import annotations

import dataclasses
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


@pytest.mark.parametrize("protocol, preset", [(p, "siremobile-iso-c3d") for p in chapter3.PROTOCOLS]
                         + [("chapter3", "siremobile-iso-c3d-motorized-table")])
def test_without_noise_tables_3_1_and_3_2_are_exact(protocol, preset):
    """§3.3.4.2's protocol too (on both presets): an exact camera and operator compensate the source
    translation in one move of the prismatic joints (linear in them), and the measured rotation is the true one."""
    system = carmkin.load_preset(preset)
    rows = chapter3.table_3_1(system, ErrorModel.exact(), procedures=1, seed=2, guidance=EXACT_GUIDANCE,
                              protocol=protocol)
    (without, with_) = rows["overall"]
    assert without[2] >= 6 and without[0] <= EXACT and with_[0] <= EXACT
    measured = chapter3.table_3_2(system, ErrorModel.exact(), seed=2, guidance=EXACT_GUIDANCE, protocol=protocol)
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
    assert verdict.judge("x", "q", 5.0, [math.nan]).verdict == "undetermined"
    assert verdict.judge("x", "q", 2.0, [1.0, 20.0, 35.0]).verdict == "undetermined"  # too wide to decide
    # the former one-sided rule called this "not reproduced"; the t-test cannot reject it at α = 0.05
    assert verdict.judge("x", "q", 2.0, [6.0, 20.0, 35.0, 33.0]).verdict == "undetermined"
    row = verdict.judge("x", "q", 5.0, [1.0, 1.1, 0.9], kind="fitted", why="chosen on it")
    assert row.kind == "fitted" and "α 0.05" in row.criterion and row.statistic > row.critical


def test_the_t_criterion_is_the_prediction_interval_of_the_t_table():
    """Oracle: the two-sided 95 % points of Student's t from a printed table (1 and 3 degrees of freedom)."""
    assert verdict.t_critical(2) == pytest.approx(12.706 * math.sqrt(1.5), rel=1e-4)
    assert verdict.t_critical(4) == pytest.approx(3.182 * math.sqrt(1.25), rel=1e-3)


@pytest.mark.parametrize("n", [3, 4, 8])
def test_the_verdict_rejects_a_consistent_value_at_its_stated_rate(n):
    """The seed's number and the repeats drawn from one normal distribution: "not reproduced" about ALPHA
    of the time (the former "all four on one side" rule: up to 40 %). 4000 draws: ±4 binomial σ."""
    rng = np.random.default_rng(n)
    draws = rng.normal(10.0, 2.0, (4000, n + 1))
    rejected = np.mean([verdict.judge("x", "q", d[0], d[1:]).verdict == "not reproduced" for d in draws])
    sigma = math.sqrt(verdict.ALPHA * (1 - verdict.ALPHA) / len(draws))
    assert abs(rejected - verdict.ALPHA) < 4 * sigma


def test_the_tolerance_test_counts_repeats_above_the_seeds_one_percent():
    """Oracle: the binomial tail by enumeration; with four repeats one above 1 % is allowed, two are not."""
    def tail(k, n, p):
        return sum(math.comb(n, j) * p**j * (1 - p) ** (n - j) for j in range(k + 1, n + 1))

    for n in (2, 4, 8, 20):
        allowed = verdict.tolerance_failures_allowed(n)
        assert tail(allowed, n, verdict.TOLERANCE_SHARE) <= verdict.ALPHA
        assert allowed == 0 or tail(allowed - 1, n, verdict.TOLERANCE_SHARE) > verdict.ALPHA
    assert verdict.judge_tolerance("3.2", "240", 239.8, 240.0, [239.0, 240.5, 241.0, 237.0]).verdict == "reproduced"
    row = verdict.judge_tolerance("3.2", "240", 239.8, 240.0, [235.0, 240.5, 244.0, 238.0])
    assert row.verdict == "not reproduced" and "2 of 4 repeats above" in row.criterion


def test_every_row_has_a_kind_and_only_predicted_rows_count():
    rows = verdict.rows_4_6_2(SYSTEM, ErrorModel(corner_noise_px=0.5), repeats=2, tasks=2)
    assert {r.quantity: r.kind for r in rows}["mean translation (mm)"] == "fitted"
    # issue 41: the rotation-angle rows re-test the seed's 0.37 ± 0.16° the fit was chosen on: fitted too
    assert {r.quantity: r.kind for r in rows}["mean rotation angle (deg)"] == "fitted"
    assert all(r.kind in verdict.KINDS and r.criterion for r in rows)
    counts = verdict.counts(rows)
    assert sum(counts["fitted"].values()) == 8 and sum(counts["predicted"].values()) == 0
    assert "fitted 8 (in-sample, not evidence)" in verdict.format_counts(rows)
    assert all("t on logs" in r.criterion for r in rows if r.verdict != "undetermined" or "no power" in r.criterion)


def test_a_ratio_scale_number_six_times_off_is_not_reproduced():
    """Issue 41: §4.6.3's std image error, 16.3 ± 6.0 px over 8 repeats (11–30 px) against the seed's 2.6 px,
    passed the linear t-test; judged by factors it is 6.3× off, beyond its stated factor."""
    values = [11.0, 12.0, 12.5, 13.5, 15.0, 17.0, 20.5, 28.5]
    assert np.mean(values) == pytest.approx(16.25) and np.std(values, ddof=1) == pytest.approx(6.0, abs=0.2)
    assert verdict.judge("4.6.3", "std", 2.6, values).verdict == "reproduced"  # the former criterion
    row = verdict.judge("4.6.3", "std", 2.6, values, scale="ratio")
    assert row.verdict == "not reproduced" and "t on logs" in row.criterion
    assert row.statistic == pytest.approx(abs(math.log(2.6) - np.mean(np.log(values))))
    # at this spread the interval spans more than a factor 2 either way of 16: no power to call it reproduced
    assert verdict.judge("x", "q", 16.0, values, scale="ratio").verdict == "undetermined"
    tight = [14.0, 15.0, 15.5, 16.0, 16.5, 17.0, 17.5, 18.0]
    assert verdict.judge("x", "q", 16.0, tight, scale="ratio").verdict == "reproduced"
    assert verdict.judge("x", "q", -1.0, values, scale="ratio").verdict == "undetermined"
    with pytest.raises(SimulationError, match="scale"):
        verdict.judge("x", "q", 1.0, values, scale="log")


@pytest.mark.parametrize("n", [4, 8])
def test_the_ratio_criterion_rejects_a_consistent_value_at_its_stated_rate(n):
    """Lognormal seed and repeats from one distribution: "not reproduced" about ALPHA of the time."""
    rng = np.random.default_rng(10 + n)
    draws = np.exp(rng.normal(1.0, 0.4, (4000, n + 1)))
    rejected = np.mean([verdict.judge("x", "q", d[0], d[1:], scale="ratio").verdict == "not reproduced"
                        for d in draws])
    assert abs(rejected - verdict.ALPHA) < 4 * math.sqrt(verdict.ALPHA * (1 - verdict.ALPHA) / len(draws))


@pytest.mark.parametrize("n, spread", [(8, 0.3), (4, 0.5)])
def test_the_printed_false_acceptance_rate_is_the_measured_one(n, spread):
    """The printed rate against a model off × 2, checked by simulation: the seed drawn ln 2 away from the
    repeats' lognormal distribution, accepted (reproduced or undetermined) at the rate the noncentral t says
    for the true spread."""
    rng = np.random.default_rng(n)
    logs = rng.normal(0.0, spread, (6000, n))
    seeds = np.exp(rng.normal(math.log(verdict.RATIO_ALTERNATIVE), spread, 6000))
    accepted = np.mean([verdict.judge("x", "q", seed, np.exp(d), scale="ratio").verdict != "not reproduced"
                        for seed, d in zip(seeds, logs)])
    predicted = verdict.false_acceptance(math.log(verdict.RATIO_ALTERNATIVE), spread, n)
    assert abs(accepted - predicted) < 4 * math.sqrt(predicted * (1 - predicted) / len(seeds))


def test_the_tolerance_test_states_its_false_acceptance_rate():
    """Oracle: the binomial tail by enumeration: with 8 repeats (≤ 2 allowed) a model with 30 % of its runs
    above 1 % passes with probability 0.55 (issue 41's figure)."""
    p = verdict.TOLERANCE_ALTERNATIVE
    far = sum(math.comb(8, j) * p**j * (1 - p) ** (8 - j) for j in range(3))
    row = verdict.judge_tolerance("3.2", "240", 239.8, 240.0, [239.0, 240.5, 241.0, 237.0, 240, 240, 240, 240])
    assert f"30% of runs above with p {far:.2f}" in row.criterion and f"{far:.2f}" == "0.55"


def test_chapter_3_protocol_compensates_below_one_millimetre():
    """After compensation the true source of each image is within the 1 mm threshold plus the camera's
    position noise of the first image's (the camera, not the truth, decides the stop)."""
    import math as m

    model = ErrorModel(corner_noise_px=0.5).with_operator_scale(0.4)
    room = repositioning.make_room(SYSTEM, model, np.random.default_rng(5))
    rng = np.random.default_rng(6)
    q_first = stitching.reference_configuration(room.system, rng)

    def second(planner, reading):
        direction = planner.default_direction()
        return [planner.K[:2, :2] @ (m.tan(chapter3.ROTATION) * direction[:2]) + planner.K[:2, 2]]

    _, _, images = chapter3.acquire_compensated(room, rng, q_first, second)
    (T1, _), (T2, H2) = images
    assert np.linalg.norm(T2[:3, 3] - T1[:3, 3]) < 0.006  # 1 mm + a few sd of the filtered camera position
    assert m.degrees(np.arccos(np.clip((np.trace(T1[:3, :3].T @ T2[:3, :3]) - 1) / 2, -1, 1))) > 3.0
    with pytest.raises(SimulationError, match="protocol"):
        chapter3.table_3_1(SYSTEM, model, protocol="chapter5")


def test_the_box_end_is_inside_its_box_and_measured_by_single_frames():
    tasks = repositioning.run(SYSTEM, ErrorModel(corner_noise_px=1.0), tasks=3, seed=2, end="box")
    system = square_pixel_system(SYSTEM)
    half = np.where(system.prismatic, repositioning.BOX[0], repositioning.BOX[1])
    for t in tasks:
        assert t.success and np.all(np.abs(t.q_final - t.q_reference) <= half + 1e-15)
        assert t.translation > 0 and t.rotation > 0
    with pytest.raises(SimulationError, match="end"):
        repositioning.run(SYSTEM, ErrorModel(), tasks=1, end="teleport")


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


def test_a_verdict_holds_only_where_it_holds_across_the_fits_region():
    """Issue 41: a row keeps its verdict when every point of the 95 % region agrees, else it is undetermined."""
    tight = [14.0, 15.0, 15.5, 16.0, 16.5, 17.0, 17.5, 18.0]
    best = [verdict.judge("x", "a", 16.0, tight, scale="ratio"), verdict.judge("x", "b", 16.0, tight, scale="ratio")]
    other = [verdict.judge("x", "a", 16.0, [t * 1.05 for t in tight], scale="ratio"),
             verdict.judge("x", "b", 16.0, [t * 4 for t in tight], scale="ratio")]
    assert [r.verdict for r in best] == ["reproduced", "reproduced"]
    assert [r.verdict for r in other] == ["reproduced", "not reproduced"]
    combined = verdict.across([best, other])
    assert [r.verdict for r in combined] == ["reproduced", "undetermined"]
    assert "across the fit's 95 % region: reproduced, not reproduced" in combined[1].criterion
    assert combined[0] == best[0] and combined[1].simulated == best[1].simulated
    with pytest.raises(SimulationError, match="same rows"):
        verdict.across([best, other[:1]])
    with pytest.raises(SimulationError, match="rows_by_point"):
        verdict.across([])


def test_the_region_models_are_the_fits_starred_points():
    models = verdict.region_models(ErrorModel())
    assert [m.corner_noise_px for m in models] == [p[0] for p in fit.FIT_REGION]
    assert fit.FIT_REGION[0] == fit.BEST_FIT
    reference = ErrorModel().with_operator_scale(fit.FIT_REGION[1][1])
    assert models[1].operator_translation == reference.operator_translation
    rows = verdict.verdict_over_region(SYSTEM, models[:2], repeats=2, experiments="3.2")
    assert len(rows) == 12 and all(r.verdict in verdict.VERDICTS for r in rows)
    with pytest.raises(SimulationError, match="models"):
        verdict.verdict_over_region(SYSTEM, [], repeats=2)


def test_repeats_over_forked_workers_give_the_values_of_one_after_the_other(monkeypatch):
    """The repeats run over one forked process per CPU: in seed order, a failed repeat None, and the rows of a
    real experiment equal to those computed one repeat after the other (the test can fail: a worker sharing
    state or a shuffled order)."""
    import os

    def one(seed):
        if seed == 2:
            raise SimulationError("the camera lost the pattern")
        return float(np.random.default_rng(seed).normal())

    monkeypatch.setattr(os, "cpu_count", lambda: 3)
    forked = verdict._repeats(one, 5)
    assert forked[2] is None
    assert forked[:2] + forked[3:] == [float(np.random.default_rng(s).normal()) for s in (0, 1, 3, 4)]
    system = carmkin.load_preset("siremobile-iso-c3d")
    parallel = verdict.EXPERIMENTS["3.2"](system, ErrorModel(), 3)
    monkeypatch.setattr(os, "cpu_count", lambda: 1)
    serial = verdict.EXPERIMENTS["3.2"](system, ErrorModel(), 3)
    assert [dataclasses.astuple(r) for r in parallel] == [dataclasses.astuple(r) for r in serial]
