"""Targets: the task of each target kind and the full pose handed to the closed forms (least rotation from
the reference source pose, roll kept)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import PRESET

from carmkin import qp_ik
from carmkin.qp.tasks import AimTask, AxisTask, PoseTask
from carmkin.qp.targets import AimTarget, AxisTarget, make_task
from carmkin.qp_ik import QPIKError

MODEL = PRESET.pinocchio()[0]
unit6 = st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6).map(np.array)


def test_make_task_by_target_kind():
    T = PRESET.fk(0.5 * (PRESET.lower + PRESET.upper))
    assert isinstance(make_task(MODEL, T), PoseTask)
    assert isinstance(make_task(MODEL, AxisTarget(T[:3, 3], T[:3, 2])), AxisTask)
    assert isinstance(make_task(MODEL, AimTarget(T[:3, 3] + T[:3, 2], (0.5, 1.5))), AimTask)
    with pytest.raises(QPIKError, match="4x4 pose"):
        make_task(MODEL, np.eye(3))


@settings(max_examples=20, deadline=None)
@given(unit6, unit6)
def test_closed_form_pose_of_a_pose_is_the_pose(u, v):
    T = PRESET.fk(PRESET.lower + u * (PRESET.upper - PRESET.lower))
    T_ref = PRESET.fk(PRESET.lower + v * (PRESET.upper - PRESET.lower))
    assert np.array_equal(qp_ik.closed_form_pose(T, T_ref), T)


@settings(max_examples=20, deadline=None)
@given(unit6, st.floats(0.3, 0.9))
def test_closed_form_pose_of_axis_and_aim_targets(u, distance):
    """The full pose handed to the closed form meets the 5-DOF/aim target and keeps q_current's roll."""
    q = PRESET.lower + u * (PRESET.upper - PRESET.lower)
    T_ref = PRESET.fk(q)
    T = PRESET.fk(np.clip(q + 0.1, PRESET.lower, PRESET.upper))
    axis = qp_ik.closed_form_pose(AxisTarget(T[:3, 3], T[:3, 2]), T_ref)
    assert np.allclose(axis[:3, 3], T[:3, 3]) and np.allclose(axis[:3, 2], T[:3, 2])
    # the least rotation taking the reference beam onto the target beam: its axis is normal to both
    delta = pin.log3(T_ref[:3, :3].T @ axis[:3, :3])
    assert abs((T_ref[:3, :3] @ delta) @ T_ref[:3, 2]) < 1e-9
    point = T[:3, 3] + distance * T[:3, 2]
    aim = qp_ik.closed_form_pose(AimTarget(point, (0.3, 0.9)), T_ref)
    w = point - aim[:3, 3]
    assert np.linalg.norm(w - (w @ aim[:3, 2]) * aim[:3, 2]) < 1e-9 and 0.3 - 1e-9 <= w @ aim[:3, 2] <= 0.9 + 1e-9


