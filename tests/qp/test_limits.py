"""Constraint objects of one QP step: joint limits as bounds, collision avoidance as velocity-damper rows."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import PRESET

from carmkin.qp.limits import CollisionAvoidance, JointLimits
from carmkin.qp_ik import QPIKError, QPIKOptions
from carmkin.world import World
from carmkin.robot.state import KinematicState

SCENE = World(PRESET)
OPTIONS = QPIKOptions()
unit6 = st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6).map(np.array)


@settings(max_examples=40, deadline=None)
@given(unit6, st.floats(0.01, 1.0), st.lists(st.integers(0, 5), max_size=3, unique=True))
def test_bounds_keep_every_step_in_the_box_and_the_trust_region(u, max_step, locked):
    limits = JointLimits(PRESET.lower, PRESET.upper, max_step, locked)
    q = PRESET.lower + u * (PRESET.upper - PRESET.lower)
    lb, ub = limits.bounds(q)
    assert np.all(lb <= 0.0) and np.all(ub >= 0.0)  # standing still is always allowed in the box
    assert np.all(q + lb >= PRESET.lower - 1e-12) and np.all(q + ub <= PRESET.upper + 1e-12)
    assert np.all(-lb <= max_step) and np.all(ub <= max_step)
    assert np.all(lb[locked] == 0.0) and np.all(ub[locked] == 0.0)


def test_bounds_report_a_start_beyond_one_step_outside_the_box():
    limits = JointLimits(PRESET.lower, PRESET.upper, 0.1)
    q = PRESET.upper.copy()
    q[2] += 0.5
    lb, ub = limits.bounds(q)
    assert lb[2] > ub[2] and np.all(lb[[0, 1, 3, 4, 5]] <= ub[[0, 1, 3, 4, 5]])
    with pytest.raises(QPIKError, match="locked joint index"):
        JointLimits(PRESET.lower, PRESET.upper, 0.1, [6])


@settings(max_examples=30, deadline=None)
@given(unit6, st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6).map(np.array))
def test_damper_rows_bound_the_first_order_closing_speed(u, direction):
    """Any step with G dq <= h closes each near pair's gap to the margin by at most the gain's fraction (to
    first order: d + grad d · dq >= margin + (1 - gain)(d - margin)), and a pair inside must leave."""
    avoidance = CollisionAvoidance(SCENE, OPTIONS.safety_margin, OPTIONS.collision_gain, OPTIONS.influence_distance)
    q = PRESET.lower + u * (PRESET.upper - PRESET.lower)
    state = KinematicState(SCENE.model, q, SCENE, jacobians=True)
    rows = avoidance.inequalities(state)
    near = np.flatnonzero(state.distances < OPTIONS.influence_distance)
    if rows is None:
        assert near.size == 0
        return
    G, h = rows
    assert G.shape == (near.size, PRESET.nq) and h.shape == (near.size,)
    d = state.distances[near]
    gap = d - OPTIONS.safety_margin
    assert np.allclose(h, np.where(gap >= 0, OPTIONS.collision_gain * gap, gap))
    dq = 1e-3 * direction
    first_order = d - G @ dq  # -G is the distance Jacobian of the near pairs
    feasible = G @ dq <= h
    assert np.all(first_order[feasible] >= OPTIONS.safety_margin + np.minimum(gap, (1 - OPTIONS.collision_gain) * gap)[feasible] - 1e-12)
    assert avoidance.clear(state) == (state.min_distance >= OPTIONS.safety_margin - 1e-6)
