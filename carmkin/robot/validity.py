"""Validity of a C-arm configuration (§4.4.3): joint ranges, collisions, table inside the X-ray cone.

A configuration is invalid when a joint leaves its mechanical range, when a C-arm part intersects the table
top (or an obstacle, or the floor), or when the table is not within the X-ray cone beam. Following §4.4.3,
the table is "within the cone" when the principal axis meets the table-top box; here the axis is taken as
the segment from the source centre to the detector plane (the beam does not extend past the detector).
Collisions use the oriented boxes of the collision model with coal (the dissertation used the separating
axis test on the same OBBs) in the one world, :class:`carmkin.world.World`, and its pair list. A pair closer
than the margin (default :data:`carmkin.world.DEFAULT_MARGIN`, the one margin of every planner) is a
collision; every report says at which margin it was made. Lengths in metres, angles in radians, all in the
table frame 0.
"""

from __future__ import annotations

import operator
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from carmkin.errors import InvalidConfigurationError
from carmkin.model.params import JOINT_RANGE_TOLERANCE
from carmkin.model.system import require_system  # noqa: F401 (the solvers' one check of ``system``)
from carmkin.transforms import segment_hits_box
from carmkin.validation import JOINT_VALUE_LIMIT, frozen_instance, real_array, real_scalar
from carmkin.world import DEFAULT_MARGIN, Obstacle, World, link_of

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


class _Deferred:
    """A field of a frozen dataclass that may also be given as a function of no arguments, called on the first
    read and kept (the exact smallest distance costs every pair's distance, the cone test a slab test: an
    acceptance rule that reads neither does not pay for them). ``kind`` converts the value; ``default`` is
    the dataclass default."""

    def __init__(self, kind, default) -> None:
        self.kind, self.default = kind, default

    def __set_name__(self, owner, name: str) -> None:
        self.slot = "_" + name

    def __get__(self, obj, owner=None):
        if obj is None:
            return self.default
        value = obj.__dict__[self.slot]
        if callable(value):
            value = self.kind(value())
            obj.__dict__[self.slot] = value
        return value

    def __set__(self, obj, value) -> None:
        obj.__dict__[self.slot] = value if callable(value) else self.kind(value)


#: Rendered when the principal axis misses the table top.
NOT_IN_CONE = "table not in the X-ray cone (principal axis misses the table top)"


@dataclass(frozen=True)
class ValidityReport:
    """Every violated condition of one configuration.

    Attributes:
        joints: joints out of range. collisions: pairs with distance < ``margin`` (intersecting when
        ``margin`` = 0). table_in_cone: whether the principal axis meets the table-top box.
        min_distance: smallest signed distance over the pairs (m). Both may be given as functions, computed
        on first read. margin: the margin used (m), which every
        report states (``str(report)``: ``valid at margin 10 mm``): a solve reports at its own margin.
    """

    q: np.ndarray
    joints: tuple[JointViolation, ...]
    collisions: tuple[Contact, ...]
    table_in_cone: bool = _Deferred(bool, True)
    min_distance: float = _Deferred(float, float("inf"))
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
        """``valid at margin 10 mm`` or the reasons, with the margin they were computed at."""
        at = f"at margin {self.margin * 1e3:g} mm"
        return f"valid {at}" if self.valid else f"invalid {at}: " + "; ".join(self.reasons)


def pose_in_cone(system, T) -> bool:
    """Whether the principal axis of the source pose ``T`` (4, 4, frame 0), from the source centre to the
    detector plane, meets the table-top box. It depends on the pose alone, not on the joints reaching it."""
    source = T[:3, 3]
    detector = source + system.carm.source_to_detector * T[:3, 2]
    return segment_hits_box(source, detector, system.table.top_center, system.table.top_size)


def table_in_cone(system, q) -> bool:
    """Whether the principal axis (source centre to detector plane) meets the table-top box (frame 0)."""
    return pose_in_cone(system, system.fk(q, check_units=False))


def check(
    system,
    q,
    obstacles: Sequence[Obstacle] = (),
    margin: float = DEFAULT_MARGIN,
    world: World | None = None,
    state: KinematicState | None = None,
) -> ValidityReport:
    """Report every violated condition of configuration ``q`` (nq,) of ``system``.

    ``margin`` (m, default :data:`carmkin.world.DEFAULT_MARGIN`): pairs closer than it count as collisions
    (0 = only intersecting pairs). Pass a prebuilt ``world`` (:class:`carmkin.world.World`, holding the
    obstacles) to avoid rebuilding it per call; ``obstacles`` and ``world`` together are an error.
    ``state``: the :class:`~carmkin.robot.state.KinematicState` of ``q`` with that world, when the caller has
    it already (one forward-kinematics pass per configuration).
    """
    require_system(system)
    model = system.pinocchio()[0]
    q = real_array(q, "q", (model.nq,), error=InvalidConfigurationError, limit=JOINT_VALUE_LIMIT, unit="m, rad")
    margin = real_scalar(margin, "margin", error=InvalidConfigurationError, low=0.0, unit="m")
    if world is not None and obstacles:
        raise InvalidConfigurationError("give the obstacles either in the world or as obstacles, not both")
    if world is not None and not isinstance(world, World):
        raise InvalidConfigurationError(f"world must be a carmkin.world.World, got {type(world).__name__}")
    if state is None:
        world = world if world is not None else World(system, obstacles)
        state = KinematicState(model, q, world)
    elif not np.array_equal(state.q, q):
        raise InvalidConfigurationError("the kinematic state given to check() belongs to another configuration")
    distances = state.distances
    pairs = np.flatnonzero(distances < margin)
    return report(system, q, state.world, pairs, distances[pairs], state.min_distance, state.source_pose, margin)


def joint_violations(system, q: np.ndarray, bounds=None) -> tuple[JointViolation, ...]:
    """The joints of ``q`` (nq,) outside their ranges (a value within the range tolerance of a limit is in);
    ``bounds``: ``(system.lower, system.upper)`` as lists when the caller holds them."""
    lower, upper = bounds if bounds is not None else (system.lower.tolist(), system.upper.tolist())
    values = q.tolist()
    if all(map(operator.le, lower, values)) and all(map(operator.le, values, upper)):  # the usual case, on floats
        return ()  # (NaN fails both comparisons: the slow path below reports it)
    return tuple(
        JointViolation(r.name if r.name != "joint" else n, float(v), float(r.excess(v)), bool(p))
        for n, r, v, p in zip(system.joint_names, system.joint_ranges, q, system.prismatic)
        if r.excess(v) != 0.0
    )


def within_ranges(system, qs: np.ndarray) -> np.ndarray:
    """(N,) bool: every joint of each row of ``qs`` (N, nq) within its range (the range tolerance included)."""
    tolerance = JOINT_RANGE_TOLERANCE
    return np.all((qs >= system.lower - tolerance) & (qs <= system.upper + tolerance), axis=1)


def report(system, q: np.ndarray, world: World, pairs, distances, min_distance,
           source_pose: np.ndarray, margin: float, bounds=None) -> ValidityReport:
    """The report of ``q`` from its parts: ``pairs`` (indices into ``world.pairs``) closer than ``margin``
    with their ``distances`` (m), the smallest distance over all pairs (a float, or a function giving it on
    first read), and the source pose (4, 4);
    ``bounds`` as in :func:`joint_violations`."""
    collisions = tuple(Contact(world.pairs[k][0], world.pairs[k][1], float(d))
                       for k, d in zip(np.asarray(pairs).tolist(), np.asarray(distances).tolist())) if len(pairs) else ()
    # what ValidityReport(q, joints, collisions, table_in_cone=..., min_distance=..., margin=...) stores (the
    # deferred fields under their slots), without the frozen __init__'s cost on every checked solve
    return frozen_instance(ValidityReport, {
        "q": q,
        "joints": joint_violations(system, q, bounds),
        "collisions": collisions,
        "_table_in_cone": lambda: pose_in_cone(system, source_pose),
        "_min_distance": min_distance if callable(min_distance) else float(min_distance),
        "margin": float(margin),
    })
