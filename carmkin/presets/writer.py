"""Write a :class:`~carmkin.model.system.CArmSystem` as preset TOML (mm, deg), the inverse of loading it.

``parse_preset(to_toml(system))`` gives back ``system`` up to the rounding of the unit conversions
(a few ulp). The table setup is written as its DH constants (γ1..γ3, D1..D3); a motorized table's joints
must be those of :func:`~carmkin.model.table_joints.standard_joints` (one ``up`` axis, one pivot).
"""

from __future__ import annotations

import math
from dataclasses import fields
from pathlib import Path

from carmkin.errors import PresetError
from carmkin.model.params import PRISMATIC, BodyGeometry, JointRange
from carmkin.model.system import CArmSystem
from carmkin.model.table_joints import standard_joints

from .schema import DEG, MM


def to_toml(system: CArmSystem) -> str:
    """The preset text of ``system``: ``[carm]``, ``[setup]`` (DH constants), ``[table]``, ``[body]``,
    ``[calibration]`` when the system carries a calibration that is not nominal, and ``[motion]`` when it has
    joint speeds."""
    import tomlkit  # only here: loading does not need it

    if not isinstance(system, CArmSystem):
        raise PresetError(f"to_toml: system must be a CArmSystem, got {type(system).__name__}")
    carm = system.carm
    carm_keys = {f"{name}_mm": getattr(carm, name) / MM for name in ("length_offset", "orbital_offset", "a1", "a2")}
    for joint_range, prismatic in zip(carm.joint_ranges, PRISMATIC[1:]):
        carm_keys.update(_limits(joint_range, prismatic))
    carm_keys.update({f"{name}_mm": getattr(carm, name) / MM
                      for name in ("source_to_detector", "detector_width", "detector_height")})
    carm_keys.update(detector_columns=carm.detector_columns, detector_rows=carm.detector_rows)
    if carm.principal_point is not None:
        carm_keys["principal_point_px"] = list(carm.principal_point)
    setup = system.setup
    setup_keys = {**{f"gamma{i}_deg": math.degrees(getattr(setup, f"gamma{i}")) for i in (1, 2, 3)},
                  **{f"D{i}_mm": getattr(setup, f"D{i}") / MM for i in (1, 2, 3)}}
    table = system.table
    table_keys = {**_limits(table.translation, True, "translation"),
                  "top_size_mm": [v / MM for v in table.top_size],
                  "top_center_mm": [v / MM for v in table.top_center]}
    if table.joints:
        table_keys["joints"] = _table_joints(table.joints)
    body = {f.name if isinstance(value, str) else f"{f.name}_mm":
            value if isinstance(value, str) else [v / MM for v in value] if isinstance(value, tuple) else value / MM
            for f in fields(BodyGeometry) for value in (getattr(system.body, f.name),) if value is not None}
    document = {"name": system.name, "carm": carm_keys, "setup": setup_keys, "table": table_keys, "body": body}
    if system.mount.joints:
        document["mount"] = _mount(system)
        if "carm_base_origin_mm" in document["mount"]:
            del document["setup"]  # derived from the mount's C-arm base at rest, as the preset stated it
    if not system.calibration.is_nominal:
        document["calibration"] = _calibration(system)
    if system.motion is not None:
        document["motion"] = _motion(system)
    return tomlkit.dumps(document)


def save_preset(system: CArmSystem, path: str | Path) -> Path:
    """Write ``system`` as a preset file (``*.toml``) that :func:`~carmkin.presets.load_preset` reads back."""
    path = Path(path)
    if path.suffix != ".toml":
        raise PresetError(f"save_preset: path must end in .toml, got {str(path)!r}")
    path.write_text(to_toml(system))
    return path


def _limits(joint_range: JointRange, prismatic: bool, name: str | None = None) -> dict[str, float]:
    name = name or joint_range.name
    unit, convert = ("mm", _mm) if prismatic else ("deg", math.degrees)
    return {f"{name}_min_{unit}": convert(joint_range.lower), f"{name}_max_{unit}": convert(joint_range.upper)}


def _mm(metres: float) -> float:
    return metres / MM


def _mount(system: CArmSystem) -> dict:
    """``[mount]`` and its ``[mount.joints.<name>]`` (twists in the robot base frame, as a preset states them);
    the C-arm base at rest (``carm_base_*``) when the system's setup is the one it gives."""
    from carmkin.presets import MOUNT_CARM_BASE, _mount_setup  # (the loader's own derivation, not a second one)

    mount = system.mount
    keys = {"base_origin_in_table_mm": [v / MM for v in mount.base_origin],
            "base_x_axis_in_table": list(mount.base_x_axis), "base_z_axis_in_table": list(mount.base_z_axis),
            "link_width_mm": mount.link_width / MM}
    if mount.carm_base is not None:
        origin, x, z = mount.carm_base
        stated = dict(zip(MOUNT_CARM_BASE, ([v / MM for v in origin], list(x), list(z))))
        if _mount_setup(stated, mount)[0] == system.setup:
            keys.update(stated)
    keys["joints"] = {joint.name: {"axis": list(joint.axis), "point_mm": [v / MM for v in joint.point],
                                   **{key.partition("_")[2]: value for key, value in
                                      _limits(joint.range, joint.prismatic, "joint").items()}}
                      for joint in mount.joints}
    return keys


def _calibration(system: CArmSystem) -> dict[str, float]:
    """``[calibration]``: every joint's zero offset (mm, deg), the detector rotation (deg) and the sag (mm)."""
    calibration = system.calibration
    keys = {f"{name}_zero_offset_{'mm' if prismatic else 'deg'}": (_mm if prismatic else math.degrees)(offset)
            for name, prismatic, offset in zip(system.joint_names, system.prismatic, calibration.offsets(system.nq))}
    return {**keys, "detector_rotation_deg": math.degrees(calibration.detector_rotation),
            "sag_cos_mm": _mm(calibration.sag_cos), "sag_sin_mm": _mm(calibration.sag_sin)}


def _table_joints(joints) -> dict:
    """``[table.joints]`` of standard joints: ranges, ``up_in_table`` and ``pivot_mm``."""
    by_name = {joint.name: joint for joint in joints}
    up = next((by_name[name].axis for name in ("table_rotation", "table_height") if name in by_name), (0.0, -1.0, 0.0))
    pivot = joints[0].point
    if standard_joints({joint.name: joint.range for joint in joints}, up, pivot) != tuple(joints):
        raise PresetError("to_toml: the table joints are not the standard ones (one up axis, one pivot) that "
                          "a preset describes")
    keys = {"up_in_table": list(up), "pivot_mm": [v / MM for v in pivot]}
    for joint in joints:
        keys.update(_limits(joint.range, joint.prismatic))
    return keys


def _motion(system: CArmSystem) -> dict[str, float]:
    """``[motion]``: each joint's speed and (when known) acceleration in mm or degrees per s and s²."""
    keys = {}
    for joint, prismatic in zip(system.motion.joints, system.prismatic):
        unit, convert = ("mm", _mm) if prismatic else ("deg", _deg)
        keys[f"{joint.name}_speed_{unit}_s"] = convert(joint.speed)
        if joint.acceleration is not None:
            keys[f"{joint.name}_acceleration_{unit}_s2"] = convert(joint.acceleration)
    return keys


def _deg(radians: float) -> float:
    """Degrees by dividing by the loader's factor (π/180), so that the loader's product gives the value back."""
    return radians / DEG
