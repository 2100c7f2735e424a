"""Validity of a C-arm configuration (§4.4.3): joint ranges, collisions, table inside the X-ray cone.

A configuration is invalid when a joint leaves its mechanical range, when a C-arm part intersects the table
top (or an obstacle, or the floor), or when the table is not within the X-ray cone beam. Following §4.4.3,
the table is "within the cone" when the principal axis meets the table-top box; here the axis is taken as
the segment from the source centre to the detector plane (the beam does not extend past the detector).
Collisions use the oriented boxes of the collision model with coal (the dissertation used the separating
axis test on the same OBBs) and the pair list of :mod:`carmkin.robot.collision`. Lengths in metres, angles in
radians, all in the table frame 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from carmkin.errors import InvalidConfigurationError
from carmkin.transforms import segment_hits_box
from carmkin.validation import JOINT_VALUE_LIMIT, real_array, real_scalar

from .collision import CollisionScene, Obstacle, link_of
from .state import KinematicState


@dataclass(frozen=True)
class JointViolation:
    """Joint ``name`` at ``value`` is outside its range by ``excess`` (< 0 below lower, > 0 above upper);
    m for a ``prismatic`` joint, rad otherwise."""

    name: str
    value: float
    excess: float
    prismatic: bool = False

    def __str__(self) -> str:
        scale, unit = (1e3, "mm") if self.prismatic else (np.degrees(1.0), "°")
        return (f"joint {self.name} out of range by {self.excess * scale:+.4g} {unit} "
                f"(value {self.value * scale:.6g} {unit})")


@dataclass(frozen=True)
class Contact:
    """Geometries ``first``/``second`` (links ``links``) closer than the margin: signed ``distance`` (m)."""

    first: str
    second: str
    distance: float

    @property
    def links(self) -> tuple[str, str]:
        return link_of(self.first), link_of(self.second)

    def __str__(self) -> str:
        a, b = self.links
        how = "intersects" if self.distance < 0 else "is within the margin of"
        return f"{a} {how} {b} ({self.first}/{self.second}, distance {self.distance * 1e3:.3g} mm)"


#: Rendered when the principal axis misses the table top.
NOT_IN_CONE = "table not in the X-ray cone (principal axis misses the table top)"


@dataclass(frozen=True)
class ValidityReport:
    """Every violated condition of one configuration.

    Attributes:
        joints: joints out of range. collisions: pairs with distance < ``margin`` (intersecting when
        ``margin`` = 0). table_in_cone: whether the principal axis meets the table-top box.
        min_distance: smallest signed distance over the pairs (m). margin: the margin used (m).
    """

    q: np.ndarray
    joints: tuple[JointViolation, ...]
    collisions: tuple[Contact, ...]
    table_in_cone: bool
    min_distance: float
    margin: float = 0.0

    @property
    def valid(self) -> bool:
        """True when no condition is violated (joints in range, no collision, table in the cone)."""
        return not self.joints and not self.collisions and self.table_in_cone

    @property
    def reachable(self) -> bool:
        """Joints in range and no collision: valid as a pose of the machine, whatever the beam sees."""
        return not self.joints and not self.collisions

    @property
    def reasons(self) -> tuple[str, ...]:
        """Every violated condition as a sentence for people (mm and degrees), rendered from the fields;
        empty when valid. Read the fields, never parse these."""
        out = tuple(str(j) for j in self.joints) + tuple(str(c) for c in self.collisions)
        return out if self.table_in_cone else out + (NOT_IN_CONE,)

    def __str__(self) -> str:
        return "valid" if self.valid else "; ".join(self.reasons)


def pose_in_cone(system, T) -> bool:
    """Whether the principal axis of the source pose ``T`` (4, 4, frame 0), from the source centre to the
    detector plane, meets the table-top box. It depends on the pose alone, not on the joints reaching it."""
    source = T[:3, 3]
    detector = source + system.carm.source_to_detector * T[:3, 2]
    return segment_hits_box(source, detector, system.table.top_center, system.table.top_size)


def table_in_cone(system, q) -> bool:
    """Whether the principal axis (source centre to detector plane) meets the table-top box (frame 0)."""
    return pose_in_cone(system, system.fk(q))


def check(
    system,
    q,
    obstacles: Sequence[Obstacle] = (),
    margin: float = 0.0,
    scene: CollisionScene | None = None,
    state: KinematicState | None = None,
) -> ValidityReport:
    """Report every violated condition of configuration ``q`` (nq,) of ``system``.

    ``margin`` (m): pairs closer than it count as collisions (0 = only intersecting pairs). Pass a
    prebuilt ``scene`` (from :meth:`CollisionScene.from_system`, holding the obstacles) to avoid
    rebuilding it per call; ``obstacles`` and ``scene`` together are an error. ``state``: the
    :class:`~carmkin.robot.state.KinematicState` of ``q`` with that scene, when the caller has it already
    (one forward-kinematics pass per configuration).
    """
    model = system.pinocchio()[0]
    q = real_array(q, "q", (model.nq,), error=InvalidConfigurationError, limit=JOINT_VALUE_LIMIT, unit="m, rad")
    margin = real_scalar(margin, "margin", error=InvalidConfigurationError, low=0.0, unit="m")
    if scene is not None and obstacles:
        raise InvalidConfigurationError("give the obstacles either in the scene or as obstacles, not both")
    if state is None:
        scene = scene if scene is not None else CollisionScene.from_system(system, obstacles)
        state = KinematicState(model, q, scene)
    elif not np.array_equal(state.q, q):
        raise InvalidConfigurationError("the kinematic state given to check() belongs to another configuration")
    scene = state.scene
    joints = tuple(
        JointViolation(r.name if r.name != "joint" else n, float(v), float(r.excess(v)), bool(p))
        for n, r, v, p in zip(system.joint_names, system.joint_ranges, q, system.prismatic)
        if r.excess(v) != 0.0
    )
    distances = state.distances
    collisions = tuple(
        Contact(scene.pairs[k][0], scene.pairs[k][1], float(distances[k])) for k in np.flatnonzero(distances < margin)
    )
    return ValidityReport(
        q=q,
        joints=joints,
        collisions=collisions,
        table_in_cone=pose_in_cone(system, state.source_pose),
        min_distance=state.min_distance,
        margin=float(margin),
    )
