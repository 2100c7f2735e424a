"""Singularity analysis (§4.3.2): Pinocchio's det J = eq. 4.7, rank drops and lost directions, measures, CLI."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from strategies import PRESET, configurations, geometries, systems

import carmkin
from carmkin import singularity as sing
from carmkin import transforms
from carmkin.cli import main

finite = dict(allow_nan=False, allow_infinity=False)
angles = st.floats(-math.pi, math.pi, **finite)


def pinocchio_jacobian(system, q, reference=pin.LOCAL_WORLD_ALIGNED) -> np.ndarray:
    """Jacobian of xray_source straight from Pinocchio (independent of carmkin.singularity)."""
    model = system.pinocchio()[0]
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    return pin.getFrameJacobian(model, data, model.getFrameId("xray_source"), reference)


def printed_eq_4_7(setup, q) -> float:
    """Eq. 4.7 exactly as printed: (sγ3 cθ2 + cγ3 sθ2) · sγ1 · cθ4."""
    s, c = math.sin, math.cos
    g1, g3, t2, t4 = setup.gamma1, setup.gamma3, q[2], q[4]
    return (s(g3) * c(t2) + c(g3) * s(t2)) * s(g1) * c(t4)


def axes_from_pinocchio(system, q) -> np.ndarray:
    """Joint axes z0..z5 (6, 3) in the table frame: Z of the root and of Pinocchio's dh_frame_1..5."""
    model = system.pinocchio()[0]
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return np.array([[0.0, 0.0, 1.0]] + [data.oMf[model.getFrameId(f"dh_frame_{i}")].rotation[:, 2]
                                         for i in range(1, 6)])


def svd_rank(J: np.ndarray, rtol: float = 1e-9) -> int:
    sv = np.linalg.svd(J, compute_uv=False)
    return int(np.sum(sv > rtol * sv[0]))


def parallel(u, v, tol=1e-7) -> bool:
    u, v = np.asarray(u, float), np.asarray(v, float)
    return np.linalg.norm(np.cross(u, v)) <= tol * np.linalg.norm(u) * np.linalg.norm(v) and np.linalg.norm(u) > 0


# --- eq. 4.7 against the chain -------------------------------------------------------------------------------
@given(systems(), st.data())
def test_pinocchio_det_equals_eq_4_7(system, data):
    q = data.draw(configurations(system, beyond=0.5))
    det = np.linalg.det(pinocchio_jacobian(system, q))
    assert abs(det - printed_eq_4_7(system.setup, q)) <= 1e-9
    assert abs(sing.det_jacobian(system, q) - det) <= 1e-12
    assert abs(sing.det_closed_form(system, q) - det) <= 1e-9


@settings(max_examples=30)
@given(systems(), st.data())
def test_det_does_not_depend_on_frame_but_on_row_order(system, data):
    q = data.draw(configurations(system, beyond=0.5))
    references = (pin.LOCAL, pin.WORLD, pin.LOCAL_WORLD_ALIGNED)
    dets = [np.linalg.det(pinocchio_jacobian(system, q, ref)) for ref in references]
    assert np.ptp(dets) <= 1e-9
    angular_first = np.roll(pinocchio_jacobian(system, q), 3, axis=0)
    expected = printed_eq_4_7(system.setup, q)
    assume(abs(expected) > 1e-3)
    assert np.linalg.det(angular_first) == pytest.approx(-expected, abs=1e-9)  # sign flips: linear rows first


@given(systems(), st.lists(configurations(beyond=0.5), min_size=1, max_size=10))
def test_closed_form_is_vectorized(system, qs):
    qs = np.array(qs)
    batch = sing.det_closed_form(system, qs)
    dist = sing.singularity_distances(system, qs)
    for k, q in enumerate(qs):
        assert batch[k] == pytest.approx(printed_eq_4_7(system.setup, q), abs=1e-15)
        single = sing.singularity_distances(system, q)
        assert all(single[c] == pytest.approx(dist[c][k], abs=1e-15) for c in sing.CASES)


# --- constructed singular configurations --------------------------------------------------------------------
@st.composite
def case_a_systems(draw):
    """Systems whose table axis is parallel to the vertical axis (γ1 = 0 or π)."""
    setup = carmkin.TableSetup(draw(st.sampled_from([0.0, math.pi])), draw(angles), draw(angles),
                               *(draw(st.floats(-1, 1, **finite)) for _ in range(3)))
    return PRESET.replace(carm=draw(geometries()), setup=setup)


def regular_in_other_cases(system, q, case, margin=0.05):
    d = sing.singularity_distances(system, q)
    return all(d[c] > margin for c in sing.CASES if c != case)


def singular_in(case, system, q):
    """Pinocchio's J (rank 5 checked), its joint axes and the classification, which names ``case`` alone."""
    assume(regular_in_other_cases(system, q, case))
    J = pinocchio_jacobian(system, q)
    assert svd_rank(J) == 5
    report = sing.classify(system, q)
    assert report.singular_cases == (case,) and report.rank == 5
    return J, axes_from_pinocchio(system, q), report


@settings(max_examples=40)
@given(case_a_systems(), st.data())
def test_case_a_table_parallel_to_vertical(system, data):
    q = data.draw(configurations(system, beyond=0.5))
    J, z, report = singular_in("a", system, q)
    assert parallel(z[0], z[1])
    # d0 and d1 drive the same line: the self-motion is ḋ0 = -(z0·z1) ḋ1, nothing else moves.
    expected = np.array([1.0, -np.dot(z[0], z[1]), 0, 0, 0, 0]) / math.sqrt(2)
    assert np.allclose(np.abs(report.joint_null), np.abs(expected), atol=1e-7)
    assert np.linalg.norm(J @ report.joint_null) <= 1e-9
    # With orientation held, no translation across the arm: linear part of the constraint ∥ Z1 × Z3.
    n = np.cross(z[1], z[3])
    assert parallel(report.cases["a"].axis, n)
    assert parallel(report.twist_constraint[:3], n, tol=1e-6)
    assert np.linalg.norm(report.twist_constraint @ J) <= 1e-9


@settings(max_examples=40)
@given(systems(), st.data(), st.sampled_from([-math.pi / 2, math.pi / 2]))
def test_case_b_orbital_parallel_to_wigwag(system, data, theta4):
    q = data.draw(configurations(system))
    q[4] = theta4
    J, z, report = singular_in("b", system, q)
    assert parallel(z[5], z[2])
    v = report.joint_null
    assert np.linalg.norm(J @ v) <= 1e-9
    assert abs(v[4]) <= 1e-7 and abs(abs(v[2]) - abs(v[5])) <= 1e-7 and abs(v[2]) > 1e-3  # θ̇2 = ±θ̇5
    # The source cannot rotate about Z2 × Z4: the constraint is a pure angular one along that axis.
    n = np.cross(z[2], z[4])
    assert np.linalg.norm(report.twist_constraint[:3]) <= 1e-7
    assert parallel(report.twist_constraint[3:], n, tol=1e-6) and parallel(report.cases["b"].axis, n)


@settings(max_examples=40)
@given(systems(), st.data(), st.sampled_from([0.0, math.pi]))
def test_case_c_horizontal_parallel_to_table_projection(system, data, k_pi):
    q = data.draw(configurations(system))
    q[2] = -system.setup.gamma3 + k_pi
    J, z, report = singular_in("c", system, q)
    assert abs(np.dot(np.cross(z[0], z[1]), z[3])) <= 1e-9  # the three prismatic axes are coplanar
    v = report.joint_null
    assert np.linalg.norm(J @ v) <= 1e-9
    assert np.abs(v[[2, 4, 5]]).max() <= 1e-7  # only d0, d1, d3 move
    n = np.cross(z[0], z[1])
    assert parallel(report.twist_constraint[:3], n, tol=1e-6) and parallel(report.cases["c"].axis, n)


@given(systems(), st.data())
def test_regular_configurations_have_rank_6(system, data):
    q = data.draw(configurations(system, beyond=0.5))
    assume(min(sing.singularity_distances(system, q).values()) > 1e-3)
    assert svd_rank(pinocchio_jacobian(system, q)) == 6
    report = sing.classify(system, q, near=1e-4, tol=1e-6)
    assert report.rank == 6 and report.singular_cases == () and report.near_cases == ()


@given(systems(), st.data())
def test_distance_is_the_joint_move_that_reaches_the_set(system, data):
    q = data.draw(configurations(system, beyond=0.5))
    d = sing.singularity_distances(system, q)
    for joint, case in ((4, "b"), (2, "c")):
        hits = []
        for sign in (-1, 1):
            moved = q.copy()
            moved[joint] += sign * d[case]
            with np.errstate(divide="ignore", invalid="ignore"):  # LAPACK meets an exact zero pivot on the set
                hits.append(abs(np.linalg.det(pinocchio_jacobian(system, moved))))
        assert min(hits) <= 1e-9


# --- printed statements that the chain refutes (docs/errata/singularity.md) --------------------------------
def test_printed_case_c_theta2_equals_minus_gamma3_misses_half_the_set():
    """§4.3.2 lists θ2 = −γ3 only; θ2 = π − γ3 is singular as well (sin(θ2 + γ3) = 0)."""
    system = PRESET.replace(carm=PRESET.carm.__class__(1.2, 0.6, a1=0.1, a2=-0.07),
                            setup=carmkin.TableSetup(1.2, 0.3, 0.4, 0.5, 0.1, 0.2))
    q = np.array([0.1, 0.2, math.pi - system.setup.gamma3, 0.1, 0.3, 0.2])
    assert not math.isclose(q[2], -system.setup.gamma3)  # not in the printed set ...
    assert svd_rank(pinocchio_jacobian(system, q)) == 5  # ... but singular
    assert sing.classify(system, q).singular_cases == ("c",)


def test_printed_words_of_case_c_need_a_level_table():
    """'table translation ∥ horizontal movement' holds at θ2 = −γ3 only if γ1 = ±90°; for a tilted table the
    axes are not parallel, yet J is singular (the prismatic axes are coplanar)."""
    system = PRESET.replace(setup=carmkin.TableSetup(1.0, 0.3, 0.4, 0.5, 0.1, 0.2))
    q = np.array([0.0, 0.2, -system.setup.gamma3, 0.1, 0.3, 0.2])
    z = axes_from_pinocchio(system, q)
    assert not parallel(z[0], z[3], tol=1e-3)
    assert svd_rank(pinocchio_jacobian(system, q)) == 5


# --- measures -----------------------------------------------------------------------------------------------
@settings(max_examples=30)
@given(systems(), st.data(), st.floats(0.05, 5.0, **finite))
def test_measures_are_consistent(system, data, length):
    q = data.draw(configurations(system, beyond=0.5))
    J = pinocchio_jacobian(system, q)
    m = sing.measures(system, q, length)
    Js = sing.scaled_jacobian(system, q, length)
    assert np.linalg.det(Js) == pytest.approx(np.linalg.det(J), abs=1e-9)  # det is scale-free
    # squared: sqrt of a det near 0 turns its ~1e-15 rounding into ~1e-7 (a singular q, e.g. θ4 = ±90°)
    assert m.manipulability ** 2 == pytest.approx(np.linalg.det(Js @ Js.T), rel=1e-9, abs=1e-12)
    assert m.manipulability == pytest.approx(abs(np.linalg.det(J)), abs=1e-9)
    assert m.condition >= 1.0 and m.sigma_min == pytest.approx(np.linalg.svd(Js, compute_uv=False)[-1])
    # Js = diag(I/L, I) J diag(L for prismatic): prismatic linear entries unchanged, revolute ones divided by L.
    prismatic = np.array(system.prismatic)
    assert np.allclose(Js[:3, prismatic], J[:3, prismatic])
    assert np.allclose(Js[:3, ~prismatic] * length, J[:3, ~prismatic])


def test_typed_errors():
    motorized = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
    with pytest.raises(sing.SingularityError, match="6-joint chain"):
        sing.classify(motorized, np.zeros(motorized.nq))
    with pytest.raises(sing.SingularityError, match="characteristic length"):
        sing.measures(PRESET, np.zeros(6), length=-1.0)
    with pytest.raises(carmkin.InvalidConfigurationError):
        sing.singular_factors(PRESET, np.zeros(5))
    with pytest.raises(sing.SingularityError, match="joint must be"):
        sing.joint_index("elbow")
    assert issubclass(sing.SingularityError, carmkin.CarmkinError)


def test_det_map_equals_pinocchio_on_grid_points():
    q = np.array([0.0, 0.2, 0.0, 0.1, 0.0, 0.3])
    system = PRESET.replace(carm=PRESET.carm.__class__(1.2, 0.6, a1=0.1, a2=-0.07))
    x, y, values = sing.measure_map(system, q, (2, 4), n=7)
    for i in (0, 3, 5):
        for j in (1, 4, 6):
            qq = q.copy()
            qq[2], qq[4] = x[j], y[i]
            assert values[i, j] == pytest.approx(abs(np.linalg.det(pinocchio_jacobian(system, qq))), abs=1e-9)


# --- CLI -----------------------------------------------------------------------------------------------------
def test_cli_writes_the_maps(tmp_path, capsys):
    out = tmp_path / "maps.png"
    assert main(["singularity", "--png", str(out), "--grid", "9", "--pair", "wigwag,horizontal",
                 "--q-mm-deg", "0,200,0,100,90,0"]) == 0
    data = out.read_bytes()
    assert data.startswith(b"\x89PNG\r\n\x1a\n") and len(data) > 1000
    text = capsys.readouterr().out
    assert "(b)" in text and "SINGULAR" in text and "rank 5" in text


def test_cli_check_and_errors(capsys):
    assert main(["singularity", "--check", "20", "--random-setups", "3"]) == 0
    assert "PASS" in capsys.readouterr().out
    assert main(["singularity", "--pair", "wigwag,elbow", "--png", "unused.png"]) == 2
    assert main(["singularity", "--q-mm-deg", "1,2,3"]) == 2


# --- issue 19: singularity for any system ----------------------------------------------------------------
MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")


def paper_det(system, q):
    """|det| of Pinocchio's Jacobian columns of the paper's six joints (extra table joints held)."""
    columns = [system.joint_names.index(n) for n in sing.JOINT_NAMES]
    return abs(np.linalg.det(pinocchio_jacobian(system, q)[:, columns]))


@pytest.mark.parametrize("system", [PRESET, MOTORIZED], ids=["plain", "motorized"])
def test_joint_index_by_name_symbol_and_index(system):
    for k, name in enumerate(system.joint_names):
        assert sing.joint_index(name, system) == k == sing.joint_index(k, system)
    assert sing.joint_index("theta4", system) == system.joint_names.index("angular")
    for bad in (-1, system.nq, 17, True, 2.0, None, "elbow", b"wigwag", np.int64(-2)):
        with pytest.raises(sing.SingularityError):  # before: -1 a Python alias, 17 accepted
            sing.joint_index(bad, system)


def test_motorized_curves_are_at_the_c_arms_joints():
    # before: (2, 4) = (table_trendelenburg, table_height) were annotated with cases c and b, and the real
    # angular/orbital pair got nothing
    assert sing.singular_curves(MOTORIZED, (2, 4)) == []
    curves = sing.singular_curves(MOTORIZED, ("angular", "orbital"))
    angular = MOTORIZED.joint_names.index("angular")
    assert sorted((c, j, round(v, 12)) for c, j, v in curves) == sorted(
        [("b", angular, round(-math.pi / 2, 12)), ("b", angular, round(math.pi / 2, 12))])


@pytest.mark.parametrize("system", [PRESET, MOTORIZED], ids=["plain", "motorized"])
@settings(max_examples=15, deadline=None)
@given(data=st.data())
def test_curves_are_singular_for_pinocchio(system, data):
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    q = system.lower + rng.random(system.nq) * (system.upper - system.lower)
    curves = sing.singular_curves(system, ("wigwag", "angular"), q)
    assert {c for c, _, _ in curves} == {"b", "c"}
    for case, joint, value in curves:
        qq = q.copy()
        qq[joint] = value
        assert paper_det(system, qq) < 1e-9, (case, system.joint_names[joint], value)
        qq[joint] = value + 0.1
        assert paper_det(system, qq) > 1e-6


def test_case_c_curve_is_minus_gamma3_on_the_six_joint_chain():
    for gamma3 in (-math.pi / 2, -0.3, 0.0, 1.1, math.pi):
        system = PRESET.replace(setup=dataclasses.replace(PRESET.setup, gamma3=gamma3))
        values = sorted(v for c, _, v in sing.singular_curves(system, (2, 4)) if c == "c")
        expected = sorted(transforms.wrap_angle(v) for v in (-gamma3, math.pi - gamma3))
        assert np.allclose(values, expected, atol=1e-12)


def test_motorized_maps_by_name():
    q = 0.5 * (MOTORIZED.lower + MOTORIZED.upper)
    x, y, values = sing.measure_map(MOTORIZED, q, ("angular", "orbital"), n=5, measure="det")
    assert values.shape == (5, 5)
    qq = q.copy()
    qq[MOTORIZED.joint_names.index("angular")], qq[MOTORIZED.joint_names.index("orbital")] = x[1], y[2]
    assert values[2, 1] == pytest.approx(paper_det(MOTORIZED, qq), abs=1e-12)
    x, y, values = sing.measure_map(MOTORIZED, q, (9, 10), n=4, measure="sigma-min")
    assert np.all(np.isfinite(values)) and values.shape == (4, 4)
    assert np.allclose(sing.grid_axis(MOTORIZED, "table_height", 3),
                       np.linspace(MOTORIZED.joint_ranges[4].lower, MOTORIZED.joint_ranges[4].upper, 3))
    with pytest.raises(sing.SingularityError):
        sing.measure_map(MOTORIZED, q, (-1, 9))  # before: a Python alias for orbital


@pytest.mark.parametrize("length", [1e300, 1e-320, 0.0, -1.0, float("nan"), float("inf"), "1", True, 1 + 0j])
def test_absurd_characteristic_lengths_are_refused(length):
    # before: NaN measures with leaked overflow warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(sing.SingularityError, match="characteristic length"):
            sing.measures(PRESET, np.zeros(6), length=length)
        with pytest.raises(sing.SingularityError, match="characteristic length"):
            sing.measure_map(MOTORIZED, np.zeros(MOTORIZED.nq), (9, 10), n=3, measure="sigma-min", length=length)
