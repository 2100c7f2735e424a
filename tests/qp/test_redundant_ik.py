"""Redundant QP IK with every table DOF (issue 9): weighted minimal motion, locked joints, agreement with
Pinocchio and with the single-axis closed form."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import carmkin
from carmkin.analytic.single_axis import solve_single_axis
from carmkin.qp_ik import (
    PREFERENCE_RATIO,
    QPIKError,
    is_table_joint,
    joint_weights,
    solve,
    solve_redundant,
)
from carmkin.world import World

MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
SCENE = World(MOTORIZED)
TABLE = np.array([is_table_joint(n) for n in MOTORIZED.joint_names])
MARGIN = 0.01


unit11 = st.lists(st.floats(0.0, 1.0), min_size=11, max_size=11).map(np.array)


def valid_configuration(u, inset: float = 0.1, clearance: float = 2 * MARGIN) -> np.ndarray:
    """The drawn point ``u`` (11,) of the unit cube in the ranges shrunk by ``inset`` of their width; the
    example is discarded unless every pair is >= ``clearance`` (m) apart."""
    lo, hi = MOTORIZED.lower, MOTORIZED.upper
    q = lo + inset * (hi - lo) + u * (1 - 2 * inset) * (hi - lo)
    assume(SCENE.distances(q=q).min() >= clearance)
    return q


def pinocchio_pose(q) -> np.ndarray:
    model = MOTORIZED.pinocchio()[0]
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[model.getFrameId("xray_source")].homogeneous


def test_joint_weights_by_name_and_preference():
    w = joint_weights(MOTORIZED, {"table_tilt": 5.0})
    assert w[MOTORIZED.joint_names.index("table_tilt")] == 5.0 and np.sum(w != 1.0) == 1
    carm = joint_weights(MOTORIZED, prefer="carm")
    assert np.all(carm[TABLE] == PREFERENCE_RATIO) and np.all(carm[~TABLE] == 1.0)
    table = joint_weights(MOTORIZED, prefer="table")
    assert np.all(table[~TABLE] == PREFERENCE_RATIO) and np.all(table[TABLE] == 1.0)


@pytest.mark.parametrize("bad", [{"nope": 1.0}, {"table_tilt": 0.0}, [1.0] * 3, [np.nan] * 11])
def test_bad_weights_raise(bad):
    with pytest.raises(QPIKError):
        joint_weights(MOTORIZED, bad)


def test_bad_preference_and_free_names_raise():
    with pytest.raises(QPIKError, match="prefer"):
        joint_weights(MOTORIZED, prefer="floor")
    with pytest.raises(QPIKError, match="free"):
        solve(MOTORIZED, MOTORIZED.fk(np.zeros(11)), free=("vertical", "elbow"))


@settings(max_examples=8, deadline=None)
@given(unit11, st.lists(st.floats(-1.0, 1.0), min_size=11, max_size=11).map(np.array))
def test_preference_changes_which_joints_move(u, noise):
    """From q0 to a target near it: prefer="carm" moves the table less and the C-arm more than prefer="table"."""
    q0 = valid_configuration(u, clearance=0.1)  # far from every collision: the QP runs free of them
    assume(np.abs(noise).max() > 0.1)
    q1 = q0 + 0.02 * noise * (MOTORIZED.upper - MOTORIZED.lower)
    target = MOTORIZED.fk(q1)
    moves = {}
    for prefer in ("carm", "table"):
        result = solve(MOTORIZED, target, q_current=q0, prefer=prefer, closed_form=False)
        assert result.success, result.reason
        assert result.seed == "q_current"
        dq = result.q - q0
        moves[prefer] = (np.linalg.norm(dq[TABLE]), np.linalg.norm(dq[~TABLE]))
    assert moves["carm"][0] < moves["table"][0]
    assert moves["carm"][1] > moves["table"][1]


@settings(max_examples=15, deadline=None)
@given(unit11)
def test_qp_solution_valid_and_pinocchio_agrees_with_closed_form_fk(u):
    """The one solve without q_current on the motorized preset (single-axis closed form, then the QP), for
    configurations at least 1 % of each range from the limits (see the known case below for the limits)."""
    q_true = valid_configuration(u, inset=0.01)
    target = MOTORIZED.fk(q_true)
    result = solve(MOTORIZED, target)
    assert result.success, result.reason
    q = result.q
    assert np.all(q >= MOTORIZED.lower - 1e-12) and np.all(q <= MOTORIZED.upper + 1e-12)
    assert SCENE.distances(q=q).min() >= MARGIN - 1e-6
    assert np.abs(pinocchio_pose(q) - MOTORIZED.fk(q)).max() <= 1e-12
    assert np.abs(MOTORIZED.fk(q) - target).max() <= 1e-5


@settings(max_examples=10, deadline=None)
@given(unit11, st.sampled_from(("table_translation", "table_lateral")))
def test_single_axis_closed_form_and_qp_reach_the_same_pose(u, active):
    """Only ``active`` and the C-arm free, other table joints held: table_ik and the QP both land on T."""
    q_true = valid_configuration(u)
    target = MOTORIZED.fk(q_true)
    free = (active,) + MOTORIZED.joint_names[-5:]
    closed = solve_single_axis(MOTORIZED, target, active, q_held=q_true)
    qp = solve(MOTORIZED, target, q_current=np.where(np.isin(MOTORIZED.joint_names, free), 0.0, q_true),
               free=free, seeds=closed.solutions[np.all(np.isfinite(closed.solutions), axis=1)],
               closed_form=False, random_seeds=4)
    assert qp.success, qp.reason
    held = ~np.isin(MOTORIZED.joint_names, free)
    assert np.array_equal(qp.q[held], q_true[held])  # locked joints did not move
    assert np.abs(MOTORIZED.fk(closed.q) - target).max() <= 1e-9
    assert np.abs(pinocchio_pose(qp.q) - pinocchio_pose(closed.q)).max() <= 1e-5


def test_solve_redundant_is_an_alias_of_solve():
    """The deprecated name gives the one solve's answer."""
    target = MOTORIZED.fk(0.5 * (MOTORIZED.lower + MOTORIZED.upper) + 0.01)
    old, new = solve_redundant(MOTORIZED, target), solve(MOTORIZED, target)
    assert old.success and new.success and np.array_equal(old.q, new.q) and old.path == new.path


@pytest.mark.xfail(strict=True, reason="known limitation: with the wigwag and four table joints exactly on their "
                   "limits the QP stalls 0.6 mm / 0.01° short of this target from every seed (400 iterations do "
                   "not help); found by hypothesis. strict: the day it is solved, this test says so")
def test_known_hard_target_with_five_joints_on_their_limits():
    u = np.array([0.5, 0.0, 0.75, 0.0, 0.75, 0.0, 0.5, 0.0, 1.0, 0.0, 0.0])
    q_true = MOTORIZED.lower + u * (MOTORIZED.upper - MOTORIZED.lower)
    assert SCENE.distances(q=q_true).min() >= 2 * MARGIN  # a valid target, well clear of table and floor
    assert solve(MOTORIZED, MOTORIZED.fk(q_true)).success
