"""Damped-least-squares IK on Pinocchio's Jacobian (carmkin.analytic.dls)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import PRESET, configurations, systems

import carmkin
from carmkin.analytic import dls as numerical_ik


@settings(max_examples=30)
@given(st.data())
def test_converges_from_a_nearby_seed(data):
    system = data.draw(systems())
    q = data.draw(configurations(system))
    seed = q + data.draw(st.lists(st.floats(-0.05, 0.05), min_size=6, max_size=6))
    T = system.fk(q)
    run = numerical_ik.solve(system, T, seed)
    assert run.success and run.residual <= 1e-9
    # the residual it reports is the pose error of FK(q) (independent FK, independent error measure)
    T_q = system.fk(run.q)
    assert np.linalg.norm(T_q[:3, 3] - T[:3, 3]) <= 1e-9
    assert np.linalg.norm(pin.log3(T_q[:3, :3].T @ T[:3, :3])) <= 1e-9


def test_reports_failure_on_an_unreachable_pose_without_raising():
    """With γ1 = 0 (case a) the chain has 5 DOF: a generic pose is out of reach."""
    s = PRESET.setup
    system = PRESET.replace(setup=carmkin.TableSetup(0.0, s.gamma2, s.gamma3, s.D1, s.D2, s.D3))
    T = system.fk(np.array([0.0, 0.1, 0.05, 0.1, 0.3, 0.2]))
    T[:3, 3] += (0.05, 0.0, 0.0)  # off the reachable set
    run = numerical_ik.solve(system, T, np.zeros(6))
    if not run.success:
        assert run.residual > 1e-9 and run.iterations > 0
    start = max(numerical_ik.pose_error(system.fk(np.zeros(6)), T))
    assert run.residual <= start  # the best iterate is kept


def test_pose_error_measures_distance_and_angle():
    T = np.eye(4)
    U = np.eye(4)
    U[:3, :3] = pin.exp3(np.array([0.0, 0.0, 0.3]))
    U[:3, 3] = (0.3, 0.4, 0.0)
    dp, angle = numerical_ik.pose_error(T, U)
    assert dp == pytest.approx(0.5) and angle == pytest.approx(0.3)
    U[:3, :3] = pin.exp3(np.array([1e-12, 0.0, 0.0]))
    assert numerical_ik.pose_error(T, U)[1] == pytest.approx(1e-12, rel=1e-3)


def test_typed_errors():
    with pytest.raises(carmkin.InvalidPoseError):
        numerical_ik.solve(PRESET, np.eye(3), np.zeros(6))
    with pytest.raises(numerical_ik.NumericalIKError):
        numerical_ik.solve(PRESET, np.eye(4), np.zeros(5))
    with pytest.raises(numerical_ik.NumericalIKError):
        numerical_ik.DampedLeastSquares(PRESET.pinocchio()[0], frame="nope")
    assert issubclass(numerical_ik.NumericalIKError, carmkin.CarmkinError)
    assert math.isfinite(numerical_ik.TOLERANCE)
