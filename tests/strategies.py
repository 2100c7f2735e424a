"""Hypothesis strategies shared by the tests: random C-arm geometries (non-isocentric), table setups,
motorized tables (random extra table joints, axes, pivots, ranges), systems and configurations for any
number of joints (SI units)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st

import carmkin
from carmkin.model.table_joints import CHAIN_ORDER, TableJoint

PRESET = carmkin.load_preset("siremobile-iso-c3d")

finite = dict(allow_nan=False, allow_infinity=False)

#: The KR 210 R3100-2 as ROS-Industrial publishes it (kr210_r3100-2_macro.xacro): each joint's axis and a point
#: of it (mm) in the robot base frame with every joint at the URDF's zero, and its limits (deg).
KR210 = [((0, 0, -1), (0, 0, 645), (-185, 185)), ((0, 1, 0), (330, 0, 645), (-140, -5)),
         ((0, 1, 0), (1680, 0, 645), (-120, 168)), ((-1, 0, 0), (3100, 0, 760), (-350, 350)),
         ((0, 1, 0), (3100, 0, 760), (-122.5, 122.5)), ((-1, 0, 0), (3340, 0, 760), (-350, 350))]
#: The robotic-carm preset's rest pose in the URDF's angles (deg, docs/PRESETS.md): the elbow folded up, the
#: flange level. The preset's joint values are the URDF's less these.
KR210_REST_DEG = (0.0, -118.69335120549698, 149.53378067020924, 0.0, -30.84042946471225, 0.0)


@st.composite
def rotations(draw) -> np.ndarray:
    """Uniform-ish rotation matrices from a unit quaternion."""
    w, x, y, z = (draw(st.floats(-1, 1, **finite)) for _ in range(4))
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if n < 1e-3:
        w, x, y, z, n = 1.0, 0.0, 0.0, 0.0, 1.0
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


@st.composite
def poses(draw, radius: float = 2.0) -> np.ndarray:
    """Rigid transforms with the origin in a cube of half-side ``radius`` (m)."""
    T = np.eye(4)
    T[:3, :3] = draw(rotations())
    T[:3, 3] = [draw(st.floats(-radius, radius, **finite)) for _ in range(3)]
    return T


@st.composite
def geometries(draw, isocentric: bool = False) -> carmkin.CArmGeometry:
    """C-arm geometries with l1 in [0.5, 2] m, l2 in [0.3, 1] m and, unless isocentric, a1, a2 in ±0.25 m."""
    from dataclasses import replace

    offsets = st.just(0.0) if isocentric else st.floats(-0.25, 0.25, **finite)
    return replace(
        PRESET.carm,
        length_offset=draw(st.floats(0.5, 2.0, **finite)),
        orbital_offset=draw(st.floats(0.3, 1.0, **finite)),
        a1=draw(offsets),
        a2=draw(offsets),
    )


@st.composite
def setups(draw, min_sin_gamma1: float = 0.05) -> carmkin.TableSetup:
    """Table setups built from random table poses by the common-normal construction (eq. 4.3).

    Poses whose table axis is within ``asin(min_sin_gamma1)`` of parallel to the vertical axis are
    rejected: near singular case (a) the common normal runs off to infinity (D2, D3 ~ 1/sin γ1), which is
    no physical setup and makes absolute tolerances meaningless.
    """
    T = draw(poses())
    assume(math.hypot(T[0, 2], T[1, 2]) >= min_sin_gamma1)  # |Z0 x Z1| = |sin γ1|, Z1 = base Z
    return carmkin.TableSetup.from_pose(T)


@st.composite
def systems(draw, isocentric: bool = False) -> carmkin.CArmSystem:
    """Systems with a random geometry and table setup (the preset's limits and bodies)."""
    return PRESET.replace(carm=draw(geometries(isocentric)), setup=draw(setups()))


@st.composite
def unit_vectors(draw) -> np.ndarray:
    """Unit 3-vectors (direction roughly uniform)."""
    v = np.array([draw(st.floats(-1, 1, **finite)) for _ in range(3)])
    n = float(np.linalg.norm(v))
    assume(n > 1e-2)
    return v / n


@st.composite
def table_joints(draw, min_joints: int = 0, max_joints: int = 5) -> tuple[TableJoint, ...]:
    """Extra joints of a motorized table, ordered from the top down: a random subset of the names of
    :data:`~carmkin.model.table_joints.CHAIN_ORDER`, each prismatic or revolute about a random unit axis
    through a random pivot (±0.5 m, frame 0), with a range containing 0 (up to ±0.3 m or ±0.6 rad)."""
    names = draw(st.lists(st.sampled_from(CHAIN_ORDER), unique=True, min_size=min_joints, max_size=max_joints))
    joints = []
    for name in (n for n in CHAIN_ORDER if n in names):  # from the floor up
        prismatic = draw(st.booleans())
        reach = 0.3 if prismatic else 0.6
        span = carmkin.JointRange(-draw(st.floats(0.0, reach, **finite)), draw(st.floats(0.0, reach, **finite)), name)
        point = tuple(draw(st.floats(-0.5, 0.5, **finite)) for _ in range(3))
        joints.append(TableJoint(name, prismatic, tuple(draw(unit_vectors())), point, span))
    return tuple(reversed(joints))


@st.composite
def motorized_systems(draw, min_joints: int = 0, max_joints: int = 5, isocentric: bool = False) -> carmkin.CArmSystem:
    """:func:`systems` with 0–5 random extra table joints (:func:`table_joints`): nq from 6 to 11."""
    from dataclasses import replace

    system = draw(systems(isocentric))
    return system.replace(table=replace(system.table, joints=draw(table_joints(min_joints, max_joints))))


@st.composite
def configurations(draw, system: carmkin.CArmSystem | None = None, beyond: float = 0.0) -> np.ndarray:
    """Joint vectors (nq,) inside the ranges of ``system`` (default: the preset), widened by ``beyond`` of
    each span on both sides; any number of joints."""
    system = system or PRESET
    q = []
    for joint_range in system.joint_ranges:
        span = joint_range.upper - joint_range.lower
        q.append(draw(st.floats(joint_range.lower - beyond * span, joint_range.upper + beyond * span, **finite)))
    return np.array(q)


@st.composite
def configurations_on_limits(draw, system: carmkin.CArmSystem | None = None) -> np.ndarray:
    """Joint vectors (nq,) in range with every joint exactly on its lower or upper limit or at a value
    inside, and at least one joint on a limit (issue 13: a value on a limit is in range)."""
    system = system or PRESET
    q = []
    for r in system.joint_ranges:
        q.append(draw(st.sampled_from((r.lower, r.upper)) | st.floats(r.lower, r.upper, **finite)))
    on_limit = [v in (r.lower, r.upper) for v, r in zip(q, system.joint_ranges)]
    if not any(on_limit):
        k = draw(st.integers(0, system.nq - 1))
        r = system.joint_ranges[k]
        q[k] = draw(st.sampled_from((r.lower, r.upper)))
    return np.array(q)
