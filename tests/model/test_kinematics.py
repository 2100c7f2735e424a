"""Closed-form kinematics: rigid outputs, batch = scalar, Pinocchio = closed form = yourdfpy."""

from __future__ import annotations

import io
import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from strategies import PRESET, configurations, finite, poses, systems

import carmkin
from carmkin.model.bounds import NEAR_PARALLEL_SIN, PARALLEL_AXES_SIN
from carmkin.model.params import JOINT_RANGE_TOLERANCE
from carmkin.robot.verify import (
    FRAMES,
    closed_form_frames,
    pinocchio_frames,
)
from carmkin.transforms import inverse, rotation_angle

TOL = 1e-12


@given(systems(), st.data())
def test_fk_is_a_rigid_transform(system, data):
    T = system.fk(data.draw(configurations(system, beyond=0.5)))
    R = T[:3, :3]
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-14)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)
    assert np.array_equal(T[3], [0, 0, 0, 1])


@given(systems(), st.lists(configurations(beyond=0.5), min_size=1, max_size=8))
def test_batch_equals_scalar(system, qs):
    batch = system.fk(np.array(qs))
    assert batch.shape == (len(qs), 4, 4)
    for q, T in zip(qs, batch):
        assert np.abs(system.fk(q) - T).max() <= 1e-15


@settings(max_examples=40)
@given(systems(), st.lists(configurations(beyond=0.5), min_size=1, max_size=20))
def test_closed_form_equals_pinocchio(system, qs):
    q = np.array(qs)
    a, b = closed_form_frames(system, q), pinocchio_frames(system, q)
    assert np.linalg.norm(a[..., :3, 3] - b[..., :3, 3], axis=-1).max() <= TOL
    assert rotation_angle(a[..., :3, :3], b[..., :3, :3]).max() <= TOL


def _yourdfpy_pose(robot, q, frame: str, root: str = "table") -> np.ndarray:
    """Pose of ``frame`` in ``root`` composed from yourdfpy's parsed joints and its joint transforms.

    The chain is walked by hand because trimesh's scene graph (behind ``get_transform``) skips updates
    smaller than its tolerance (~1e-8), which would hide errors at the 1e-12 level.
    """
    values = dict(zip(robot.actuated_joint_names, q))
    parent_joint = {j.child: j for j in robot.robot.joints}
    T = np.eye(4)
    while frame != root:
        joint = parent_joint[frame]
        matrix, _ = robot._forward_kinematics_joint(joint, q=float(values.get(joint.name, 0.0)))
        T = matrix @ T
        frame = joint.parent
    return T


@settings(max_examples=15)
@given(systems(), st.lists(configurations(beyond=0.5), min_size=1, max_size=5))
def test_yourdfpy_agrees_with_closed_form(system, qs):
    import yourdfpy

    robot = yourdfpy.URDF.load(io.StringIO(system.urdf()), load_meshes=False, build_collision_scene_graph=False)
    assert tuple(robot.actuated_joint_names) == carmkin.JOINT_NAMES
    for q in qs:
        assert np.abs(_yourdfpy_pose(robot, q, "xray_source") - system.fk(q)).max() <= TOL
    robot.update_cfg(qs[0])  # the public API agrees too, within trimesh's tolerance
    assert np.abs(robot.get_transform("xray_source", "table") - system.fk(qs[0])).max() <= 1e-7


@given(poses())
def test_table_setup_from_pose_round_trips(T_base_table):
    sin_gamma1 = math.hypot(T_base_table[0, 2], T_base_table[1, 2])
    assume(not PARALLEL_AXES_SIN < sin_gamma1 < NEAR_PARALLEL_SIN)  # refused: tests/test_presets.py
    setup = carmkin.TableSetup.from_pose(T_base_table)
    system = PRESET.replace(setup=setup)
    # At d0 = d1 = 0 frame 2 of the chain is the C-arm base frame: 0T2 = (T_base_table)^-1.
    T_table_base = system.dh_frames(np.zeros(6))[1]
    scale = max(1.0, abs(setup.D1), abs(setup.D2), abs(setup.D3))  # D2, D3 ~ 1/sin(gamma1) near case (a)
    assert np.abs(inverse(T_table_base) - T_base_table).max() <= 1e-12 * scale


def test_from_pose_parallel_axes_uses_the_normal_through_the_table_origin():
    T = np.eye(4)
    T[:3, 3] = (0.3, -0.4, 0.7)  # Z0 parallel to the vertical axis (singular case a)
    setup = carmkin.TableSetup.from_pose(T)
    assert setup.gamma1 == 0.0 and setup.D1 == pytest.approx(0.5) and setup.D2 == 0.0
    T_table_base = PRESET.replace(setup=setup).dh_frames(np.zeros(6))[1]
    assert np.abs(inverse(T_table_base) - T).max() <= 1e-12


def test_preset_setup_matches_section_4_6_1():
    """Table frame at the isocentre, Z0 along X_xray, X0 opposite to Y_xray, at zero joints (§4.6.1)."""
    T = PRESET.fk(np.zeros(6))
    assert np.allclose(T[:3, 0], [0, 0, 1], atol=1e-15)  # X_xray = Z0
    assert np.allclose(T[:3, 1], [-1, 0, 0], atol=1e-15)  # Y_xray = -X0
    l2 = PRESET.carm.orbital_offset
    assert np.allclose(T[:3, :3] @ [0, 0, l2] + T[:3, 3], 0, atol=1e-15)  # isocentre at the origin


def test_frames_compared_by_verify_exist_in_the_urdf():
    model = PRESET.pinocchio()[0]
    for name in FRAMES:
        assert model.existFrame(name), name
    assert [model.names[i] for i in range(1, model.njoints)] == list(carmkin.JOINT_NAMES)


def test_urdf_limits_come_from_the_system():
    model = PRESET.pinocchio()[0]
    assert np.allclose(model.lowerPositionLimit, PRESET.lower)
    assert np.allclose(model.upperPositionLimit, PRESET.upper)


def test_detector_frame_is_on_the_principal_axis():
    model = PRESET.pinocchio()[0]
    data = model.createData()
    q = np.array([0.1, 0.2, 0.1, 0.05, 0.4, -0.3])
    pin.framesForwardKinematics(model, data, q)
    source = data.oMf[model.getFrameId("xray_source")]
    detector = data.oMf[model.getFrameId("detector")]
    offset = source.actInv(detector.translation)
    assert np.allclose(offset, [0, 0, PRESET.carm.source_to_detector], atol=1e-14)


@given(systems(), st.lists(configurations(beyond=0.5), min_size=1, max_size=10))
def test_expanded_closed_form_equals_the_dh_product_and_pinocchio(system, qs):
    q = np.array(qs)
    dh_product = system.dh_frames(q)[:, -1] @ system.xray_in_flange
    assert np.abs(system.fk(q) - dh_product).max() <= 1e-14
    pinocchio_source = pinocchio_frames(system, q)[:, FRAMES.index("xray_source")]
    assert np.abs(system.fk(q) - pinocchio_source).max() <= TOL


# --- derived lengths, the joint-range tolerance, the per-system caches ------------------------------------------
@given(systems())
def test_derived_lengths_are_those_of_the_dh_rows(system):
    carm = system.carm
    assert carm.source_to_orbital_axis == carm.orbital_offset + carm.a1
    assert carm.arm_length == carm.length_offset - carm.a2
    rows = system.dh_table
    assert rows[3].d == carm.arm_length and rows[5].a == -carm.source_to_orbital_axis
    assert (system.closed_form.L, system.closed_form.M) == (carm.source_to_orbital_axis, carm.arm_length)


@given(st.floats(-1.0, 1.0, **finite), st.floats(0.0, 1.0, **finite),
       st.floats(-3 * JOINT_RANGE_TOLERANCE, 3 * JOINT_RANGE_TOLERANCE, **finite))
def test_a_value_on_a_limit_up_to_the_tolerance_is_in_range(lower, width, offset):
    r = carmkin.JointRange(lower, lower + width)
    for limit, sign in ((r.lower, -1.0), (r.upper, 1.0)):
        value = limit + sign * abs(offset)
        inside = abs(offset) <= JOINT_RANGE_TOLERANCE
        assert bool(r.contains(value)) == inside
        assert (r.excess(value) == 0.0) == inside
        if not inside:  # the excess is the true distance beyond the limit, not beyond the widened one
            assert float(r.excess(value)) == pytest.approx(value - limit, abs=1e-18)


def test_solvers_are_cached_per_system_without_writing_into_it():
    from carmkin import analytic_ik
    from carmkin.analytic import dls

    system = PRESET.replace(name="cache test")
    before = set(vars(system))
    assert analytic_ik.solver_for(system) is analytic_ik.solver_for(system)
    assert dls.solver_for(system) is dls.solver_for(system)
    assert not {k for k in set(vars(system)) - before if "solver" in k}
    key = id(system)
    assert key in analytic_ik.solver_for.cache
    del system
    import gc

    gc.collect()
    assert key not in analytic_ik.solver_for.cache and key not in dls.solver_for.cache
