"""Closed form with one table translation active and the other table joints held (issue 9)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import finite

import carmkin
from carmkin.model.singular_cases import SingularCase
from carmkin.analytic.single_axis import (
    TRANSLATIONS,
    TableIKError,
    equivalent_chain,
    solve_single_axis,
)

MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")


@st.composite
def in_range(draw, system=MOTORIZED) -> np.ndarray:
    return np.array([draw(st.floats(r.lower, r.upper, **finite)) for r in system.joint_ranges])


def _pose_error(system, q, T) -> float:
    model = system.pinocchio()[0]
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return float(np.abs(data.oMf[model.getFrameId("xray_source")].homogeneous - T).max())


@settings(max_examples=150)
@given(in_range(), st.sampled_from(TRANSLATIONS))
def test_round_trip_with_each_translation_active(q, active):
    T = MOTORIZED.fk(q)
    result = solve_single_axis(MOTORIZED, T, active, q_held=q)
    assert result.ik.branches[0].reached
    errors = [np.abs(MOTORIZED.fk(s, check_units=False) - T).max() for s in result.solutions if np.all(np.isfinite(s))]
    assert max(errors) <= 1e-9
    # one branch is the generating configuration; held joints are untouched
    assert min(np.abs(result.solutions - q).max(axis=1)) <= 1e-7
    held = [i for i, n in enumerate(MOTORIZED.joint_names[:6]) if n != active]
    assert np.array_equal(result.solutions[:, held], np.tile(q[held], (2, 1)))
    assert _pose_error(MOTORIZED, result.q, T) <= 1e-9  # Pinocchio agrees


@given(in_range(), st.sampled_from(TRANSLATIONS))
def test_equivalent_chain_reproduces_the_multi_dof_model(q, active):
    system6, T_eq_table, index = equivalent_chain(MOTORIZED, active, q)
    q6 = np.concatenate(([q[index]], q[-5:]))
    assert np.abs(T_eq_table @ MOTORIZED.fk(q) - system6.fk(q6)).max() <= 1e-12


def test_height_with_a_level_table_is_singular_case_a_and_solved_numerically():
    q = np.zeros(MOTORIZED.nq)
    q[MOTORIZED.joint_names.index("table_height")] = 0.05
    q[-5:] = (0.2, 0.05, 0.1, 0.3, -0.2)
    result = solve_single_axis(MOTORIZED, MOTORIZED.fk(q), "table_height", q_held=q)
    assert SingularCase.TABLE_PARALLEL_TO_VERTICAL in result.ik.singular
    assert result.ik.numerical
    assert np.abs(MOTORIZED.fk(result.q) - MOTORIZED.fk(q)).max() <= 1e-9


def test_rejects_rotational_or_unknown_active_joints():
    q = np.zeros(MOTORIZED.nq)
    with pytest.raises(TableIKError, match="not a table translation"):
        solve_single_axis(MOTORIZED, np.eye(4), "table_tilt", q)
    with pytest.raises(TableIKError, match="not a joint"):
        solve_single_axis(MOTORIZED, np.eye(4), "table_yaw", q)
