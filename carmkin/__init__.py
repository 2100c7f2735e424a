"""carmkin: kinematics of a mobile X-ray C-arm and the operating table as one chain, backed by Pinocchio.

Units are SI (m, rad) throughout the library; presets and the CLI speak mm and degrees.
"""

from carmkin._lazy import submodules as _submodules
from carmkin.errors import (
    CarmkinError,
    InvalidConfigurationError,
    InvalidParameterError,
    InvalidPoseError,
    NearSingularSetupError,
    PresetError,
    UnknownPresetError,
)
from carmkin.model.params import (
    JOINT_NAMES,
    BodyGeometry,
    CArmGeometry,
    JointRange,
    TableGeometry,
    TableSetup,
)
from carmkin.model.system import CArmSystem
from carmkin.presets import list_presets, load_preset

__all__ = [
    "JOINT_NAMES",
    "BodyGeometry",
    "CArmGeometry",
    "CArmSystem",
    "CarmkinError",
    "DEFAULT_MARGIN",
    "InvalidConfigurationError",
    "InvalidParameterError",
    "InvalidPoseError",
    "JointRange",
    "NearSingularSetupError",
    "PresetError",
    "TableGeometry",
    "TableSetup",
    "UnknownPresetError",
    "list_presets",
    "load_preset",
]


#: Submodules load on first attribute access (``carmkin.analytic_ik.solve(...)`` after ``import carmkin``), so
#: that importing carmkin does not pull in the QP solvers, coal or meshcat: every public submodule
#: (:func:`carmkin._lazy.submodules`).
_submodule = _submodules(__name__, __path__, also=("viz",))


def _version() -> str:
    """The installed distribution's version (pyproject.toml's ``version``), read from the package metadata."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("carmkin")
    except PackageNotFoundError:  # a source tree on sys.path that was never installed
        return "0+unknown"


def __getattr__(name: str):
    if name == "__version__":  # computed on first use: importing carmkin stays light
        globals()["__version__"] = _version()
        return globals()["__version__"]
    if name == "DEFAULT_MARGIN":  # the one default clearance margin (m): carmkin.world.DEFAULT_MARGIN
        from carmkin.world.tolerances import DEFAULT_MARGIN

        return DEFAULT_MARGIN
    return _submodule(name)
