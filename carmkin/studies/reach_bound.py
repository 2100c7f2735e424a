"""A necessary condition for the C-arm and table translations to reach a source position and principal axis.

When :func:`cannot_reach` says so, no configuration within the joint ranges (collisions aside) puts the
source on the target, so the workspace study (:mod:`carmkin.studies.table_workspace`) skips the QP: the
answer is the one the QP would give, found without running it. It decides nothing the other way.

Derivation, in the C-arm base frame K (:attr:`carmkin.CArmSystem.carm_base_pose`; DH rows of
:mod:`carmkin.model.kinematics`: vertical d1 along Z_K, wigwag θ2 about Z_K). With ``c_i = cos θ_i``,
``s_i = sin θ_i``, ``L = l2 + a1`` and ``M = l1 − a2``, the source position p and principal axis a are::

    a = Rz(θ2) (c5 s4, s5, c5 c4)
    p = d1 e_z + Rz(θ2) (X s4, Z + M + d3, X c4),    X = a1 − L c5 − a2 s5,  Z = a2 c5 − L s5

hence, with ``δ = |a1| + |a2|`` (0 for an isocentric C-arm)::

    p_z + L a_z − d1                        = (a1 − a2 s5) c4                    |·| ≤ δ
    p_xy + L a_xy − (M + d3) Rz(θ2) e_y     = Rz(θ2) (a1 s4 − a2 s5 s4, a2 c5)   |·| ≤ δ

so ``p_z + L a_z`` lies within δ of the vertical range and ``p_xy + L a_xy`` within δ of the annular sector
``S = {ρ Rz(θ) e_y : ρ ∈ M + [d3 range], θ ∈ [θ2 range]}``. Free table translations shift the target by
``t(s)``, linear in their values s: the vertical test takes the exact interval of ``t_z`` over the box, the
horizontal one a grid of s, each grid point's test widened by the largest horizontal shift between it and the
box points nearest to it (the distance to S is 1-Lipschitz), so a solution between grid points is never
missed. Lengths in metres, angles in radians.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np

from carmkin.model.params import CARM_JOINT_NAMES
from carmkin.model.system import CArmSystem
from carmkin.transforms import inverse

#: Slack (m) added to every test: covers the IK's tolerances (1e-6 m, 1e-6 rad on a ~1 m lever) many times.
SLACK = 1e-5
#: Grid step (m) of the table translations in the horizontal test, doubled until the grid has at most
#: MAX_GRID points.
GRID_STEP, MAX_GRID = 0.005, 20_000


@functools.lru_cache(maxsize=16)
def _table_shifts(system: CArmSystem, names: tuple[str, ...]) -> np.ndarray | None:
    """(k, 3) shift of a target in frame K per unit value of each named table joint (others at zero), or
    ``None`` when one of them is not a pure translation there."""
    K_inv = inverse(system.carm_base_pose)
    rest = system.fk(np.zeros(system.nq))
    shifts = []
    for name in names:
        i = system.joint_names.index(name)
        if not system.prismatic[i]:
            return None
        q = np.zeros(system.nq)
        q[i] = 1.0
        moved = system.fk(q) @ inverse(rest)  # the source, hence a reachable target, moves by this (frame 0)
        if not np.allclose(moved[:3, :3], np.eye(3), atol=1e-12):
            return None
        shifts.append(K_inv[:3, :3] @ moved[:3, 3])
    return np.array(shifts).reshape(-1, 3)


def _points(length: float, step: float) -> int:
    """Grid points along an axis that moves the target ``length`` (m): steps of at most ``step``."""
    return 1 if length <= step else int(np.ceil(length / step)) + 1


def _distance_to_sector(x: np.ndarray, radii: tuple[float, float], angles: tuple[float, float]) -> np.ndarray:
    """Distance (n,) of points x (n, 2) to ``{ρ (−sin θ, cos θ) : ρ ∈ radii, θ ∈ angles}`` (angles span < π)."""
    r = np.hypot(x[:, 0], x[:, 1])
    phi = np.arctan2(-x[:, 0], x[:, 1])
    inside = (phi >= angles[0]) & (phi <= angles[1])
    radial = np.maximum.reduce([radii[0] - r, r - radii[1], np.zeros_like(r)])
    edges = []
    for theta in angles:  # outside the wedge the nearest point lies on one of its two radial edges
        u = np.array([-np.sin(theta), np.cos(theta)])
        rho = np.clip(x @ u, *radii)
        edges.append(np.hypot(*(x - rho[:, None] * u).T))
    return np.where(inside, radial, np.minimum(*edges))


def cannot_reach(system: CArmSystem, T: np.ndarray, free: Sequence[str]) -> bool:
    """True when no configuration moving only ``free`` joints (others at zero) within their ranges puts the
    source on the position and principal axis (Z) of T (4, 4, table frame 0); False means "cannot tell".

    Says nothing (False) unless every free joint is one of the C-arm's five or a table translation, the
    wigwag range spans less than π and the horizontal arm ``M + d3`` cannot be negative.
    """
    carm = system.carm
    vertical, wigwag, horizontal = (system.joint_ranges[system.joint_names.index(n)] for n in CARM_JOINT_NAMES[:3])
    table = tuple(n for n in system.joint_names if n in free and n not in CARM_JOINT_NAMES)
    shifts = _table_shifts(system, table)
    L, M, delta = carm.source_to_orbital_axis, carm.arm_length, abs(carm.a1) + abs(carm.a2)
    if shifts is None or wigwag.upper - wigwag.lower >= np.pi or M + horizontal.lower < 0:
        return False
    spans = np.array([[system.joint_ranges[system.joint_names.index(n)].lower,
                       system.joint_ranges[system.joint_names.index(n)].upper] for n in table]).reshape(-1, 2)
    target = inverse(system.carm_base_pose) @ T
    centre = target[:3, 3] + L * target[:3, 2]  # p + L a, minus the table shift t(s) = s @ shifts
    # vertical: the exact interval of centre_z - t_z over the box must come within δ of the d1 range
    low = centre[2] - np.maximum(spans[:, 0] * shifts[:, 2], spans[:, 1] * shifts[:, 2]).sum()
    high = centre[2] - np.minimum(spans[:, 0] * shifts[:, 2], spans[:, 1] * shifts[:, 2]).sum()
    if low > vertical.upper + delta + SLACK or high < vertical.lower - delta - SLACK:
        return True
    # horizontal: a grid of s whose steps move the target at most `step` each (coarser for many axes)
    lengths = (spans[:, 1] - spans[:, 0]) * np.hypot(shifts[:, 0], shifts[:, 1])
    step = GRID_STEP
    while np.prod([_points(length, step) for length in lengths]) > MAX_GRID:
        step *= 2.0
    axes, reach = [], 0.0
    for k, length in enumerate(lengths):
        n = _points(length, step)
        axes.append(np.linspace(spans[k, 0], spans[k, 1], n) if n > 1 else spans[k].mean(keepdims=True))
        reach += 0.5 * length / max(n - 1, 1)
    s = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(table)) if axes else np.zeros((1, 0))
    points = centre[None, :2] - s @ shifts[:, :2]
    radii = (M + horizontal.lower, M + horizontal.upper)
    distance = _distance_to_sector(points, radii, (wigwag.lower, wigwag.upper))
    return bool(distance.min() > delta + reach + SLACK)
