"""Closed-form IK (carmkin.analytic_ik): round trips, agreement with Pinocchio, singular cases, selection
rules of §4.4.2, angle representatives, typed errors, and the printed equations of Table 4.2."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from strategies import PRESET, configurations, configurations_on_limits, poses, systems

import carmkin
from carmkin import analytic_ik, transforms
from carmkin.model import sampling
from carmkin.model.params import JOINT_NAMES, JOINT_RANGE_TOLERANCE
from carmkin.analytic_ik import SINGULAR_CASES
from carmkin.transforms import NEARLY_RIGID_TOLERANCE, nearest_rigid, pose_error

REVOLUTE = [2, 4, 5]
PRISMATIC = [0, 1, 3]


def det_j(system, q) -> float:
    """Eq. 4.7, evaluated from the joint values (independent of the IK code)."""
    return math.sin(q[2] + system.setup.gamma3) * math.sin(system.setup.gamma1) * math.cos(q[4])


def pose_errors(T, T_target) -> tuple[float, float]:
    """(position error m, rotation error rad) through the rotation-vector norm."""
    rotation = pin.log3(T[:3, :3].T @ T_target[:3, :3])
    return float(np.linalg.norm(T[:3, 3] - T_target[:3, 3])), float(np.linalg.norm(rotation))


def wrapped(d):
    """Differences of configurations with the revolute joints taken modulo 2π."""
    d = np.array(d, dtype=float)
    d[..., REVOLUTE] = (d[..., REVOLUTE] + np.pi) % (2 * np.pi) - np.pi
    return d


def pinocchio_pose(system, q):
    model = system.pinocchio()[0]
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
    return data.oMf[model.getFrameId("xray_source")].homogeneous


# --- round trips ------------------------------------------------------------------------------------------
@given(st.data())
def test_round_trip_both_branches_and_the_generating_configuration(data):
    system = data.draw(systems())
    q = data.draw(configurations(system, beyond=0.5))
    q[REVOLUTE] = data.draw(st.lists(st.floats(-np.pi, np.pi), min_size=3, max_size=3))
    assume(abs(det_j(system, q)) > 1e-3)
    T = system.fk(q)
    result = analytic_ik.solve(system, T)
    assert result.solutions.shape == (2, 6) and not result.numerical
    for k in range(2):
        dp, dr = pose_errors(system.fk(result.solutions[k], check_units=False), T)
        assert dp <= 1e-9 and dr <= 1e-9
    assert min(np.abs(wrapped(result.solutions - q)).max(axis=1)) <= 1e-8
    assert np.cos(result.solutions[0, 4]) > 0 > np.cos(result.solutions[1, 4])


@settings(max_examples=40)
@given(st.data())
def test_every_branch_agrees_with_pinocchio(data):
    system = data.draw(systems())
    q = data.draw(configurations(system, beyond=0.25))
    assume(abs(det_j(system, q)) > 1e-3)
    T = pinocchio_pose(system, q)
    result = analytic_ik.solve(system, T)
    for k in range(2):
        dp, dr = pose_errors(pinocchio_pose(system, result.solutions[k]), T)
        assert dp <= 1e-9 and dr <= 1e-9


def test_batch_round_trip_100k_poses_over_many_systems():
    """100 000 poses: random non-isocentric systems with random table setups x 1000 configurations each."""
    rng = np.random.default_rng(20240601)
    worst, matched, total, poses_done = 0.0, 0, 0, 0
    while poses_done < 100_000:
        system = sampling.random_system(rng, PRESET)
        if abs(math.sin(system.setup.gamma1)) < 0.05:  # near case (a): no physical setup
            continue
        Q = sampling.random_configurations(rng, system, 1000)
        T = system.fk(Q)
        batch = analytic_ik.solve_batch(system, T)
        poses_done += len(T)
        regular = ~batch.numerical
        for k in range(2):
            fk = system.fk(batch.solutions[k, regular], check_units=False)
            worst = max(worst, np.abs(fk - T[regular]).max())
        d = np.abs(wrapped(batch.solutions - Q[None])).max(axis=2).min(axis=0)
        away = np.abs(np.sin(Q[:, 2] + system.setup.gamma3) * math.sin(system.setup.gamma1) * np.cos(Q[:, 4])) > 1e-3
        matched += int(np.sum(d[away] <= 1e-8))
        total += int(away.sum())
    assert worst <= 1e-9
    assert total > 99_000 and matched == total


@settings(max_examples=40)
@given(st.data())
def test_batch_equals_the_scalar_path(data):
    system = data.draw(systems())
    Q = np.array(data.draw(st.lists(configurations(system, beyond=0.3), min_size=1, max_size=12)))
    T = system.fk(Q)
    q_current = data.draw(st.sampled_from(["none", "one", "per pose"]))
    if q_current == "none":
        q_current = None
    elif q_current == "one":
        q_current = data.draw(configurations(system))
    else:
        q_current = np.array([data.draw(configurations(system)) for _ in Q])
    batch = analytic_ik.solve_batch(system, T, q_current)
    for i in range(len(Q)):
        ref = q_current[i] if q_current is not None and q_current.ndim == 2 else q_current
        one = analytic_ik.solve(system, T[i], ref)
        scale = 1.0 + np.abs(one.solutions).max()
        tolerance = 1e-10 * scale / max(abs(one.det_j), 1e-3)  # round-off grows as 1/|det J|
        assert np.allclose(one.solutions, batch.solutions[:, i], rtol=0, atol=tolerance)
        assert one.chosen == batch.chosen[i]
        assert [b.within_limits for b in one.branches] == list(batch.within_limits[:, i])
        assert one.numerical == batch.numerical[i]


# --- a value on a limit is in range (issue 13) ----------------------------------------------------------------
def test_the_home_configuration_on_two_limits_is_within_range():
    """FK of q = (0, 0, 0, 0, 30°, 10°), then IK: reported in range (it was out by −2.8e-17 m)."""
    q = np.array([0.0, 0.0, 0.0, 0.0, math.radians(30), math.radians(10)])
    result = analytic_ik.solve(PRESET, PRESET.fk(q))
    assert result.valid and result.branches[result.chosen].excess == {}
    assert np.abs(wrapped(result.q - q)).max() <= 1e-12


def _limit_grid(system) -> np.ndarray:
    """Every combination of (lower, 1/3, 2/3, upper) of each joint's range, keeping those with a joint on a
    limit: 4^6 − 2^6 = 4032 configurations."""
    values = [(r.lower, r.lower + (r.upper - r.lower) / 3, r.upper - (r.upper - r.lower) / 3, r.upper)
              for r in system.joint_ranges]
    grid = np.array(np.meshgrid(*values, indexing="ij")).reshape(6, -1).T
    on_limit = (grid == system.lower) | (grid == system.upper)
    return grid[on_limit.any(axis=1)]


def test_round_trip_of_configurations_on_their_limits_is_reported_within_range():
    """Issue 13 acceptance: ≥ 10 000 FK → IK round trips with joints exactly on their limits, all in range."""
    geometries = [PRESET.carm, dataclasses.replace(PRESET.carm, a1=0.05, a2=-0.03),
                  dataclasses.replace(PRESET.carm, a1=-0.12, a2=0.2, length_offset=0.9)]
    total = 0
    for carm in geometries:
        system = PRESET.replace(carm=carm)
        Q = _limit_grid(system)
        batch = analytic_ik.solve_batch(system, system.fk(Q))
        total += len(Q)
        assert batch.valid.all(), Q[~batch.valid][:3]
        assert np.abs(batch.excess[batch.chosen, np.arange(len(Q))]).max() == 0.0
        assert batch.residual[batch.chosen, np.arange(len(Q))].max() <= 1e-9
    assert total >= 10_000


@given(st.data())
def test_scalar_round_trip_with_joints_on_their_limits_is_within_range(data):
    system = data.draw(systems())
    q = data.draw(configurations_on_limits(system))
    assume(abs(det_j(system, q)) > 1e-3)
    result = analytic_ik.solve(system, system.fk(q))
    assert result.valid, result.branches[result.chosen].excess
    assert result.branches[result.chosen].excess == {}


# --- singular poses -----------------------------------------------------------------------------------------
def singular_system(system):
    """``system`` with γ1 = 0: table translation parallel to the vertical axis (case a)."""
    s = system.setup
    return system.replace(setup=carmkin.TableSetup(0.0, s.gamma2, s.gamma3, s.D1, s.D2, s.D3))


@settings(max_examples=25)
@given(st.data(), st.sampled_from(["a", "b", "c", "b+c"]), st.sampled_from([0.0, 1e-9, 1e-7]))
def test_singular_poses_are_solved_numerically_or_raise(data, case, offset):
    system = data.draw(systems())
    q = data.draw(configurations(system))
    if case == "a":
        system = singular_system(system)
    if "b" in case:
        q[4] = data.draw(st.sampled_from([np.pi / 2, -np.pi / 2])) + offset
    if "c" in case:
        q[2] = -system.setup.gamma3 + offset
    T = system.fk(q)
    expected = {"a": 0, "b": 1, "c": 2}
    try:
        result = analytic_ik.solve(system, T)
    except analytic_ik.SingularPoseError as exc:
        assert all(analytic_ik.SINGULAR_CASES[expected[c]] in exc.cases for c in case.split("+"))
        return
    assert abs(result.det_j) < analytic_ik.SINGULAR_TOLERANCE
    # the singular family (case b) has its closed form; near a and c the regular closed form is kept when the FK
    # accepts it; the others are solved numerically (every answer is checked below)
    # in case b, θ2 is free (only θ2 ± θ5 is fixed): whether (c) holds too depends on the θ2 picked
    for c in case.split("+")[:1]:
        assert analytic_ik.SINGULAR_CASES[expected[c]] in result.singular
    reached = [k for k in range(2) if result.branches[k].reached]
    assert reached and result.chosen in reached
    for k in reached:
        assert result.branches[k].numerical == result.numerical and result.branches[k].residual <= 1e-9
        # near case c the exact solution can sit metres to kilometres away: round-off scales with it
        scale = max(1.0, np.abs(result.solutions[k]).max())
        dp, dr = pose_errors(system.fk(result.solutions[k], check_units=False), T)
        assert dp <= 2e-9 * scale and dr <= 2e-9


@settings(max_examples=40)
@given(st.data())
def test_det_j_of_eq_4_7_equals_the_determinant_of_pinocchios_jacobian(data):
    system = data.draw(systems())
    model = system.pinocchio()[0]
    q = data.draw(configurations(system, beyond=0.3))
    J = pin.computeFrameJacobian(model, model.createData(), q, model.getFrameId("xray_source"), pin.LOCAL)
    assert np.linalg.det(J) == pytest.approx(det_j(system, q), abs=1e-12)
    assert analytic_ik.solve(system, system.fk(q)).det_j == pytest.approx(det_j(system, q), abs=1e-9)


def test_batch_flags_singular_poses_and_solves_them():
    """The first pose is on the singular family (θ4 = π/2): closed form, θ2 from q_current (zero), θ2 + θ5 kept."""
    system = PRESET
    q = np.array([[0.1, 0.2, 0.05, 0.1, np.pi / 2, 0.3], [0.1, 0.2, 0.05, 0.1, 0.2, 0.3]])
    batch = analytic_ik.solve_batch(system, system.fk(q))
    assert list(batch.numerical) == [False, False]  # the singular family has its closed form
    assert list(batch.singular[0]) == [False, True, False] and not batch.singular[1].any()
    assert batch.residual[batch.chosen, [0, 1]].max() <= 1e-9
    assert batch.q[0, 2] == 0.0 and batch.q[0, 5] == pytest.approx(0.35, abs=1e-12)


# --- selection and representatives ---------------------------------------------------------------------------
def in_range(system, q) -> bool:
    """Within the ranges, a value on a limit (up to the stated tolerance, issue 13) included."""
    tol = JOINT_RANGE_TOLERANCE
    return bool(np.all(q >= system.lower - tol) and np.all(q <= system.upper + tol))


@given(st.data())
def test_selection_follows_the_ordered_rules_of_4_4_2(data):
    system = data.draw(systems())
    q = data.draw(configurations(system, beyond=0.3))
    assume(abs(det_j(system, q)) > 1e-3)
    q_current = data.draw(st.none() | configurations(system))
    result = analytic_ik.solve(system, system.fk(q), q_current)
    ref = np.zeros(6) if q_current is None else q_current
    inside = [in_range(system, s) for s in result.solutions]
    assert [b.within_limits for b in result.branches] == inside
    assert result.valid == inside[result.chosen]
    if inside[0] != inside[1]:
        assert inside[result.chosen]
        return
    rot = [np.abs(s[REVOLUTE] - ref[REVOLUTE]).sum() for s in result.solutions]
    trans = [np.abs(s[PRISMATIC] - ref[PRISMATIC]).sum() for s in result.solutions]
    other = 1 - result.chosen
    assert rot[result.chosen] <= rot[other] + 1e-12
    if abs(rot[0] - rot[1]) <= 1e-12:
        assert trans[result.chosen] <= trans[other] + 1e-12


@given(st.data())
def test_excess_names_the_out_of_range_joints_and_nothing_is_clipped(data):
    system = data.draw(systems())
    q = data.draw(configurations(system, beyond=0.5))
    assume(abs(det_j(system, q)) > 1e-3)
    T = system.fk(q)
    result = analytic_ik.solve(system, T)
    for solution, status in zip(result.solutions, result.branches):
        expected = {}
        for name, value, lo, hi in zip(JOINT_NAMES, solution, system.lower, system.upper):
            if value < lo - JOINT_RANGE_TOLERANCE:  # on a limit is in range (issue 13)
                expected[name] = value - lo
            elif value > hi + JOINT_RANGE_TOLERANCE:
                expected[name] = value - hi
        assert status.excess.keys() == expected.keys()
        for name in expected:
            assert status.excess[name] == pytest.approx(expected[name], abs=1e-15)
        assert status.within_limits == (not expected)
        assert np.abs(system.fk(solution, check_units=False) - T).max() <= 1e-9  # the reported values reach the pose


def test_angular_joint_takes_the_representative_inside_its_190_degree_range():
    q = np.array([0.05, 0.2, 0.05, 0.1, math.radians(185.0), 0.3])
    result = analytic_ik.solve(PRESET, PRESET.fk(q))
    # principal value −175° is also in range: (−π, π] wins without q_current
    assert result.solutions[1, 4] == pytest.approx(math.radians(-175.0))
    q_current = q.copy()
    result = analytic_ik.solve(PRESET, PRESET.fk(q), q_current)
    assert result.solutions[1, 4] == pytest.approx(math.radians(185.0)) and result.chosen == 1
    assert np.allclose(result.q, q)
    # a range beyond ±π on one side only: the principal value is out of range, the other one is taken
    angular = carmkin.JointRange(math.radians(100.0), math.radians(250.0), "angular")
    system = PRESET.replace(carm=dataclasses.replace(PRESET.carm, angular=angular))
    q[4] = math.radians(200.0)
    result = analytic_ik.solve(system, system.fk(q))
    assert result.solutions[1, 4] == pytest.approx(math.radians(200.0)) and result.branches[1].within_limits


def test_result_contract():
    q = np.array([0.1, 0.2, 0.05, 0.1, 0.3, 0.4])
    result = analytic_ik.solve(PRESET, PRESET.fk(q))
    assert isinstance(result.solutions, np.ndarray) and result.solutions.shape == (2, 6)
    assert isinstance(result.chosen, int) and np.array_equal(result.q, result.solutions[result.chosen])
    assert len(result.branches) == 2 and result.valid is True
    for b in result.branches:
        assert isinstance(b.within_limits, bool) and isinstance(b.excess, dict)
        assert isinstance(b.singular, tuple) and b.numerical is False and isinstance(b.residual, float)
        assert b.residual <= 1e-9
    assert np.allclose(result.q, q)
    assert result.branches[0].status == "ok" and "out of range" in result.branches[1].status


def is_rigid(T) -> bool:
    try:
        transforms.check_rigid_transform(np.asarray(T, dtype=float))
        return True
    except carmkin.InvalidPoseError:
        return False


# --- nearly rigid poses (rounded by a user, stored as float32): projected, the correction reported -----------
@settings(max_examples=50)
@given(configurations(), st.sampled_from(["round4", "float32"]))
def test_a_nearly_rigid_pose_is_projected_and_the_correction_reported(q, kind):
    T = PRESET.fk(q)
    rough = np.round(T, 4) if kind == "round4" else T.astype(np.float32)
    rigid, correction = nearest_rigid(np.asarray(rough, dtype=float))  # the independent route
    if is_rigid(rough):  # rigid to RIGID_TOLERANCE already: taken as it is
        rigid, correction = np.asarray(rough, dtype=float), 0.0
    for result in (analytic_ik.solve(PRESET, rough), analytic_ik.solve_batch(PRESET, np.asarray(rough)[None])):
        assert np.all(np.abs(np.atleast_1d(result.pose_correction) - correction) <= 1e-15)
        solutions = np.asarray(result.solutions).reshape(2, 6)
        for q_b in solutions:
            if np.all(np.isfinite(q_b)):
                position, angle = pose_error(PRESET.fk(q_b), rigid)
                assert position <= 1e-9 and angle <= 1e-9


def test_a_rigid_pose_has_no_correction():
    T = PRESET.fk(np.zeros(6) + 0.1)
    assert analytic_ik.solve(PRESET, T).pose_correction == 0.0
    assert np.all(analytic_ik.solve_batch(PRESET, T[None]).pose_correction == 0.0)


def test_a_pose_beyond_the_nearly_rigid_tolerance_names_nearest_rigid():
    T = PRESET.fk(np.zeros(6) + 0.1)
    T[0, 0] += 10 * NEARLY_RIGID_TOLERANCE
    with pytest.raises(carmkin.InvalidPoseError, match="carmkin.transforms.nearest_rigid"):
        analytic_ik.solve(PRESET, T)
    with pytest.raises(carmkin.InvalidPoseError, match="carmkin.transforms.nearest_rigid"):
        analytic_ik.solve_batch(PRESET, np.stack((np.eye(4), T)))


# --- typed errors --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("bad", [
    np.eye(3),
    np.diag([1.0, 1.0, -1.0, 1.0]),
    np.full((4, 4), np.nan),
    np.eye(4) + 1e-2 * np.eye(4)[::-1],  # farther from rigid than NEARLY_RIGID_TOLERANCE
    [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 2]],
    "pose",
])
def test_non_rigid_input_is_a_typed_error(bad):
    T = np.array(bad) if not isinstance(bad, str) else bad
    with pytest.raises(carmkin.InvalidPoseError):
        analytic_ik.solve(PRESET, T)
    if isinstance(T, np.ndarray) and T.shape == (4, 4):
        good = np.repeat(np.eye(4)[None], 3, axis=0)
        good[1] = T
        with pytest.raises(carmkin.InvalidPoseError):
            analytic_ik.solve_batch(PRESET, good)


def test_bad_q_current_and_unsupported_systems_are_typed_errors():
    T = PRESET.fk(np.zeros(6))
    for bad in (np.zeros(5), [0, 0, 0, 0, 0, np.nan], "x"):
        with pytest.raises(carmkin.InvalidConfigurationError):
            analytic_ik.solve(PRESET, T, bad)
    with pytest.raises(carmkin.InvalidConfigurationError):
        analytic_ik.solve_batch(PRESET, T[None], np.zeros((2, 6)))
    motorized = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
    with pytest.raises(analytic_ik.UnsupportedSystemError):
        analytic_ik.solve(motorized, T)


@given(poses())
def test_any_rigid_pose_gets_two_exact_solutions_on_the_preset(T):
    """Every pose is reachable by the 6-DOF chain (away from singularities): nothing is "unreachable"."""
    try:
        result = analytic_ik.solve(PRESET, T)
    except analytic_ik.SingularPoseError:
        return
    for k in range(2):
        if result.branches[k].reached:
            dp, dr = pose_errors(PRESET.fk(result.solutions[k], check_units=False), T)
            assert dp <= 1e-9 * max(1.0, np.abs(result.solutions[k]).max()) and dr <= 1e-9


# --- printed equations of Table 4.2 (see docs/errata/analytic_ik.md) -------------------------------------------
def printed_table_4_2(system, q, corrected: bool = False) -> dict:
    """Each printed equation of Table 4.2 as (left-hand side evaluated from 0T6 and the other joints, true
    value). ``corrected`` adds the a1·cθ4 term eq. 4.16 misses."""
    T6 = system.fk(q) @ transforms.inverse(system.xray_in_flange)  # eq. 4.8
    (r11, r12, r13, px), (r21, r22, r23, py), (r31, r32, r33, pz) = T6[:3]
    g = system.setup
    c1, s1, cg2, sg2, c3, s3 = (f(a) for a in (g.gamma1, g.gamma2, g.gamma3) for f in (math.cos, math.sin))
    d0, d1, t2, d3, t4, t5 = q
    c2, s2, c4, s4, c5, s5 = math.cos(t2), math.sin(t2), math.cos(t4), math.sin(t4), math.cos(t5), math.sin(t5)
    L, M, a1 = system.carm.orbital_offset + system.carm.a1, system.carm.length_offset - system.carm.a2, system.carm.a1
    out = {
        "4.9": (((c1 * sg2 * c3 + cg2 * s3) * r13 + (sg2 * s3 - c1 * cg2 * c3) * r23 - s1 * c3 * r33) / c4, s2),
        "4.10": (((c1 * sg2 * s3 - cg2 * c3) * r13 - (sg2 * c3 + c1 * cg2 * s3) * r23 - s1 * s3 * r33) / c4, c2),
        "4.11": ((r13 * sg2 - r23 * cg2 - (c1 * s3 * c2 * c4 + c1 * c3 * s2 * c4)) / s1, s4),
        "4.12": ((r11 * s1 * sg2 - r21 * s1 * cg2 + c1 * r31) / c4, c5),
        "4.13": ((-r12 * s1 * sg2 + r22 * s1 * cg2 - c1 * r32) / c4, s5),
    }
    eq0 = (-cg2 * px - sg2 * py + g.D1 + c3 * (L * s2 * s5 - M * s2 - L * c2 * s4 * c5 + a1 * c2 * s4)
           + s3 * (L * s2 * s4 * c5 + L * c2 * s5 - M * c2 - a1 * s2 * s4))
    out["4.14"] = (eq0 / (c3 * s2 + s3 * c2), d3)
    eq1 = (sg2 * px - cg2 * py + c1 * s3 * (L * s2 * s5 - M * s2 - s2 * d3 - L * c2 * s4 * c5 + a1 * c2 * s4)
           - c1 * c3 * (L * s2 * s4 * c5 + L * c2 * s5 - M * c2 - c2 * d3 - a1 * s2 * s4))
    out["4.15"] = (eq1 / s1 + L * c4 * c5 - g.D3 - a1 * c4, d1)
    missing = a1 * c4 if corrected else 0.0
    eq2 = (g.D2 + c1 * (d1 + g.D3 + missing - L * c4 * c5)
           + s1 * s3 * (L * s2 * s5 - M * s2 - s2 * d3 - L * c2 * s4 * c5 + a1 * c2 * s4)
           + s1 * c3 * (-L * s2 * s4 * c5 - L * c2 * s5 + M * c2 + c2 * d3 + a1 * s2 * s4))
    out["4.16"] = (pz - eq2, d0)
    return out


@given(st.data())
def test_printed_equations_4_9_to_4_15_hold_for_general_parameters(data):
    system = data.draw(systems())
    q = data.draw(configurations(system, beyond=0.5))
    assume(abs(det_j(system, q)) > 1e-2)
    for name, (lhs, true) in printed_table_4_2(system, q).items():
        if name != "4.16":
            assert lhs == pytest.approx(true, abs=1e-9), name
    lhs, true = printed_table_4_2(system, q, corrected=True)["4.16"]
    assert lhs == pytest.approx(true, abs=1e-9)


def test_printed_eq_4_16_fails_for_non_isocentric_c_arms():
    """Erratum: eq. 4.16 lacks a1·cθ4 in the cγ1 bracket; it holds only when a1·cγ1·cθ4 = 0."""
    carm = dataclasses.replace(PRESET.carm, a1=0.1, a2=0.05)
    system = PRESET.replace(carm=carm, setup=carmkin.TableSetup(1.2, 0.3, -1.4, -1.3, 0.1, 0.2))
    q = np.array([0.1, 0.2, 0.05, 0.1, 0.3, 0.4])
    lhs, true = printed_table_4_2(system, q)["4.16"]
    assert abs(lhs - true) == pytest.approx(abs(0.1 * math.cos(1.2) * math.cos(0.3)), rel=1e-9)
    iso = system.replace(carm=PRESET.carm)
    lhs, true = printed_table_4_2(iso, q)["4.16"]
    assert lhs == pytest.approx(true, abs=1e-12)


# --- CLI -------------------------------------------------------------------------------------------------------
def cli_pose(q) -> str:
    T = PRESET.fk(np.asarray(q, dtype=float))
    return ",".join(repr(float(v)) for v in np.r_[T[:3, 3] * 1000.0, np.degrees(pin.log3(T[:3, :3]))])


def test_cli_prints_both_branches_in_mm_and_degrees(capsys, tmp_path):
    import json

    from carmkin.cli import main

    q = np.array([0.1, 0.2, 0.05, 0.1, 0.3, 0.4])
    assert main(["ik", f"--pose={cli_pose(q)}", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    chosen = out["branches"][out["chosen"]]
    assert chosen["joints"]["table_translation_mm"] == pytest.approx(100.0, abs=1e-6)
    assert chosen["joints"]["angular_deg"] == pytest.approx(math.degrees(0.3), abs=1e-6)
    assert chosen["status"] == "ok" and len(out["branches"]) == 2
    other = out["branches"][1 - out["chosen"]]
    assert not other["within_limits"] and other["excess"]
    # same pose from a file, with a current configuration in mm/deg; text output
    T = PRESET.fk(q)
    path = tmp_path / "pose.json"
    T_mm = T.copy()
    T_mm[:3, 3] *= 1000.0
    path.write_text(json.dumps({"matrix_mm": T_mm.tolist()}))
    assert main(["ik", "--pose-file", str(path), "--current", "100,200,2.86,100,17.2,22.9"]) == 0
    text = capsys.readouterr().out
    assert "*0" in text and "ok" in text and "out of range" in text


def test_cli_exit_codes(capsys, tmp_path):
    from carmkin.cli import main

    q_out = np.array([0.1, 0.2, 0.5, 0.1, 0.3, 0.4])  # wigwag 28.6° beyond ±10° on both branches
    assert main(["ik", f"--pose={cli_pose(q_out)}"]) == 1
    assert "NOT within" in capsys.readouterr().out
    assert main(["ik", "--pose", "1,2,3"]) == 2
    assert main(["ik", "--pose=0,0,0,0,0,0", "--current", "1,2"]) == 2
    bad = tmp_path / "bad.json"
    bad.write_text('{"position_mm": [0, 0, 0]}')
    assert main(["ik", "--pose-file", str(bad)]) == 2
    assert "rotation_vector_deg" in capsys.readouterr().err


@pytest.mark.parametrize("entry", [0, 1, 2])
def test_a_nan_translation_is_refused_on_the_fast_path(entry):
    """An exactly rigid rotation with one NaN translation entry passed the fast rigidity check (the bound was
    ``max(|px|, |py|, |pz|)``, and ``max(0.6, nan)`` is 0.6) and reached the singular solver (found by
    benchmarks/fuzz.py)."""
    system = carmkin.load_preset("siremobile-iso-c3d")
    T = system.fk(np.array([0.1, 0.2, 0.05, 0.1, math.pi / 2, 0.3]))
    T[entry, 3] = np.nan
    with pytest.raises(carmkin.errors.InvalidPoseError, match="finite"):
        carmkin.analytic_ik.solve(system, T)
