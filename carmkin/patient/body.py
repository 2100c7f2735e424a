"""A parametric patient lying on the table: head, trunk, arms and legs as coal capsules and a box.

Sizes come from one anthropometric source, D. A. Winter, *Biomechanics and Motor Control of Human
Movement*, 4th ed., Wiley 2009, ch. 4:

* segment **lengths** as fractions of the body height H (Fig. 4.1, after Drillis and Contini 1966),
  :data:`LENGTH_FRACTIONS`;
* segment **masses** as fractions of the body mass m and segment **densities** (Table 4.1, after Dempster
  1955), :data:`MASS_FRACTIONS`, :data:`DENSITIES`.

Each segment's volume is its mass over its density; a capsule of the segment's length takes the radius that
gives that volume, the trunk is a box of the cited chest width and length whose depth gives its volume. So a
heavier patient of the same height is thicker, not longer.

Frames. The body is described in the DICOM patient frame (LPS: +L to the patient's left, +P posterior, +H
to the head, metres) with its **reference point** at the origin: the mid-sagittal plane (L = 0), the plane
of the back (P = 0, the body lies at P < 0) and the level of the nipples (Winter's chest height 0.720 H).
:meth:`ParametricPatient.pose` places that frame in the table frame 0 from the DICOM Patient Position
(0018,5100) and the table-frame position of the reference point (``origin``, m), through
:func:`carmkin.imaging.projection.patient_pose`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from carmkin.errors import PatientModelError
from carmkin.imaging.projection import PATIENT_POSITIONS, patient_pose
from carmkin.transforms import rotation_between
from carmkin.validation import point_array, real_scalar

#: Winter (2009) Fig. 4.1: heights above the floor (standing) and widths, as fractions of the height H.
LENGTH_FRACTIONS = {
    "chin": 0.870, "shoulder": 0.818, "chest": 0.720, "elbow": 0.630, "wrist": 0.485, "fingertip": 0.377,
    "hip": 0.530, "knee": 0.285, "ankle": 0.039, "shoulder_width": 0.259, "chest_width": 0.174,
    "hip_width": 0.191,
}
#: Winter (2009) Table 4.1: segment mass / total body mass (hand included in the forearm, foot in the leg).
MASS_FRACTIONS = {"head": 0.081, "trunk": 0.497, "upper_arm": 0.028, "forearm": 0.022, "thigh": 0.100,
                  "leg": 0.061}
#: Winter (2009) Table 4.1: segment densities (kg/m³; forearm and leg: the segment's, hand and foot alike).
DENSITIES = {"head": 1110.0, "trunk": 1030.0, "upper_arm": 1070.0, "forearm": 1130.0, "thigh": 1050.0,
             "leg": 1090.0}
#: Accepted body height (m) and mass (kg): a newborn to the tallest, a premature infant to the heaviest.
HEIGHT_RANGE = (0.4, 2.8)
MASS_RANGE = (1.0, 650.0)
#: Share of the volume its mass needs (Winter's densities) the body's segments must hold: below it, segments are
#: balls far too small for their masses (a mass far too large for the height: 60 kg at 0.4 m holds 58 %) and
#: the body is refused. Real extremes pass (600 kg at 1.8 m holds 91 %, 200 kg at 1 m 80 %; a segment that is
#: a ball loses some volume, which the model accepts).
VOLUME_SHARE = 0.75
#: A patient placed in a world rests on the table top: its lowest point within this (m) of the top surface
#: (neither floating above it nor sunk into it).
REST_TOLERANCE = 0.001


@dataclass(frozen=True)
class Segment:
    """One body part in the patient frame (LPS, m): a capsule from ``a`` to ``b`` of ``radius``, or a box of
    full ``extents`` (L, P, H) centred at ``a`` (``b`` unused)."""

    name: str
    shape: str
    a: tuple[float, float, float]
    b: tuple[float, float, float]
    radius: float = 0.0
    extents: tuple[float, float, float] = (0.0, 0.0, 0.0)


def capsule_radius(volume: float, length: float) -> float:
    """Radius r (m) of a capsule of total length ``length`` (m, caps included) and ``volume`` (m³):
    ``π r² length − (2/3) π r³ = volume`` solved by bisection on (0, length/2] (monotone there)."""
    lo, hi = 0.0, 0.5 * length
    if math.pi * hi * hi * length - 2.0 / 3.0 * math.pi * hi ** 3 < volume:
        return hi  # a sphere of that length is still smaller: the segment is a ball
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if math.pi * mid * mid * length - 2.0 / 3.0 * math.pi * mid ** 3 < volume:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _segment_volume(name: str, mass: float) -> float:
    return MASS_FRACTIONS[name] * mass / DENSITIES[name]


def _kind(segment: "Segment") -> str:
    """The Winter segment of a body part (``thigh_left`` -> ``thigh``)."""
    return segment.name if segment.name in MASS_FRACTIONS else segment.name.rsplit("_", 1)[0]


def segment_volume(segment: "Segment") -> float:
    """Volume (m³) of a segment's shape: a box's extents multiplied, a capsule of total length L = |b − a|
    (caps included) ``π r² L − (2/3) π r³``."""
    if segment.shape == "box":
        return float(np.prod(segment.extents))
    length, r = float(np.linalg.norm(np.subtract(segment.b, segment.a))), segment.radius
    return math.pi * r * r * length - 2.0 / 3.0 * math.pi * r ** 3


def body_segments(height: float, mass: float, arms: str = "side") -> tuple[Segment, ...]:
    """The segments (patient frame, reference point at the origin) of a body of ``height`` (m), ``mass``
    (kg), arms along the trunk (``"side"``) or raised beside the head (``"up"``)."""
    H, f = height, LENGTH_FRACTIONS
    level = lambda name: (f[name] - f["chest"]) * H  # noqa: E731 (H coordinate of a landmark)
    segments = []
    # Trunk: a box from the hips to the shoulders, chest width, depth from its volume.
    length = (f["shoulder"] - f["hip"]) * H
    width = f["chest_width"] * H
    depth = _segment_volume("trunk", mass) / (width * length)
    segments.append(Segment("trunk", "box", (0.0, -depth / 2, 0.5 * (level("shoulder") + level("hip"))), (0, 0, 0),
                            extents=(width, depth, length)))
    # Head and neck: a capsule from the shoulders to the vertex.
    top, bottom = H * (1.0 - f["chest"]), level("shoulder")
    r = capsule_radius(_segment_volume("head", mass), top - bottom)
    segments.append(Segment("head", "capsule", (0.0, -r, bottom), (0.0, -r, top), r))
    # Legs: thigh (hip to knee) and leg with foot (knee to floor), at half the hip width apart.
    for side, sign in (("left", 1.0), ("right", -1.0)):
        x = sign * f["hip_width"] * H / 4
        for name, hi, lo in (("thigh", "hip", "knee"), ("leg", "knee", None)):
            h_hi, h_lo = level(hi), (level(lo) if lo else -f["chest"] * H)
            r = capsule_radius(_segment_volume(name, mass), h_hi - h_lo)
            segments.append(Segment(f"{name}_{side}", "capsule", (x, -r, h_lo), (x, -r, h_hi), r))
    # Arms: upper arm (shoulder to elbow) and forearm with hand (elbow to fingertip), outside the trunk.
    for side, sign in (("left", 1.0), ("right", -1.0)):
        r_upper = capsule_radius(_segment_volume("upper_arm", mass), (f["shoulder"] - f["elbow"]) * H)
        r_fore = capsule_radius(_segment_volume("forearm", mass), (f["elbow"] - f["fingertip"]) * H)
        x = sign * (width / 2 + max(r_upper, r_fore))
        for name, hi, lo, r in (("upper_arm", "shoulder", "elbow", r_upper), ("forearm", "elbow", "fingertip", r_fore)):
            if arms == "side":
                a, b = (x, -r, level(lo)), (x, -r, level(hi))
            else:  # raised: mirrored about the shoulder level, beside the head
                s = level("shoulder")
                a, b = (x, -r, 2 * s - level(hi)), (x, -r, 2 * s - level(lo))
            segments.append(Segment(f"{name}_{side}", "capsule", a, b, r))
    return tuple(segments)


@dataclass(frozen=True)
class ParametricPatient:
    """A patient of ``height`` (m) and ``mass`` (kg) in DICOM Patient Position ``position``, reference point
    (mid-sagittal, back plane, nipple level) at ``origin`` (3,) in the table frame 0 (m); ``arms`` ``"side"``
    or ``"up"``. Use :meth:`on_table` to lay it on a system's table top."""

    height: float = 1.75
    mass: float = 75.0
    position: str = "HFS"
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    arms: str = "side"
    segments: tuple[Segment, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        h = real_scalar(self.height, "height", error=PatientModelError, low=HEIGHT_RANGE[0], high=HEIGHT_RANGE[1],
                        unit="m")
        m = real_scalar(self.mass, "mass", error=PatientModelError, low=MASS_RANGE[0], high=MASS_RANGE[1], unit="kg")
        if not isinstance(self.position, str) or self.position.upper() not in PATIENT_POSITIONS:
            raise PatientModelError(f"position must be one of {', '.join(PATIENT_POSITIONS)}, got {self.position!r}")
        if not isinstance(self.arms, str) or self.arms not in ("side", "up"):
            raise PatientModelError(f"arms must be 'side' or 'up', got {self.arms!r}")
        origin = point_array(self.origin, "origin", error=PatientModelError)
        if len(origin) != 1:
            raise PatientModelError(f"origin must be one point (3,) in m, got {len(origin)} points")
        object.__setattr__(self, "height", h)
        object.__setattr__(self, "mass", m)
        object.__setattr__(self, "position", self.position.upper())
        object.__setattr__(self, "origin", tuple(float(v) for v in origin[0]))
        object.__setattr__(self, "segments", body_segments(h, m, self.arms))
        held = sum(segment_volume(seg) for seg in self.segments)
        needed = sum(_segment_volume(_kind(seg), m) for seg in self.segments)
        if held < VOLUME_SHARE * needed:
            raise PatientModelError(
                f"mass {m:g} kg is too large for height {h:g} m: the body's segments hold {held * 1e3:.1f} L of the "
                f"{needed * 1e3:.1f} L that mass needs at Winter's densities (a lighter mass or a taller height)")

    @classmethod
    def on_table(cls, system, height: float = 1.75, mass: float = 75.0, position: str = "HFS",
                 chest_z: float = 0.0, lateral_x: float = 0.0, arms: str = "side") -> "ParametricPatient":
        """The patient resting on ``system``'s table top: its lowest point on the top surface, the chest
        (reference point) at ``chest_z`` along the table (m, Z0) and ``lateral_x`` across it (m, X0)."""
        from carmkin.model.system import require_system

        require_system(system, PatientModelError)
        probe = cls(height, mass, position, (0.0, 0.0, 0.0), arms)
        surface = system.table.top_center[1] - system.table.top_size[1] / 2  # Y0 points down
        lowest = float(np.max(probe.surface_points()[:, 1]))
        z = real_scalar(chest_z, "chest_z", error=PatientModelError, unit="m")
        x = real_scalar(lateral_x, "lateral_x", error=PatientModelError, unit="m")
        patient = cls(height, mass, position, (x, surface - lowest, z), arms)
        patient.check_placement(system, "chest_z, lateral_x")
        return patient

    def centre_of_mass(self) -> np.ndarray:
        """The body's centre of mass (3,) in the table frame (m): the segments' centres weighted by Winter's mass
        fractions."""
        T = self.pose()
        weights = np.array([MASS_FRACTIONS[_kind(s)] for s in self.segments])
        centres = np.array([s.a if s.shape == "box" else np.add(s.a, s.b) / 2 for s in self.segments])
        return T[:3, :3] @ (weights @ centres / weights.sum()) + T[:3, 3]

    def check_placement(self, system, name: str = "patient") -> None:
        """:class:`PatientModelError` naming ``name`` unless the body rests on ``system``'s table top: its lowest
        point on the top surface (within :data:`REST_TOLERANCE`, not floating above it nor sunk into it) and
        its centre of mass over the top (not off the table's end or side)."""
        table = system.table
        surface = table.top_center[1] - table.top_size[1] / 2  # Y0 points down
        gap = surface - float(np.max(self.surface_points()[:, 1]))
        if abs(gap) > REST_TOLERANCE:
            where = f"floats {gap * 1e3:.1f} mm above" if gap > 0 else f"sinks {-gap * 1e3:.1f} mm into"
            raise PatientModelError(f"{name}: the patient {where} the table top (at most {REST_TOLERANCE * 1e3:g} mm; "
                                    "ParametricPatient.on_table places it on the top)")
        com = self.centre_of_mass()
        for axis, label in ((2, "end"), (0, "side")):
            offset = com[axis] - table.top_center[axis]
            if abs(offset) > table.top_size[axis] / 2:
                raise PatientModelError(
                    f"{name}: the patient's centre of mass is {(abs(offset) - table.top_size[axis] / 2) * 1e3:.0f} mm "
                    f"beyond the table top's {label} (the top spans ±{table.top_size[axis] / 2 * 1e3:.0f} mm)")

    def pose(self) -> np.ndarray:
        """Pose (4, 4) of the patient frame (LPS, m) in the table frame 0."""
        return patient_pose(self.position, self.origin)

    def surface_points(self) -> np.ndarray:
        """Points (N, 3) in the table frame (m) on every segment's extreme along the six axes (their
        bounding-box corners), for extents and resting checks."""
        T = self.pose()
        points = []
        for s in self.segments:
            if s.shape == "box":
                half = np.array(s.extents) / 2
                corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)]) * half + s.a
                points.append(corners)
            else:
                a, b = np.asarray(s.a), np.asarray(s.b)
                axis = (b - a) / max(np.linalg.norm(b - a), 1e-12)
                inset = min(s.radius, 0.5 * np.linalg.norm(b - a))
                for end in (a + inset * axis, b - inset * axis):  # the cylinder's ends, then ± r
                    points.append(end + s.radius * np.vstack((np.eye(3), -np.eye(3))))
        P = np.vstack(points)
        return P @ T[:3, :3].T + T[:3, 3]

    def obstacles(self, prefix: str = "patient") -> list:
        """The body as :class:`carmkin.robot.collision.Obstacle` s fixed to the table frame (names
        ``<prefix>_<segment>``)."""
        from carmkin.world.obstacles import Obstacle

        if not isinstance(prefix, str):
            raise PatientModelError(f"prefix must be a string (the obstacles' names start with it), got {prefix!r:.60}")
        T = self.pose()
        out = []
        for s in self.segments:
            a = T[:3, :3] @ np.asarray(s.a) + T[:3, 3]
            if s.shape == "box":
                out.append(Obstacle.box(f"{prefix}_{s.name}", s.extents, a, T[:3, :3]))
                continue
            b = T[:3, :3] @ np.asarray(s.b) + T[:3, 3]
            axis = (b - a) / np.linalg.norm(b - a)
            R = rotation_between(np.array([0.0, 0.0, 1.0]), axis)
            length = float(np.linalg.norm(b - a)) - 2 * s.radius
            if length <= 0:
                out.append(Obstacle(f"{prefix}_{s.name}", "sphere", (s.radius,), _pose((a + b) / 2, R)))
            else:
                out.append(Obstacle.capsule(f"{prefix}_{s.name}", s.radius, length, (a + b) / 2, R))
        return out


def _pose(center, R) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, center
    return T
