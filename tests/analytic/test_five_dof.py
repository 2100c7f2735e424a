"""5-DOF C-arm IK (source position + principal axis, roll free): closed form, polynomial solver, selection."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from strategies import PRESET, geometries

from carmkin.analytic import five_dof
from carmkin.errors import CarmkinError
from carmkin.model import kinematics
from carmkin.studies.workspace import PAPER_GRID, desired_targets

finite = dict(allow_nan=False, allow_infinity=False)


def reference_targets(carm, q5):
    """Source position and principal axis in the C-arm base frame by the generic DH product (the reference)."""
    T = kinematics.forward(kinematics.carm_rows(carm), kinematics.xray_in_flange(carm), np.atleast_2d(q5))
    return T[:, :3, 3], T[:, :3, 2]


def reference_residual(carm, q, p, z):
    """max(|Δp|, |Δz|) of branches q (N, B, 5) against targets (N, 3), by the reference FK."""
    flat = q.reshape(-1, 5)
    p_fk, z_fk = reference_targets(carm, flat)
    B = q.shape[1]
    dp = np.linalg.norm(p_fk - np.repeat(p, B, axis=0), axis=1)
    dz = np.linalg.norm(z_fk - np.repeat(z, B, axis=0), axis=1)
    return np.maximum(dp, dz).reshape(q.shape[:2])


def angle_diff(a, b):
    return np.abs(np.mod(a - b + np.pi, 2 * np.pi) - np.pi)


def contains(q_branches, q_valid, q5, tol=1e-7):
    """True where the generating configuration q5 (N, 5) is among the valid branches (angles mod 2π)."""
    d = np.abs(q_branches - q5[:, None, :])
    d[..., (1, 3, 4)] = angle_diff(q_branches[..., (1, 3, 4)], q5[:, None, (1, 3, 4)])
    return np.any(q_valid & np.all(d <= tol, axis=-1), axis=1)


@st.composite
def c_arm_configurations(draw, n_max: int = 12, min_cos5: float = 0.05) -> np.ndarray:
    """(N, 5) configurations over wide ranges, away from the cos θ5 = 0 singularity."""
    rows = []
    for _ in range(draw(st.integers(1, n_max))):
        q = [draw(st.floats(-0.5, 0.5, **finite)), draw(st.floats(-math.pi, math.pi, **finite)),
             draw(st.floats(-0.3, 0.5, **finite)), draw(st.floats(-math.pi, math.pi, **finite)),
             draw(st.floats(-math.pi, math.pi, **finite))]
        assume(abs(math.cos(q[4])) >= min_cos5)
        rows.append(q)
    return np.array(rows)


# --- closed form (isocentric) on the grid of §4.6.1 ------------------------------------------------------

@pytest.mark.parametrize("d0", np.array(PAPER_GRID.translations_mm) * 1e-3)
def test_every_branch_of_every_grid_pose_verifies_by_fk(d0):
    """Acceptance: FK residual ≤ 1e-9 for all branches of the 12285 poses at each translation."""
    p, z = desired_targets(PRESET, PAPER_GRID.configurations(), d0)
    solutions = five_dof.solve(PRESET.carm, p, z)
    assert solutions.q.shape == (len(p), 4, 5)
    assert solutions.valid.all()
    assert reference_residual(PRESET.carm, solutions.q, p, z).max() <= 1e-9


def test_grid_at_zero_translation_recovers_the_generating_pose():
    q5 = PAPER_GRID.configurations()
    p, z = reference_targets(PRESET.carm, q5)
    solutions = five_dof.solve(PRESET.carm, p, z)
    regular = np.abs(np.cos(q5[:, 4])) > 1e-6  # at cos θ5 = 0 the angular joint only rolls the image
    assert contains(solutions.q, solutions.valid, q5)[regular].all()
    # the roll-free target: in the singular case, the branch has the same d1, θ2, d3 and |θ5| = 90°
    chosen = solutions.selected[~regular]
    assert np.allclose(chosen[:, [0, 2]], q5[~regular][:, [0, 2]], atol=1e-12)
    assert np.allclose(np.abs(chosen[:, 4]), np.pi / 2, atol=1e-7)


@given(geometries(isocentric=True), c_arm_configurations())
def test_closed_form_has_four_verified_branches(carm, q5):
    p, z = reference_targets(carm, q5)
    solutions = five_dof.solve(carm, p, z)
    assert solutions.valid.all()
    assert contains(solutions.q, solutions.valid, q5).all()
    assert reference_residual(carm, solutions.q, p, z).max() <= 1e-9
    # isocentre c = p + l2 z: every branch puts it at height d1 and at reach M + d3 along the arm
    c = p + carm.orbital_offset * z
    for b in range(4):
        q = solutions.q[:, b]
        assert np.allclose(q[:, 0], c[:, 2], atol=1e-12)
        assert np.allclose(np.abs(carm.length_offset + q[:, 2]), np.hypot(c[:, 0], c[:, 1]), atol=1e-12)


@given(geometries(isocentric=True), c_arm_configurations())
def test_selection_rule_isocentric(carm, q5):
    """The chosen branch: arm forward (M + d3 > 0) and |θ5| ≤ 90°; it is the only such branch."""
    solutions = five_dof.solve(carm, *reference_targets(carm, q5))
    q = solutions.selected
    assert np.all(carm.length_offset + q[:, 2] > 0)
    assert np.all(np.abs(q[:, 4]) <= np.pi / 2 + 1e-12)
    preferred = (carm.length_offset + solutions.q[..., 2] > 0) & (np.cos(solutions.q[..., 4]) > 0)
    assert np.all(preferred.sum(axis=1) == 1)


def test_singular_target_isocentric_sets_angular_to_zero():
    """Principal axis along the angular axis (θ5 = 90°): θ4 only rolls the image; it is set to 0."""
    q5 = np.array([[0.1, 0.05, 0.1, 0.7, np.pi / 2]])
    p, z = reference_targets(PRESET.carm, q5)
    solutions = five_dof.solve(PRESET.carm, p, z)
    assert solutions.selected[0, 3] == 0.0
    assert solutions.selected[0, 4] == pytest.approx(np.pi / 2)
    assert reference_residual(PRESET.carm, solutions.q, p, z).max() <= 1e-9


# --- polynomial solver (general a1, a2) ----------------------------------------------------------------

@settings(max_examples=60)
@given(geometries(), c_arm_configurations())
def test_polynomial_solver_finds_the_generating_configuration(carm, q5):
    p, z = reference_targets(carm, q5)
    solutions = five_dof.solve(carm, p, z, method="polynomial")
    assert contains(solutions.q, solutions.valid, q5, tol=1e-6).all()
    res = reference_residual(carm, np.nan_to_num(solutions.q), p, z)
    assert np.all(res[solutions.valid] <= 1e-9)
    assert np.all(solutions.valid.sum(axis=1) <= 8)  # a degree-8 polynomial in tan(θ2/2)


@settings(max_examples=20)
@given(geometries(), c_arm_configurations(n_max=3))
def test_polynomial_solver_misses_no_root_of_the_wigwag_equation(carm, q5):
    """Every sign change of f_σ(θ2) on a fine θ2 grid (both σ) is one of the returned branches."""
    p, z = reference_targets(carm, q5)
    solutions = five_dof.solve(carm, p, z, method="polynomial")
    L, a1, a2 = carm.orbital_offset + carm.a1, carm.a1, carm.a2
    theta = np.linspace(-np.pi, np.pi, 40001)
    c, s = np.cos(theta), np.sin(theta)
    for i in range(len(p)):
        Px = c * p[i, 0] + s * p[i, 1]
        Ux, Uy = c * z[i, 0] + s * z[i, 1], -s * z[i, 0] + c * z[i, 1]
        for sigma in (1.0, -1.0):
            f = (Px + L * Ux) * sigma * np.hypot(Ux, z[i, 2]) - Ux * (a1 - a2 * Uy)
            for j in np.flatnonzero(np.sign(f[1:]) * np.sign(f[:-1]) < 0):
                found = angle_diff(solutions.q[i, :, 1], theta[j])[solutions.valid[i]]
                assert found.size and found.min() < 1e-3


@settings(max_examples=30)
@given(geometries(isocentric=True), c_arm_configurations())
def test_polynomial_solver_agrees_with_closed_form_on_isocentric_arms(carm, q5):
    p, z = reference_targets(carm, q5)
    closed = five_dof.solve(carm, p, z, method="closed-form")
    poly = five_dof.solve(carm, p, z, method="polynomial")
    assert np.all(poly.valid.sum(axis=1) == 4)
    for b in range(4):
        assert contains(poly.q, poly.valid, closed.q[:, b], tol=1e-6).all()
    assert contains(poly.selected[:, None], np.ones((len(q5), 1), bool), closed.selected, tol=1e-6).all()


@given(geometries(), c_arm_configurations())
def test_complete_inverts_fk_at_the_true_wigwag(carm, q5):
    """The shared completion step: given the true θ2 and sign of cos θ5, the other joints follow exactly."""
    p, z = reference_targets(carm, q5)
    q = five_dof.complete(carm, p, z, q5[:, 1], np.sign(np.cos(q5[:, 4])))
    d = np.abs(q - q5)
    d[:, (1, 3, 4)] = angle_diff(q[:, (1, 3, 4)], q5[:, (1, 3, 4)])
    assert d.max() <= 1e-9


# --- range excess and errors -------------------------------------------------------------------------

def test_range_excess_wraps_revolute_joints_but_not_prismatic_ones():
    carm = PRESET.carm
    q = np.array([[0.45, math.radians(355), -0.01, math.radians(200), math.radians(-100)]])
    e = five_dof.range_excess(carm, q)[0]
    assert e[0] == pytest.approx(0.05)
    assert e[1] == 0.0  # 355° is −5°
    assert e[2] == pytest.approx(-0.01)
    assert e[3] == 0.0  # 200° is −160°
    assert e[4] == pytest.approx(math.radians(-5))  # −100° = 260°: outside ±95° either way


@pytest.mark.parametrize("position, direction", [
    ([0, 0, 0], [0, 0, 2.0]),
    ([0, 0], [0, 0, 1]),
    ([0, 0, np.nan], [0, 0, 1]),
    ([[0, 0, 0], [1, 1, 1]], [0, 0, 1]),
    ("abc", [0, 0, 1]),
])
def test_bad_targets_raise_a_typed_error(position, direction):
    with pytest.raises(five_dof.FiveDofTargetError):
        five_dof.solve(PRESET.carm, position, direction)


def test_closed_form_refuses_non_isocentric_arms_and_unknown_methods():
    carm = replace(PRESET.carm, a1=0.05)
    with pytest.raises(CarmkinError, match="isocentric"):
        five_dof.solve(carm, [0, 1.3, 0], [0, 0, 1], method="closed-form")
    with pytest.raises(CarmkinError, match="method"):
        five_dof.solve(PRESET.carm, [0, 1.3, 0], [0, 0, 1], method="newton")
