"""The parameters a calibration can fit, each named with its unit for people (mm, deg, px), and how a set of
values of them makes a :class:`~carmkin.model.system.CArmSystem`.

The list (:func:`parameters`) is in **priority order**: where the views cannot separate two parameters, the
one listed first is fitted and the later one held at its nominal value (:mod:`.identifiability`):

========================  ====  ======================================================================
name                      unit  what it is (SI field it sets)
========================  ====  ======================================================================
``<joint>_zero_offset``   mm    per joint in the order of q (deg for revolute joints): reading + offset =
                                model value (``Calibration.joint_offsets``)
``source_to_detector``    mm    source–detector distance (``CArmGeometry.source_to_detector``)
``principal_point_u/v``   px    principal point (``CArmGeometry.principal_point``)
``detector_rotation``     deg   the detector's in-plane rotation (``Calibration.detector_rotation``)
``length_offset``         mm    l1 (``CArmGeometry.length_offset``)
``orbital_offset``        mm    l2 (``CArmGeometry.orbital_offset``)
``a1``, ``a2``            mm    the C-arm's non-isocentric offsets
``gamma1..3``             deg   the table setup's angles (``TableSetup``)
``D1..3``                 mm    the table setup's distances (``TableSetup``)
``sag_cos``, ``sag_sin``  mm    the C's sag along Y_xray, ∝ cos and sin of the orbital angle (``Calibration``)
========================  ====  ======================================================================
"""

from __future__ import annotations

import dataclasses
import difflib
import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import CalibrationError
from carmkin.model.calibration import Calibration
from carmkin.model.system import CArmSystem, require_system
from carmkin.validation import real_scalar

#: One millimetre in metres, one degree in radians: the units people read.
MM, DEG = 1e-3, math.pi / 180
_LINKS = ("length_offset", "orbital_offset", "a1", "a2")
_SETUP = ("gamma1", "gamma2", "gamma3", "D1", "D2", "D3")


@dataclass(frozen=True)
class Parameter:
    """One calibration parameter: its ``name``, ``unit`` ("mm", "deg" or "px") and ``group`` ("joint zero
    offset", "imaging", "link", "table setup" or "sag")."""

    name: str
    unit: str
    group: str


def parameters(system: CArmSystem) -> tuple[Parameter, ...]:
    """Every parameter of ``system`` (any nq), in priority order (see the module docstring)."""
    require_system(system, CalibrationError)
    joints = tuple(Parameter(f"{name}_zero_offset", "mm" if prismatic else "deg", "joint zero offset")
                   for name, prismatic in zip(system.joint_names, system.prismatic))
    imaging = (Parameter("source_to_detector", "mm", "imaging"), Parameter("principal_point_u", "px", "imaging"),
               Parameter("principal_point_v", "px", "imaging"), Parameter("detector_rotation", "deg", "imaging"))
    links = tuple(Parameter(name, "mm", "link") for name in _LINKS)
    setup = tuple(Parameter(name, "deg" if name.startswith("gamma") else "mm", "table setup") for name in _SETUP)
    sag = (Parameter("sag_cos", "mm", "sag"), Parameter("sag_sin", "mm", "sag"))
    return joints + imaging + links + setup + sag


def select(system: CArmSystem, names=None) -> tuple[Parameter, ...]:
    """The parameters named by ``names`` (a sequence of names; None = all), kept in priority order, or
    :class:`~carmkin.errors.CalibrationError` naming an unknown or repeated one and the nearest valid name."""
    every = parameters(system)
    if names is None:
        return every
    if isinstance(names, str) or not hasattr(names, "__iter__"):
        raise CalibrationError(f"parameters must be a list of parameter names, got {names!r:.80}")
    names = list(names)
    by_name = {p.name: p for p in every}
    for name in names:
        if not isinstance(name, str):
            raise CalibrationError(f"parameters must be parameter names (text), got {name!r:.80}")
        if name not in by_name:
            hint = difflib.get_close_matches(str(name), list(by_name), n=1)
            raise CalibrationError(f"parameters: unknown parameter {name!r}"
                                   + (f"; did you mean {hint[0]!r}?" if hint else f"; valid: {', '.join(by_name)}"))
    if len(set(names)) != len(names) or not names:
        raise CalibrationError(f"parameters must name distinct parameters, at least one, got {names}")
    return tuple(p for p in every if p.name in names)


def values(system: CArmSystem, params) -> np.ndarray:
    """The values of ``params`` (:class:`Parameter` s of ``system``, e.g. from :func:`parameters`) in ``system``
    (mm, deg, px as each parameter's unit); CalibrationError naming an argument that is not one."""
    params = _own(system, params)
    carm, setup, calibration = system.carm, system.setup, system.calibration
    offsets = calibration.offsets(system.nq)
    u0, v0 = carm.intrinsics()[:2, 2]
    known = {"source_to_detector": carm.source_to_detector / MM, "principal_point_u": u0, "principal_point_v": v0,
             "detector_rotation": calibration.detector_rotation / DEG,
             "sag_cos": calibration.sag_cos / MM, "sag_sin": calibration.sag_sin / MM,
             **{name: getattr(carm, name) / MM for name in _LINKS},
             **{name: getattr(setup, name) / (DEG if name.startswith("gamma") else MM) for name in _SETUP},
             **{f"{name}_zero_offset": offset / (MM if prismatic else DEG)
                for name, prismatic, offset in zip(system.joint_names, system.prismatic, offsets)}}
    return np.array([known[p.name] for p in params])


def _own(system, params) -> tuple[Parameter, ...]:
    """``params`` as a tuple of :class:`Parameter` s of ``system``, or CalibrationError naming ``params``."""
    every = parameters(system)
    if isinstance(params, (str, bytes, Parameter)) or not hasattr(params, "__iter__"):
        raise CalibrationError(f"params must be a sequence of carmkin.calibration.Parameter (from parameters("
                               f"system)), got {params!r:.80}")
    params = tuple(params)
    for p in params:
        if not isinstance(p, Parameter) or p not in every:
            raise CalibrationError(f"params: {p!r:.80} is not a parameter of this system; see "
                                   "carmkin.calibration.parameters(system)")
    return params


def with_values(system: CArmSystem, params, x) -> CArmSystem:
    """``system`` with the parameters ``params`` set to the values ``x`` (mm, deg, px as each one's unit)."""
    given = {p.name: float(v) for p, v in zip(params, x)}
    carm, setup, calibration = system.carm, system.setup, system.calibration
    carm_changes = {name: given[name] * MM for name in (*_LINKS, "source_to_detector") if name in given}
    if "principal_point_u" in given or "principal_point_v" in given:
        u0, v0 = carm.intrinsics()[:2, 2]
        carm_changes["principal_point"] = (given.get("principal_point_u", u0), given.get("principal_point_v", v0))
    setup_changes = {name: given[name] * (DEG if name.startswith("gamma") else MM) for name in _SETUP if name in given}
    offsets = tuple(given.get(f"{name}_zero_offset", offset / (MM if prismatic else DEG)) * (MM if prismatic else DEG)
                    for name, prismatic, offset in zip(system.joint_names, system.prismatic,
                                                       calibration.offsets(system.nq)))
    return system.replace(
        carm=dataclasses.replace(carm, **carm_changes) if carm_changes else carm,
        setup=dataclasses.replace(setup, **setup_changes) if setup_changes else setup,
        calibration=Calibration(
            offsets, given.get("detector_rotation", calibration.detector_rotation / DEG) * DEG,
            given.get("sag_cos", calibration.sag_cos / MM) * MM, given.get("sag_sin", calibration.sag_sin / MM) * MM))


def adjust(system: CArmSystem, changes: dict) -> CArmSystem:
    """``system`` with parameters moved by the given amounts, e.g. ``adjust(system, {"orbital_zero_offset":
    0.3, "a1": 2.0})`` (deg, mm; each parameter's unit): the known perturbation of a simulated device."""
    require_system(system, CalibrationError)
    if not isinstance(changes, dict):
        raise CalibrationError(f"changes must be a dict {{parameter name: amount}}, got {changes!r:.80}")
    params = select(system, list(changes))
    amounts = np.array([real_scalar(changes[p.name], f"changes[{p.name!r}] ({p.unit})", error=CalibrationError)
                        for p in params])
    return with_values(system, params, values(system, params) + amounts)
