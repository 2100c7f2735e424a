"""Multi-DOF operating tables: the model, its URDF and Pinocchio agree; joint motions mean what they say."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import PRESET, configurations, finite, motorized_systems

import carmkin
from carmkin import InvalidParameterError, JointRange
from carmkin.model.table_joints import CHAIN_ORDER, TableJoint, standard_joints
from carmkin.robot.verify import (
    FRAMES,
    closed_form_frames,
    pinocchio_frames,
)
from carmkin.transforms import rotation_angle

MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")


def _q(system, **values) -> np.ndarray:
    q = np.zeros(system.nq)
    for name, value in values.items():
        q[system.joint_names.index(name)] = value
    return q


@st.composite
def table_configurations(draw, system=MOTORIZED) -> np.ndarray:
    return np.array([draw(st.floats(r.lower - 0.2, r.upper + 0.2, **finite)) for r in system.joint_ranges])


def test_motorized_preset_has_the_five_extra_joints_in_chain_order():
    assert MOTORIZED.nq == 11
    assert MOTORIZED.joint_names == ("table_translation",) + tuple(reversed(CHAIN_ORDER)) + carmkin.JOINT_NAMES[1:]
    model = MOTORIZED.pinocchio()[0]
    assert [model.names[i] for i in range(1, model.njoints)] == list(MOTORIZED.joint_names)
    assert np.allclose(model.lowerPositionLimit, MOTORIZED.lower) and np.allclose(model.upperPositionLimit, MOTORIZED.upper)


@settings(max_examples=40)
@given(st.lists(table_configurations(), min_size=1, max_size=10))
def test_closed_form_equals_pinocchio_with_table_joints(qs):
    q = np.array(qs)
    a, b = closed_form_frames(MOTORIZED, q), pinocchio_frames(MOTORIZED, q)
    assert np.linalg.norm(a[..., :3, 3] - b[..., :3, 3], axis=-1).max() <= 1e-12
    assert rotation_angle(a[..., :3, :3], b[..., :3, :3]).max() <= 1e-12
    assert np.abs(MOTORIZED.fk(q) - np.array([MOTORIZED.fk(qk) for qk in q])).max() <= 1e-15


@settings(max_examples=15)
@given(st.data())
def test_closed_form_equals_pinocchio_for_random_motorized_tables(data):
    """Random extra table joints (0–5; random axes, pivots, ranges) on random non-isocentric systems."""
    system = data.draw(motorized_systems())
    q = np.array(data.draw(st.lists(configurations(system, beyond=0.2), min_size=1, max_size=5)))
    assert q.shape[1] == system.nq == 6 + len(system.table.joints)
    a, b = closed_form_frames(system, q), pinocchio_frames(system, q)
    assert np.linalg.norm(a[..., :3, 3] - b[..., :3, 3], axis=-1).max() <= 1e-12
    assert rotation_angle(a[..., :3, :3], b[..., :3, :3]).max() <= 1e-12


@given(table_configurations())
def test_with_table_joints_at_zero_the_chain_is_the_papers(q):
    k = len(MOTORIZED.table.joints)
    q[1:1 + k] = 0.0
    q6 = np.concatenate((q[:1], q[1 + k:]))
    assert np.abs(MOTORIZED.fk(q) - PRESET.fk(q6)).max() <= 1e-15


def _floor_in_table(system, q) -> pin.SE3:
    model = system.pinocchio()[0]
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[model.getFrameId("table_reference")]


def test_height_and_lateral_move_the_table_top_relative_to_the_floor():
    up = np.array([0.0, -1.0, 0.0])
    rest = _floor_in_table(MOTORIZED, _q(MOTORIZED)).translation
    raised = _floor_in_table(MOTORIZED, _q(MOTORIZED, table_height=0.1)).translation
    assert np.allclose(raised - rest, -0.1 * up, atol=1e-15)  # the floor drops by 0.1 m as seen from the top
    slid = _floor_in_table(MOTORIZED, _q(MOTORIZED, table_lateral=0.05)).translation
    assert np.allclose(slid - rest, [-0.05, 0, 0], atol=1e-15)


@pytest.mark.parametrize("name, axis", [("table_tilt", [0, 0, 1]), ("table_trendelenburg", [1, 0, 0]),
                                        ("table_rotation", [0, -1, 0])])
def test_rotations_turn_the_top_about_their_axis_through_the_pivot(name, axis):
    placement = _floor_in_table(MOTORIZED, _q(MOTORIZED, **{name: 0.2}))
    top_in_floor = placement.inverse()
    assert np.allclose(pin.log3(top_in_floor.rotation), 0.2 * np.array(axis, float), atol=1e-14)
    pivot = np.array(MOTORIZED.table.joints[0].point)
    assert np.allclose(top_in_floor.act(pivot), pivot, atol=1e-14)  # the pivot does not move


def test_table_joint_validation():
    with pytest.raises(InvalidParameterError, match="unknown table joint"):
        standard_joints({"table_yaw": JointRange(-1, 1)}, up=(0, 1, 0), pivot=(0, 0, 0))
    with pytest.raises(InvalidParameterError, match="unit"):
        TableJoint("table_height", True, (0, 2, 0), (0, 0, 0), JointRange(-1, 1))
    with pytest.raises(InvalidParameterError, match="lower limit"):
        JointRange(0.3, -0.3, "table_tilt")


def test_verify_passes_on_the_motorized_preset():
    from carmkin.robot.verify import verify

    report = verify(MOTORIZED, samples=2000, random_setups=5, seed=3)
    assert report.worst <= 1e-12
    assert set(report.position_error) == set(FRAMES)


def _pinocchio_source(system, q) -> np.ndarray:
    """The independent oracle: Pinocchio's placement of ``xray_source`` (4, 4) from the generated URDF."""
    model = system.pinocchio()[0]
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
    return data.oMf[model.getFrameId("xray_source")].homogeneous


def _axis_aligned(joints):
    """The same joints with each axis rounded to its largest coordinate axis (±e_i exactly): the scalar FK's
    two-row rotation branch; random axes take its general branch."""
    from dataclasses import replace

    out = []
    for joint in joints:
        i = int(np.argmax(np.abs(joint.axis)))
        out.append(replace(joint, axis=tuple(float(np.sign(joint.axis[i])) if k == i else 0.0 for k in range(3))))
    return tuple(out)


@settings(max_examples=30)
@given(st.data())
def test_scalar_fk_equals_pinocchio_for_random_tables_both_branches(data):
    """The scalar path of system.fk (plain floats, table motion composed in front) against Pinocchio to 1e-12,
    for random axes (general rotation) and the same axes snapped to coordinate axes (two rows turn)."""
    from dataclasses import replace

    system = data.draw(motorized_systems(min_joints=1))
    for candidate in (system, system.replace(table=replace(system.table, joints=_axis_aligned(system.table.joints)))):
        q = data.draw(configurations(candidate, beyond=0.2))
        T, oracle = candidate.fk(q), _pinocchio_source(candidate, q)
        assert T.shape == (4, 4) and T.dtype == np.float64
        assert np.linalg.norm(T[:3, 3] - oracle[:3, 3]) <= 1e-12
        assert rotation_angle(T[:3, :3], oracle[:3, :3]) <= 1e-12
        assert np.array_equal(T[3], [0.0, 0.0, 0.0, 1.0])
        # the same configuration as a list of floats takes the same path; as a batch of one, the array path
        assert np.array_equal(candidate.fk(q.tolist()), T)
        assert np.abs(candidate.fk(q[None])[0] - T).max() <= 1e-15


@pytest.mark.parametrize("system", [PRESET, MOTORIZED], ids=["preset", "motorized"])
def test_scalar_fk_refuses_what_the_checked_path_refuses(system):
    """Anything but plain finite floats leaves the fast path and gets the one configuration check."""
    q = 0.5 * (system.lower + system.upper)
    assert np.array_equal(system.fk(q.astype(np.float32)), system.fk(q.astype(np.float32).astype(float)))
    assert np.array_equal(system.fk([0] * system.nq), system.fk(np.zeros(system.nq)))  # ints are numbers
    for bad in (np.r_[q[:-1], np.nan], np.r_[q[:-1], np.inf], np.r_[q[:-1], 1e200], q[:-1], [True] * system.nq,
                list(q[:-1]) + [float("nan")], tuple(q) + (0.0,)):
        with pytest.raises(carmkin.InvalidConfigurationError, match="q"):
            system.fk(bad)


def test_scalar_fk_takes_a_nearly_coordinate_axis_as_any_axis():
    """A unit axis whose largest component rounds to 1.0 beside a tiny one (found by hypothesis) is not a
    coordinate axis: dropping its 2e-10 component moved the source by 1e-10 m."""
    from dataclasses import replace

    joint = TableJoint("table_height", False, (0.0, 1.0, 2.253846257937214e-10), (0.0, 0.0, 0.0),
                       JointRange(-0.5, 0.0, "table_height"))
    system = PRESET.replace(table=replace(PRESET.table, joints=(joint,)))
    q = np.array([0.0, -0.5, 0.0, 0.0, 0.0, 0.0, 0.0])
    T, oracle = system.fk(q), _pinocchio_source(system, q)
    assert np.linalg.norm(T[:3, 3] - oracle[:3, 3]) <= 1e-12
    assert rotation_angle(T[:3, :3], oracle[:3, :3]) <= 1e-12
