"""Value objects describing the C-arm, the table and how they are set up (SI units: m, rad).

They are frozen dataclasses validated on construction: a bad value raises
:class:`~carmkin.errors.InvalidParameterError` naming the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np

from carmkin.errors import InvalidParameterError, NearSingularSetupError
from carmkin.transforms import check_rigid_transform
from carmkin.validation import sequence_length

from .bounds import (
    MAX_ANGLE,
    MAX_LENGTH,
    MAX_PIXELS,
    MAX_SETUP_DISTANCE,
    NEAR_PARALLEL_SIN,
    PARALLEL_AXES_SIN,
    check_count,
    check_joint_limits,
    check_length,
    check_real,
)

#: Joint names of the 6-DOF chain, in the order of ``q = [d0, d1, theta2, d3, theta4, theta5]``.
JOINT_NAMES = ("table_translation", "vertical", "wigwag", "horizontal", "angular", "orbital")
#: ``True`` where the joint of :data:`JOINT_NAMES` is prismatic (m), ``False`` where revolute (rad).
PRISMATIC = (True, True, False, True, False, False)
#: The five joints of the C-arm itself (all but the table translation), in the order of q.
CARM_JOINT_NAMES = JOINT_NAMES[1:]
#: A joint value counts as within its range when it lies no more than this beyond a limit (m for prismatic,
#: rad for revolute joints): a value on a limit is in range, even after the round-off of an FK → IK round
#: trip (~1e-16 m / rad for poses within a few metres). 1e-9 m and 1e-9 rad are far below any C-arm's
#: positioning accuracy. Used by :meth:`JointRange.excess`, :meth:`JointRange.contains` and every range check.
JOINT_RANGE_TOLERANCE = 1e-9


@dataclass(frozen=True)
class JointRange:
    """Closed range ``[lower, upper]`` of one joint (m for prismatic, rad for revolute joints)."""

    lower: float
    upper: float
    name: str = "joint"

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise InvalidParameterError(f"JointRange.name must be a string, got {self.name!r}")
        # ±MAX_LENGTH here (m or rad); the owner, who knows the joint's kind, narrows revolute ranges to ±2π.
        lower = check_real(f"{self.name}.lower", self.lower, -MAX_LENGTH, MAX_LENGTH)
        upper = check_real(f"{self.name}.upper", self.upper, -MAX_LENGTH, MAX_LENGTH)
        if lower > upper:
            raise InvalidParameterError(f"{self.name}: lower limit {lower} > upper limit {upper}")
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)

    @property
    def locked(self) -> bool:
        """True for a joint that does not move: a range no wider than :data:`JOINT_RANGE_TOLERANCE` (min = max,
        e.g. an angiography stand's vertical travel)."""
        return self.upper - self.lower <= JOINT_RANGE_TOLERANCE

    def excess(self, value):
        """Signed distance outside the range: < 0 below ``lower``, > 0 above ``upper``, 0 inside.

        Values within :data:`JOINT_RANGE_TOLERANCE` of the range count as inside (excess 0).
        """
        value = np.asarray(value, dtype=float)
        lo, hi = self.lower - JOINT_RANGE_TOLERANCE, self.upper + JOINT_RANGE_TOLERANCE
        return np.where(value < lo, value - self.lower, np.where(value > hi, value - self.upper, 0.0))

    def contains(self, value):
        """True where ``value`` is within the range, up to :data:`JOINT_RANGE_TOLERANCE` (NaN is not)."""
        value = np.asarray(value, dtype=float)
        return (value >= self.lower - JOINT_RANGE_TOLERANCE) & (value <= self.upper + JOINT_RANGE_TOLERANCE)


@dataclass(frozen=True)
class CArmGeometry:
    """Geometry and joint ranges of a mobile C-arm (§4.3.1 of the dissertation, Fig. 4.1).

    Attributes:
        length_offset: l1, distance from the wigwag axis to the X-ray beam (m).
        orbital_offset: l2, distance from the X-ray source centre to the angular axis (m).
        a1: distance from the angular axis to the orbital axis (m); 0 for an isocentric C-arm.
        a2: distance from the X-ray beam centre to the orbital axis (m); 0 for an isocentric C-arm.
        vertical, wigwag, horizontal, angular, orbital: joint ranges (m or rad).
        source_to_detector: distance from the source centre to the detector plane along the principal
            axis (m).
        detector_width, detector_height: active detector size along image X and Y (m).
        detector_columns, detector_rows: image size in pixels (width, height).
        principal_point: pixel coordinates (u, v) of the principal point; ``None`` = image centre.
    """

    length_offset: float
    orbital_offset: float
    a1: float = 0.0
    a2: float = 0.0
    vertical: JointRange = field(default_factory=lambda: JointRange(0.0, 0.4, "vertical"))
    wigwag: JointRange = field(default_factory=lambda: JointRange(-math.radians(10), math.radians(10), "wigwag"))
    horizontal: JointRange = field(default_factory=lambda: JointRange(0.0, 0.2, "horizontal"))
    angular: JointRange = field(default_factory=lambda: JointRange(-math.radians(190), math.radians(190), "angular"))
    orbital: JointRange = field(default_factory=lambda: JointRange(-math.radians(95), math.radians(95), "orbital"))
    source_to_detector: float = 1.0
    detector_width: float = 0.23
    detector_height: float = 0.23
    detector_columns: int = 800
    detector_rows: int = 600
    principal_point: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        owner = "CArmGeometry"
        for name in ("length_offset", "orbital_offset", "source_to_detector", "detector_width", "detector_height"):
            object.__setattr__(self, name, check_length(f"{owner}.{name}", getattr(self, name), positive=True))
        for name in ("a1", "a2"):
            object.__setattr__(self, name, check_length(f"{owner}.{name}", getattr(self, name)))
        for name in ("detector_columns", "detector_rows"):
            object.__setattr__(self, name, check_count(f"{owner}.{name}", getattr(self, name)))
        for name, prismatic in zip(("vertical", "wigwag", "horizontal", "angular", "orbital"), PRISMATIC[1:]):
            if not isinstance(getattr(self, name), JointRange):
                raise InvalidParameterError(f"{owner}.{name} must be a JointRange, got {getattr(self, name)!r}")
            check_joint_limits(getattr(self, name), prismatic, owner)
        if self.principal_point is not None:
            if sequence_length(self.principal_point) != 2:
                raise InvalidParameterError(f"{owner}.principal_point must be (u, v) in px, got "
                                            f"{self.principal_point!r:.80}")
            u, v = (check_real(f"{owner}.principal_point", x, -MAX_PIXELS, MAX_PIXELS, "px")
                    for x in self.principal_point)
            object.__setattr__(self, "principal_point", (u, v))

    @property
    def is_isocentric(self) -> bool:
        """True when both geometric offsets a1 and a2 are zero."""
        return self.a1 == 0.0 and self.a2 == 0.0

    @property
    def source_to_orbital_axis(self) -> float:
        """L = l2 + a1 (m): distance along the principal axis from the source to the orbital axis's foot
        (the ``-(l2 + a1)`` of DH row 5; the C radius of the URDF)."""
        return self.orbital_offset + self.a1

    @property
    def arm_length(self) -> float:
        """M = l1 − a2 (m): length of the horizontal arm at d3 = 0 (the ``l1 − a2`` of DH row 3)."""
        return self.length_offset - self.a2

    @property
    def joint_ranges(self) -> tuple[JointRange, ...]:
        """Ranges of the five C-arm joints: vertical, wigwag, horizontal, angular, orbital."""
        return (self.vertical, self.wigwag, self.horizontal, self.angular, self.orbital)

    @property
    def pixel_spacing(self) -> tuple[float, float]:
        """Detector pixel size (m) along image X and Y."""
        return self.detector_width / self.detector_columns, self.detector_height / self.detector_rows

    def intrinsics(self) -> np.ndarray:
        """Pinhole intrinsic matrix K (pixels) of the X-ray source/detector pair."""
        sx, sy = self.pixel_spacing
        u0, v0 = self.principal_point or ((self.detector_columns - 1) / 2, (self.detector_rows - 1) / 2)
        f = self.source_to_detector
        return np.array([[f / sx, 0.0, u0], [0.0, f / sy, v0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class TableSetup:
    """Where the table frame 0 sits relative to the C-arm's vertical axis (§4.3.1, Fig. 4.2).

    Attributes:
        gamma1: Ang(Z0, Z1), angle from the table translation axis to the vertical axis about X1 (rad).
        gamma2: Ang(X0, X1), about Z0 (rad).
        gamma3: Ang(X1, X2), about Z1 (rad).
        D1: Dist(Z0, Z1) along X1 (m). D2: Dist(X0, X1) along Z0 (m). D3: Dist(X1, X2) along Z1 (m).
    """

    gamma1: float
    gamma2: float
    gamma3: float
    D1: float
    D2: float
    D3: float

    def __post_init__(self) -> None:
        for f in fields(self):
            bound, unit = (MAX_ANGLE, "rad") if f.name.startswith("gamma") else (MAX_SETUP_DISTANCE, "m")
            object.__setattr__(self, f.name, check_real(f"TableSetup.{f.name}", getattr(self, f.name), -bound, bound, unit))

    @classmethod
    def from_pose(cls, T_base_table) -> "TableSetup":
        """Build the setup from the table frame's pose in the C-arm base frame (eq. 4.3).

        ``T_base_table`` (4x4) maps table-frame coordinates into the C-arm base frame, the frame fixed to
        the cart with Z along the vertical axis and origin where the vertical joint is zero (frame 1 of the
        5-DOF model, Fig. 4.1). X1 is the common normal from the table axis Z0 to the vertical axis Z1
        (DH rule); when the axes are parallel (singular case a) the normal through the table origin is
        taken, and X1 = X0 when they coincide. Axes within a small angle of parallel (sine between
        :data:`~carmkin.model.bounds.PARALLEL_AXES_SIN` and :data:`~carmkin.model.bounds.NEAR_PARALLEL_SIN`)
        raise :class:`~carmkin.errors.NearSingularSetupError`: there the common normal runs off to
        infinity and cannot be computed to any useful precision.
        """
        T = check_rigid_transform(T_base_table, "T_base_table")
        p0, x0, z0 = T[:3, 3], T[:3, 0], T[:3, 2]
        z1 = np.array([0.0, 0.0, 1.0])
        normal = np.cross(z0, z1)
        sin_angle = float(np.linalg.norm(normal))
        if PARALLEL_AXES_SIN < sin_angle < NEAR_PARALLEL_SIN:
            raise NearSingularSetupError(
                f"T_base_table: the table axis Z0 is {math.asin(sin_angle):.3g} rad "
                f"({math.degrees(math.asin(sin_angle)):.3g} deg) from the C-arm's vertical axis, nearly "
                f"parallel (singular case a); need exactly parallel (sine <= {PARALLEL_AXES_SIN:g}) or at "
                f"least {math.asin(NEAR_PARALLEL_SIN):.3g} rad apart")
        if sin_angle > PARALLEL_AXES_SIN:
            x1 = normal / np.linalg.norm(normal)
            # Feet of the common normal: p0 + t0 z0 on Z0 and t1 z1 on Z1 with (t1 z1 - p0 - t0 z0) ∥ x1.
            A = np.column_stack((z0, -z1, x1))
            t0, t1, _ = np.linalg.solve(A, -p0)
        else:  # parallel axes: the DH convention takes the normal through the table origin
            t0 = 0.0
            t1 = p0[2]
            offset = np.array([0.0, 0.0, t1]) - p0
            x1 = offset / np.linalg.norm(offset) if np.linalg.norm(offset) > 1e-12 else x0
        foot0, foot1 = p0 + t0 * z0, t1 * z1
        gamma1 = math.atan2(np.dot(np.cross(z0, z1), x1), np.dot(z0, z1))
        gamma2 = math.atan2(np.dot(np.cross(x0, x1), z0), np.dot(x0, x1))
        gamma3 = math.atan2(np.dot(np.cross(x1, (1.0, 0.0, 0.0)), z1), x1[0])
        return cls(gamma1, gamma2, gamma3, D1=float(np.dot(foot1 - foot0, x1)), D2=float(t0), D3=float(-t1))


@dataclass(frozen=True)
class TableGeometry:
    """The operating table: translation range and the table-top box (table frame 0, metres).

    Attributes:
        translation: range of the table translation joint d0 (m). d0 is the displacement of the C-arm
            relative to the table along Z0, so the table itself moves by -d0 relative to the C-arm.
        top_size: box extents along X0, Y0, Z0 (m).
        top_center: box centre in frame 0 (m).
        joints: extra joints of a motorized table (:class:`carmkin.model.table_joints.TableJoint`), ordered from
            the table top down; empty for the paper's single translation.
    """

    translation: JointRange = field(default_factory=lambda: JointRange(-0.4, 0.4, "table_translation"))
    top_size: tuple[float, float, float] = (0.6, 0.06, 2.0)
    top_center: tuple[float, float, float] = (0.0, 0.18, 0.0)
    joints: tuple = ()

    def __post_init__(self) -> None:
        if not isinstance(self.translation, JointRange):
            raise InvalidParameterError(f"TableGeometry.translation must be a JointRange, got {self.translation!r}")
        check_joint_limits(self.translation, True, "TableGeometry")
        object.__setattr__(self, "top_size", _check_lengths("TableGeometry.top_size", self.top_size, positive=True))
        object.__setattr__(self, "top_center", _check_lengths("TableGeometry.top_center", self.top_center))
        if (isinstance(self.joints, (str, bytes, dict)) or not hasattr(self.joints, "__iter__")
                or np.ndim(self.joints) == 0):  # a 0-d array has __iter__ but cannot be iterated
            raise InvalidParameterError(f"TableGeometry.joints must be a tuple of TableJoint, got {self.joints!r}")
        object.__setattr__(self, "joints", tuple(self.joints))
        names = [getattr(j, "name", None) for j in self.joints]
        if len(set(names)) != len(names) or not all(hasattr(j, "inverse_motion") for j in self.joints):
            raise InvalidParameterError(f"TableGeometry.joints must be distinct TableJoint objects, got {names}")


#: Where a stand may be fixed (:attr:`BodyGeometry.mount`).
MOUNTS = ("floor", "ceiling")


@dataclass(frozen=True)
class BodyGeometry:
    """Extents of the C-arm's collision/visual primitives that the kinematics does not fix (m).

    Lengths along the chain (arm, C radius) follow from :class:`CArmGeometry`; these are the rest.
    Attributes:
        floor_height: floor height in the C-arm base frame (negative: below the vertical axis origin).
        cart_size: cart box extents along base X, Y, Z; the cart stands on the floor behind the column.
        column_width: side of the square column and of the horizontal arm's cross-section.
        c_thickness: radial thickness of the C; c_depth: its extent along the orbital axis.
        source_housing: box extents of the X-ray tube housing (m), behind the focal spot.
        detector_thickness: thickness of the detector housing behind the detector plane.
        mount: where the stand is fixed: ``"floor"`` (the cart stands on the floor, the column rises from it)
            or ``"ceiling"`` (an angiography stand hanging from a ceiling carriage: the cart box sits under the
            ceiling and the column rises from the arm to it). Only the bodies change; the chain is the same.
        ceiling_height: ceiling height in the C-arm base frame (m, above the vertical axis origin); used
            when ``mount == "ceiling"``.
        c_radius: the C-arc's own radius (m), about the orbital axis; ``None`` (the default): the source to
            orbital axis distance L, the C passing through the source. A larger one (at least L, checked by
            :class:`~carmkin.model.system.CArmSystem`) runs from L - c_radius to L + c_radius along the
            principal axis, a bracket joining its near end to the source housing (a biplane's lateral C, the
            frontal turning inside it). Bodies only: the kinematics does not change.
    """

    floor_height: float = -1.0
    cart_size: tuple[float, float, float] = (0.7, 0.9, 0.9)
    column_width: float = 0.16
    c_thickness: float = 0.08
    c_depth: float = 0.14
    source_housing: tuple[float, float, float] = (0.24, 0.24, 0.22)
    detector_thickness: float = 0.15
    mount: str = "floor"
    ceiling_height: float = 2.0
    c_radius: float | None = None

    def __post_init__(self) -> None:
        owner = "BodyGeometry"
        if self.c_radius is not None:
            object.__setattr__(self, "c_radius", check_length(f"{owner}.c_radius", self.c_radius, positive=True))
        if self.mount not in MOUNTS:
            raise InvalidParameterError(f"{owner}.mount must be one of {', '.join(map(repr, MOUNTS))}, got {self.mount!r}")
        object.__setattr__(self, "floor_height", check_length(f"{owner}.floor_height", self.floor_height))
        object.__setattr__(self, "ceiling_height", check_length(f"{owner}.ceiling_height", self.ceiling_height))
        for name in ("column_width", "c_thickness", "c_depth", "detector_thickness"):
            object.__setattr__(self, name, check_length(f"{owner}.{name}", getattr(self, name), positive=True))
        for name in ("cart_size", "source_housing"):
            object.__setattr__(self, name, _check_lengths(f"{owner}.{name}", getattr(self, name), positive=True))
        if self.mount == "ceiling" and self.ceiling_height - self.cart_size[2] <= 0:
            raise InvalidParameterError(
                f"{owner}.ceiling_height = {self.ceiling_height:g} m leaves no room for the ceiling carriage "
                f"(cart_size z = {self.cart_size[2]:g} m) above the arm: need ceiling_height > cart_size z")


def _check_lengths(what: str, values, positive: bool = False) -> tuple[float, float, float]:
    """Three lengths (m), each checked by :func:`~carmkin.model.bounds.check_length`."""
    if sequence_length(values) != 3:
        raise InvalidParameterError(f"{what} needs three values (m), got {values!r:.80}")
    return tuple(check_length(what, v, positive) for v in values)
