"""Random systems and configurations for cross-checks and studies (numpy Generators, SI units).

The hypothesis strategies of the tests draw the same kinds of values; this module serves the CLI
(``carmkin verify --random-setups``) and benchmarks, which need plain seeded numpy sampling.
"""

from __future__ import annotations

import numpy as np

from carmkin.transforms import check_rigid_transform

from .params import CArmGeometry, TableSetup
from .system import CArmSystem


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly distributed rotation matrix (3, 3) (QR of a Gaussian matrix, sign-fixed)."""
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q * np.sign(np.diag(R))
    if np.linalg.det(Q) < 0:
        Q[:, 0] = -Q[:, 0]
    return Q


def random_pose(rng: np.random.Generator, radius: float = 2.0) -> np.ndarray:
    """A random rigid transform with its origin in a cube of half-side ``radius`` (m)."""
    T = np.eye(4)
    T[:3, :3] = random_rotation(rng)
    T[:3, 3] = rng.uniform(-radius, radius, 3)
    return check_rigid_transform(T)


def random_geometry(rng: np.random.Generator, base: CArmGeometry) -> CArmGeometry:
    """``base`` with random, generally non-isocentric offsets: l1, l2 scaled by 0.5–1.5, a1, a2 in ±0.2 m."""
    from dataclasses import replace

    return replace(
        base,
        length_offset=base.length_offset * rng.uniform(0.5, 1.5),
        orbital_offset=base.orbital_offset * rng.uniform(0.5, 1.5),
        a1=rng.uniform(-0.2, 0.2),
        a2=rng.uniform(-0.2, 0.2),
    )


def random_system(rng: np.random.Generator, base: CArmSystem) -> CArmSystem:
    """``base`` with a random non-isocentric geometry and a random table pose (eq. 4.3 construction)."""
    return base.replace(carm=random_geometry(rng, base.carm), setup=TableSetup.from_pose(random_pose(rng)))


#: Width (m or rad) a locked joint's range counts for in :func:`random_configurations`, so that samples beyond
#: the limits still move it (the chain is checked there too).
LOCKED_SPAN = 0.2


def random_configurations(rng: np.random.Generator, system: CArmSystem, n: int, beyond: float = 0.25) -> np.ndarray:
    """``n`` configurations (n, nq) uniform over the joint ranges widened by ``beyond`` of their span each side.

    Revolute joints are drawn over at least a full turn so that every angle is exercised; a locked joint
    (range of zero width, e.g. an angiography stand's vertical travel) counts as :data:`LOCKED_SPAN` wide.
    """
    lower, upper = system.lower, system.upper
    span = np.maximum(upper - lower, LOCKED_SPAN)  # a locked joint (min = max) is still exercised beyond it
    lower, upper = lower - beyond * span, upper + beyond * span
    revolute = ~np.array(system.prismatic)
    lower = np.where(revolute, np.minimum(lower, -np.pi), lower)
    upper = np.where(revolute, np.maximum(upper, np.pi), upper)
    return rng.uniform(lower, upper, size=(n, system.nq))
