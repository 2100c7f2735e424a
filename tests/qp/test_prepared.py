"""The prepared IK (qp_ik.prepare): the same answers as qp_ik.solve, a validity at the solve's margin that
agrees with validity.check computing every pair, clearance of many configurations, and the inputs it refuses."""

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import PRESET, configurations

import carmkin
from carmkin import analytic_ik, qp_ik
from carmkin.errors import CarmkinError, InvalidConfigurationError, InvalidPoseError, QPIKError
from carmkin.robot import validity
from carmkin.world.tolerances import BOUND_SLACK
from carmkin.world import Obstacle, World
from carmkin.transforms import nearest_rigid, pose_error

MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
PATIENT = [Obstacle.box("torso", (0.35, 0.2, 0.7), (0.0, 0.32, 0.1)),
           Obstacle.capsule("leg", 0.07, 0.8, (0.1, 0.29, 0.8))]
SOLVERS = {name: qp_ik.prepare(system, PATIENT) for name, system in (("preset", PRESET), ("motorized", MOTORIZED))}
SYSTEMS = {"preset": PRESET, "motorized": MOTORIZED}


def same_report(a, b):
    """Two validity reports say the same (distances to coal's tolerance)."""
    assert a.margin == b.margin
    assert [(j.name, j.excess) for j in a.joints] == [(j.name, j.excess) for j in b.joints]
    assert [(c.first, c.second) for c in a.collisions] == [(c.first, c.second) for c in b.collisions]
    for c, d in zip(a.collisions, b.collisions):
        assert abs(c.distance - d.distance) <= BOUND_SLACK
    assert a.table_in_cone == b.table_in_cone and a.valid == b.valid and a.reachable == b.reachable
    assert abs(a.min_distance - b.min_distance) <= BOUND_SLACK


@settings(max_examples=25)
@given(st.sampled_from(sorted(SOLVERS)), st.data())
def test_check_agrees_with_validity_check_of_every_pair(name, data):
    system, solver = SYSTEMS[name], SOLVERS[name]
    q = data.draw(configurations(system, beyond=0.1))
    full = validity.check(system, q, PATIENT, margin=solver.options.safety_margin)  # every pair, fresh scene
    same_report(solver.check(q), full)
    np.testing.assert_allclose(solver.clearance(q[None]), [full.min_distance], rtol=0, atol=BOUND_SLACK)


@settings(max_examples=15)
@given(st.sampled_from(sorted(SOLVERS)), st.data())
def test_prepared_solve_is_qp_ik_solve(name, data):
    """Same q, success, path and seed as the wrapper (which prepares per call with obstacles); the answer
    reaches the target (closed-form FK) and its validity is at the solve's margin."""
    system, solver = SYSTEMS[name], SOLVERS[name]
    q = data.draw(configurations(system))
    T = system.fk(q)
    mine = solver.solve(T)
    theirs = qp_ik.solve(system, T, obstacles=PATIENT)
    if mine.path != qp_ik.Path.QP and theirs.path != qp_ik.Path.QP:
        assert mine.success == theirs.success and mine.path == theirs.path and mine.seed == theirs.seed
        np.testing.assert_array_equal(mine.q, theirs.q)
    # A QP run may part ways: coal's distances depend on its previous queries by up to its GJK tolerance
    # (1e-6 m), and a reused scene has had other queries than a fresh one. Both answers must be right.
    for result in (mine, theirs):
        if result.success:
            position, angle = pose_error(system.fk(result.q), T)
            assert position <= 1e-6 and angle <= 1e-6
            assert validity.check(system, result.q, PATIENT, margin=solver.margin - 1e-6).reachable
    if mine.validity is not None:
        assert mine.validity.margin == solver.options.safety_margin
        assert f"margin {solver.options.safety_margin * 1e3:g} mm" in str(mine.validity)
        same_report(mine.validity, validity.check(system, mine.q, PATIENT, margin=solver.options.safety_margin))
    for branch in mine.branch_reports:
        assert branch.validity is None or branch.validity.margin == solver.options.safety_margin


REUSED = qp_ik.prepare(PRESET)  # one solver for every example: its coal data carries earlier queries


@settings(max_examples=40)
@given(configurations(beyond=0.05), configurations(), st.booleans())
def test_a_reused_prepared_solve_is_the_unprepared_one(q, q_current, give_current):
    """Without obstacles, on random targets (some out of range): a solver reused over many targets gives the
    closed form's branches (analytic_ik.solve, the unchecked route), and the answer, path, seed and reports
    of a solve prepared for this call alone; its validity is validity.check's of every pair."""
    T = PRESET.fk(q)
    current = q_current if give_current else None
    mine = REUSED.solve(T, q_current=current)
    theirs = qp_ik.solve(PRESET, T, q_current=current, world=World(PRESET))  # prepared for this call
    closed = analytic_ik.solve(PRESET, T, q_current=current)
    np.testing.assert_array_equal(mine.closed_form.solutions, closed.solutions)
    assert mine.closed_form.chosen == closed.chosen and mine.closed_form.pose_correction == closed.pose_correction
    assert len(mine.branch_reports) == len(theirs.branch_reports)
    if qp_ik.Path.QP not in (mine.path, theirs.path):  # a QP run may part ways by coal's warm starts (see above)
        assert (mine.success, mine.path, mine.seed, mine.failure) == (theirs.success, theirs.path, theirs.seed,
                                                                       theirs.failure)
        np.testing.assert_array_equal(mine.q, theirs.q)
        for a, b in zip(mine.branch_reports, theirs.branch_reports):
            assert (a.name, a.reached, a.accepted) == (b.name, b.reached, b.accepted)
            np.testing.assert_array_equal(a.q, b.q)
            if a.validity is not None:
                same_report(a.validity, b.validity)
                same_report(a.validity, validity.check(PRESET, a.q, margin=REUSED.margin))
    if mine.validity is not None:
        same_report(mine.validity, validity.check(PRESET, mine.q, margin=REUSED.margin))


def test_one_meaning_of_valid_when_a_branch_is_inside_the_margin():
    """A pose whose closed-form branch is clear but within 10 mm of the table: every report of the result is
    at 10 mm, so a branch refused for the margin never prints 'valid'."""
    solver = qp_ik.prepare(PRESET)
    rng = np.random.default_rng(4)
    found = 0
    for q in rng.uniform(PRESET.lower, PRESET.upper, (4000, 6)):
        d = solver.clearance(q[None])[0]
        if not 0.0 < d < solver.margin:
            continue
        result = solver.solve(PRESET.fk(q), q_current=q)
        for branch in result.branch_reports:
            if branch.validity is not None and not branch.accepted and branch.reached:
                assert not branch.validity.reachable and "margin 10 mm" in str(branch.validity)
                assert not str(branch.validity).startswith("valid")
                found += 1
        if found >= 3:
            break
    assert found >= 3


def test_clearance_with_exact_below_is_a_cheap_margin_test():
    solver = SOLVERS["preset"]
    qs = np.random.default_rng(1).uniform(PRESET.lower, PRESET.upper, (300, 6))
    exact = solver.clearance(qs)
    cheap = solver.clearance(qs, exact_below=solver.margin)
    near = exact < solver.margin
    np.testing.assert_allclose(cheap[near], exact[near], rtol=0, atol=BOUND_SLACK)
    assert np.all(cheap[~near] >= solver.margin) and np.all(cheap[~near] <= exact[~near] + BOUND_SLACK)
    reachable = solver.reachable(qs)
    expected = [validity.check(PRESET, q, PATIENT, margin=solver.margin).reachable for q in qs]
    assert reachable.tolist() == expected


@settings(max_examples=20)
@given(configurations(), st.sampled_from(["round4", "float32"]))
def test_a_nearly_rigid_target_is_projected_and_reported(q, kind):
    """The correction is the closed form's (tested there against nearest_rigid); the answer reaches the
    projected pose."""
    T = PRESET.fk(q)
    rough = np.round(T, 4) if kind == "round4" else T.astype(np.float32)
    result = qp_ik.solve(PRESET, rough)
    assert result.pose_correction == analytic_ik.solve(PRESET, rough).pose_correction
    rigid = nearest_rigid(np.asarray(rough, dtype=float))[0] if result.pose_correction else np.asarray(rough, float)
    if result.success:
        assert max(pose_error(PRESET.fk(result.q), rigid)) <= 1e-6


def test_a_target_far_from_rigid_names_nearest_rigid():
    T = PRESET.fk(np.full(6, 0.1))
    T[:3, :3] *= 1.01
    with pytest.raises(InvalidPoseError, match="carmkin.transforms.nearest_rigid"):
        qp_ik.solve(PRESET, T)


@pytest.mark.parametrize("q_current", [
    np.ones(6, dtype=bool), [True, False, True, False, True, False], PRESET.upper + 0.01, "0 0 0 0 0 0",
    {"a": 1}, b"123456", np.zeros(6) + 1j, np.zeros(5), np.full(6, np.nan),
])
def test_q_current_is_refused_naming_it(q_current):
    with pytest.raises(InvalidConfigurationError, match="q_current"):
        qp_ik.solve(PRESET, PRESET.fk(np.zeros(6)), q_current=q_current)


@pytest.mark.parametrize("target", [None, {"T": 1}, "pose", b"pose", 1j, True, np.eye(3)])
def test_junk_targets_are_typed_errors(target):
    with pytest.raises(CarmkinError, match="target"):
        qp_ik.solve(PRESET, target)


@pytest.mark.parametrize("kwargs", [
    dict(options="fast"), dict(options=None), dict(obstacles="patient"), dict(obstacles=None),
    dict(obstacles=[1]), dict(random_seeds=True), dict(random_seeds=-1), dict(rng_seed="0"),
    dict(closed_form="yes"), dict(prefer="both"), dict(free="wigwag"), dict(weights="heavy"),
    dict(weights=[True] * 6), dict(accept=True), dict(world="scene"),
])
def test_junk_options_are_typed_errors(kwargs):
    with pytest.raises(CarmkinError):
        qp_ik.solve(PRESET, PRESET.fk(np.zeros(6)), **kwargs)


JUNK = [None, {"a": 1}, "x", b"x", 1j, True, [1, "a"], np.array([1j] * 3), [[1, 2], [3]]]


@pytest.mark.parametrize("junk", JUNK)
def test_junk_everywhere_is_a_typed_error_naming_the_argument(junk):
    """Each public argument of qp_ik/prepared given junk: a CarmkinError, never a numpy or Python one."""
    T = PRESET.fk(np.zeros(6))
    solver = SOLVERS["preset"]
    calls = [
        (lambda: qp_ik.AxisTarget(junk, (0, 0, 1)), "position"), (lambda: qp_ik.AxisTarget((0, 0, 0), junk), "direction"),
        (lambda: qp_ik.AimTarget(junk, (0.5, 0.7)), "point"), (lambda: qp_ik.AimTarget((0, 0, 0), junk), "distance_range"),
        (lambda: solver.clearance(np.zeros((1, 6)), junk), "exact_below"), (lambda: solver.check(junk), "q"),
        (lambda: solver.clearance(junk), "qs"), (lambda: solver.reachable(junk), "qs"),
        (lambda: Obstacle.box("b", junk), "size"), (lambda: Obstacle.box("b", (1, 1, 1), junk), "center"),
    ]
    if junk is not None:
        calls += [(lambda: qp_ik.solve(PRESET, T, backend=junk), "backend"),
                  (lambda: qp_ik.solve(PRESET, T, free=junk), "free")]
    if junk is not None and not isinstance(junk, list):
        calls.append((lambda: qp_ik.solve(PRESET, T, seeds=junk), "seeds"))
    for call, name in calls:
        with pytest.raises(CarmkinError, match=name):
            call()


def test_junk_option_fields_are_typed_errors():
    for field in ("position_tolerance", "max_iterations", "safety_margin"):
        for value in (None, "1", True, 1j):
            with pytest.raises(QPIKError, match=field):
                qp_ik.QPIKOptions(**{field: value})


def test_prepared_solvers_are_reused_by_the_wrapper_and_freed_with_the_system():
    system = PRESET.replace(setup=PRESET.setup)
    T = system.fk(np.zeros(6))
    qp_ik.solve(system, T)
    cache = qp_ik._prepared.cache
    assert id(system) in cache and len(cache[id(system)][1]) == 1
    qp_ik.solve(system, T)
    assert len(cache[id(system)][1]) == 1
    key = id(system)
    del system
    import gc

    gc.collect()
    assert key not in cache or cache[key][0]() is None


def test_a_prebuilt_scene_and_obstacles_together_are_refused():
    with pytest.raises(QPIKError, match="either"):
        qp_ik.prepare(PRESET, PATIENT, world=World(PRESET))


def test_a_world_of_another_system_is_refused():
    """The prepared solver's system is its world's: a world built for another system is a typed error."""
    from carmkin.world import World

    other = PRESET.replace(carm=dataclasses.replace(PRESET.carm, a1=0.02))
    with pytest.raises(QPIKError, match="another system"):
        qp_ik.prepare(PRESET, world=World(other))
    assert qp_ik.prepare(PRESET, world=World(PRESET)).system is PRESET


def test_results_built_without_init_hold_every_field():
    """PreparedIK.solve builds SolveResult and BranchReport without their __init__ (frozen_instance): every
    field is there, and the objects equal those their __init__ builds from the same values."""
    qs = np.random.default_rng(2).uniform(PRESET.lower, PRESET.upper, (200, 6))
    result = REUSED.solve(PRESET.fk(qs[REUSED.reachable(qs)][0]))
    assert result.success and result.path == qp_ik.Path.CLOSED_FORM and result.branch_reports
    for obj in (result, *result.branch_reports):
        fields = dataclasses.fields(obj)
        assert set(obj.__dict__) == {f.name for f in fields}
        assert type(obj)(**{f.name: getattr(obj, f.name) for f in fields}) == obj
        assert dataclasses.replace(obj) == obj
