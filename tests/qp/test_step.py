"""One QP step on its own: the objective handed to the backend is the damped least-squares objective of
the tasks, and the solved step respects the bounds and rows (checked against an independent solver)."""

from __future__ import annotations

import numpy as np
import qpsolvers
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import PRESET

from carmkin.qp.backends import make_backend
from carmkin.qp.limits import CollisionAvoidance, JointLimits
from carmkin.qp.step import build_step, solve_step
from carmkin.qp.tasks import PoseTask
from carmkin.qp_ik import QPIKOptions
from carmkin.world import World
from carmkin.robot.state import KinematicState

SCENE = World(PRESET)
MODEL = SCENE.model
OPTIONS = QPIKOptions()
unit6 = st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6).map(np.array)
small6 = st.lists(st.floats(-0.05, 0.05), min_size=6, max_size=6).map(np.array)
weights6 = st.lists(st.floats(0.1, 10.0), min_size=6, max_size=6).map(np.array)


def setup(u, v, weights, collisions=True):
    q = PRESET.lower + u * (PRESET.upper - PRESET.lower)
    T = PRESET.fk(PRESET.lower + v * (PRESET.upper - PRESET.lower))
    task = PoseTask(MODEL, "xray_source", T, weight=2.0)
    state = KinematicState(MODEL, q, SCENE, jacobians=True)
    limits = JointLimits(PRESET.lower, PRESET.upper, OPTIONS.max_step)
    avoidance = CollisionAvoidance(SCENE, OPTIONS.safety_margin, OPTIONS.collision_gain,
                                   OPTIONS.influence_distance) if collisions else None
    return state, task, build_step(state, [task], limits, avoidance, weights, OPTIONS)


@settings(max_examples=30, deadline=None)
@given(unit6, unit6, weights6, small6)
def test_step_objective_is_the_damped_least_squares_objective(u, v, weights, dq):
    """½ dqᵀH dq + gᵀdq = ½ (w |r + J dq|² − w |r|²) + ½ λ dqᵀ diag(weights) dq, λ = damping + error_damping E."""
    state, task, step = setup(u, v, weights)
    J, r = task.residual(MODEL, state.data)
    assert np.isclose(step.energy, task.weight * r @ r)
    lam = OPTIONS.damping + OPTIONS.error_damping * step.energy
    expected = 0.5 * task.weight * (np.sum((r + J @ dq) ** 2) - r @ r) + 0.5 * lam * dq @ (weights * dq)
    assert np.isclose(0.5 * dq @ step.H @ dq + step.g @ dq, expected, rtol=1e-9, atol=1e-12)
    assert np.allclose(step.H, step.H.T)


@settings(max_examples=30, deadline=None)
@given(unit6, unit6, weights6)
def test_solved_step_is_feasible_and_optimal(u, v, weights):
    state, _, step = setup(u, v, weights)
    dq = solve_step(make_backend(None, MODEL.nv, len(SCENE)), step)
    if dq is None:  # only when rows ask to leave the margin faster than the bounds allow
        assert step.h is not None and np.any(step.h < 0)
        return
    assert np.all(dq >= step.lb - 1e-9) and np.all(dq <= step.ub + 1e-9)
    if step.G is not None and np.all(step.h >= 0):
        assert np.all(step.G @ dq <= step.h + 1e-9)
        reference = qpsolvers.solve_qp(step.H, step.g, step.G, step.h, lb=step.lb, ub=step.ub, solver="quadprog")
        objective = lambda x: 0.5 * x @ step.H @ x + step.g @ x  # noqa: E731
        assert objective(dq) <= objective(reference) + 1e-9 * max(1.0, abs(objective(reference)))


@settings(max_examples=20, deadline=None)
@given(unit6, unit6)
def test_unconstrained_step_is_the_levenberg_marquardt_step(u, v):
    """Without rows and with inactive bounds the step solves H dq = -g."""
    state, _, step = setup(u, v, np.ones(6), collisions=False)
    dq = solve_step(make_backend(None, MODEL.nv, 0), step)
    newton = np.linalg.solve(step.H, -step.g)
    if np.all(newton > step.lb + 1e-9) and np.all(newton < step.ub - 1e-9):
        assert np.allclose(dq, newton, atol=1e-8 * max(1.0, np.abs(newton).max()))
