"""Hypothesis strategies shared by the tests: random C-arm geometries (non-isocentric), table setups,
systems and configurations (SI units)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st

import carmkin
from carmkin.model.params import PRISMATIC

PRESET = carmkin.load_preset("siremobile-iso-c3d")

finite = dict(allow_nan=False, allow_infinity=False)


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
def configurations(draw, system: carmkin.CArmSystem | None = None, beyond: float = 0.0) -> np.ndarray:
    """Joint vectors (6,) inside the ranges of ``system`` (default: the preset), widened by ``beyond`` of
    each span on both sides."""
    system = system or PRESET
    q = []
    for joint_range, prismatic in zip(system.joint_ranges, PRISMATIC):
        span = joint_range.upper - joint_range.lower
        q.append(draw(st.floats(joint_range.lower - beyond * span, joint_range.upper + beyond * span, **finite)))
    return np.array(q)
