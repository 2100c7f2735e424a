"""carmkin: kinematics of a mobile X-ray C-arm and the operating table as one chain, backed by Pinocchio.

Units are SI (m, rad) throughout the library; presets and the CLI speak mm and degrees.
"""

from .errors import (
    CarmkinError,
    InvalidConfigurationError,
    InvalidParameterError,
    InvalidPoseError,
    UnknownPresetError,
)
from .geometry import JOINT_NAMES, BodyGeometry, CArmGeometry, JointRange, TableGeometry, TableSetup
from .presets import list_presets, load_preset
from .system import CArmSystem
from . import analytic_ik, qp_ik  # noqa: E402  (contract: carmkin.analytic_ik.solve, carmkin.qp_ik.solve)

__all__ = [
    "JOINT_NAMES",
    "BodyGeometry",
    "CArmGeometry",
    "CArmSystem",
    "CarmkinError",
    "InvalidConfigurationError",
    "InvalidParameterError",
    "InvalidPoseError",
    "JointRange",
    "TableGeometry",
    "TableSetup",
    "UnknownPresetError",
    "list_presets",
    "load_preset",
]
