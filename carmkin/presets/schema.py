"""The preset format: every section and key a preset may hold, its type and its bounds in the preset's units.

A preset speaks mm and degrees with the unit in the key name; this module checks a parsed file against
:data:`SECTIONS` before anything is converted to SI, so that an error quotes the user's key, value and unit.
The bounds are those of :mod:`carmkin.model.bounds`, converted to mm and degrees.
"""

from __future__ import annotations

import re
import math
from dataclasses import dataclass

from carmkin.errors import InvalidParameterError, PresetError
from carmkin.model.bounds import (
    MAX_ANGLE,
    MAX_LENGTH,
    MAX_PIXELS,
    MAX_SETUP_DISTANCE,
    MIN_LENGTH,
    check_real,
)
from carmkin.model.motion import MAX_RATE, MIN_RATE
from carmkin.model.params import JOINT_NAMES, PRISMATIC
from carmkin.model.table_joints import CHAIN_ORDER, KINDS

#: One millimetre in metres and one degree in radians: the preset's units.
MM = 1e-3
DEG = math.pi / 180


@dataclass(frozen=True)
class Rule:
    """What one key holds: ``kind`` "number", "integer", "string" or "vector" (``size`` numbers), in ``unit``
    ("mm", "deg", "px" or "" for a direction), each number within ``[low, high]`` in that unit."""

    kind: str
    unit: str = ""
    low: float = -math.inf
    high: float = math.inf
    size: int = 0

    def expected(self) -> str:
        unit = f" ({self.unit})" if self.unit else ""
        return {"number": f"a number{unit}", "integer": "an integer", "string": "a string",
                "vector": f"a list of {self.size} numbers{unit}"}[self.kind]


def _length(positive: bool = False, size: int = 0) -> Rule:
    low = MIN_LENGTH / MM if positive else -MAX_LENGTH / MM
    return Rule("vector" if size else "number", "mm", low, MAX_LENGTH / MM, size)


_PRISMATIC_LIMIT = Rule("number", "mm", -MAX_LENGTH / MM, MAX_LENGTH / MM)
_REVOLUTE_LIMIT = Rule("number", "deg", -MAX_ANGLE / DEG, MAX_ANGLE / DEG)
_DIRECTION = Rule("vector", "", -1.0, 1.0, 3)
_STRING = Rule("string")


def _limits(joints: dict[str, bool]) -> dict[str, Rule]:
    """``<joint>_min_mm|deg`` and ``<joint>_max_mm|deg`` for joints given as {name: prismatic}."""
    return {f"{name}_{side}_{'mm' if prismatic else 'deg'}": _PRISMATIC_LIMIT if prismatic else _REVOLUTE_LIMIT
            for name, prismatic in joints.items() for side in ("min", "max")}


def _rates(joints: dict[str, bool]) -> dict[str, Rule]:
    """``<joint>_speed_mm_s|deg_s`` and ``<joint>_acceleration_mm_s2|deg_s2`` for joints given as {name:
    prismatic}, within [:data:`~carmkin.model.motion.MIN_RATE`, :data:`~carmkin.model.motion.MAX_RATE`]
    converted to mm or degrees."""
    rules = {}
    for name, prismatic in joints.items():
        unit, scale = ("mm", MM) if prismatic else ("deg", DEG)
        rules[f"{name}_speed_{unit}_s"] = Rule("number", f"{unit}/s", MIN_RATE / scale, MAX_RATE / scale)
        rules[f"{name}_acceleration_{unit}_s2"] = Rule("number", f"{unit}/s²", MIN_RATE / scale, MAX_RATE / scale)
    return rules


#: Every joint a preset may have, {name: prismatic}: the paper's six and a motorized table's.
ALL_JOINTS = {**dict(zip(JOINT_NAMES, PRISMATIC)), **{name: KINDS[name][0] for name in CHAIN_ORDER}}

#: Every section (dotted for sub-tables; "" is the top level) and the rule of each of its keys.
SECTIONS: dict[str, dict[str, Rule]] = {
    "": {"name": _STRING, "description": _STRING, "base": _STRING},
    "carm": {
        "length_offset_mm": _length(positive=True),
        "orbital_offset_mm": _length(positive=True),
        "a1_mm": _length(),
        "a2_mm": _length(),
        **_limits({"vertical": True, "wigwag": False, "horizontal": True, "angular": False, "orbital": False}),
        "source_to_detector_mm": _length(positive=True),
        "detector_width_mm": _length(positive=True),
        "detector_height_mm": _length(positive=True),
        "detector_columns": Rule("integer", "px", 1, MAX_PIXELS),
        "detector_rows": Rule("integer", "px", 1, MAX_PIXELS),
        "principal_point_px": Rule("vector", "px", -MAX_PIXELS, MAX_PIXELS, 2),
    },
    "setup": {
        "table_origin_in_xray_mm": _length(size=3),
        "table_x_axis_in_xray": _DIRECTION,
        "table_z_axis_in_xray": _DIRECTION,
        **{f"gamma{i}_deg": Rule("number", "deg", -MAX_ANGLE / DEG, MAX_ANGLE / DEG) for i in (1, 2, 3)},
        **{f"D{i}_mm": Rule("number", "mm", -MAX_SETUP_DISTANCE / MM, MAX_SETUP_DISTANCE / MM) for i in (1, 2, 3)},
    },
    "table": {
        **_limits({"translation": True}),
        "top_size_mm": _length(positive=True, size=3),
        "top_center_mm": _length(size=3),
    },
    "table.joints": {
        "up_in_table": _DIRECTION,
        "pivot_mm": _length(size=3),
        **_limits({name: KINDS[name][0] for name in CHAIN_ORDER}),
    },
    "mount": {  # a robot (or any chain) carrying the C-arm base: carmkin.model.mount_joints
        "base_origin_in_table_mm": _length(size=3),
        "base_x_axis_in_table": _DIRECTION,
        "base_z_axis_in_table": _DIRECTION,
        "carm_base_origin_mm": _length(size=3),
        "carm_base_x_axis": _DIRECTION,
        "carm_base_z_axis": _DIRECTION,
        "link_width_mm": _length(positive=True),
    },
    "mount.joints": {},
    "mount.joints.*": {  # one sub-table per joint, named by the joint, in the order from the floor up
        "axis": _DIRECTION,
        "point_mm": _length(size=3),
        "min_mm": _PRISMATIC_LIMIT, "max_mm": _PRISMATIC_LIMIT,  # a prismatic joint
        "min_deg": _REVOLUTE_LIMIT, "max_deg": _REVOLUTE_LIMIT,  # a revolute joint
    },
    # a calibrated device (carmkin.model.calibration.Calibration): reading + zero offset = model joint value
    "calibration": {
        **{f"{name}_zero_offset_{'mm' if prismatic else 'deg'}": _PRISMATIC_LIMIT if prismatic else _REVOLUTE_LIMIT
           for name, prismatic in {**dict(zip(JOINT_NAMES, PRISMATIC)),
                                   **{name: KINDS[name][0] for name in CHAIN_ORDER}}.items()},
        "detector_rotation_deg": _REVOLUTE_LIMIT,
        "sag_cos_mm": _PRISMATIC_LIMIT,
        "sag_sin_mm": _PRISMATIC_LIMIT,
    },
    "body": {
        "floor_height_mm": _length(),
        "cart_size_mm": _length(positive=True, size=3),
        "column_width_mm": _length(positive=True),
        "c_thickness_mm": _length(positive=True),
        "c_depth_mm": _length(positive=True),
        "source_housing_mm": _length(positive=True, size=3),
        "detector_thickness_mm": _length(positive=True),
        "mount": _STRING,
        "ceiling_height_mm": _length(),
        "c_radius_mm": _length(positive=True),
    },
    "motion": _rates(ALL_JOINTS),
}

#: The two alternative key sets of ``[setup]``: the table pose in the source frame, or the DH constants.
SETUP_FORMS = (("table_origin_in_xray_mm", "table_x_axis_in_xray", "table_z_axis_in_xray"),
               tuple(f"gamma{i}_deg" for i in (1, 2, 3)) + tuple(f"D{i}_mm" for i in (1, 2, 3)))


def _nearest(name: str, candidates) -> str:
    import difflib

    hint = difflib.get_close_matches(name, list(candidates), n=1)
    return f"; did you mean {hint[0]!r}?" if hint else f"; valid: {', '.join(sorted(candidates))}"


def check_file(data: dict, file: str) -> None:
    """Refuse unknown sections and keys (naming the nearest valid one), wrong types and out-of-bound values.

    ``data`` is one parsed file (before any ``base`` is merged in); ``file`` names it in the messages.
    """
    _check_section(data, "", file)


def _check_section(data: dict, section: str, file: str, sections: dict[str, dict[str, Rule]] = SECTIONS) -> None:
    rules = sections[section]
    subsections = {s.rpartition(".")[2] for s in sections if s and s.rpartition(".")[0] == section}
    where = f"[{section}]" if section else "the top level"
    for key, value in data.items():
        if not isinstance(key, str):  # a dict built by hand (TOML keys are strings): issue 41, difflib's TypeError
            raise PresetError(f"{file}: every key in {where} must be a string, got {key!r:.40} "
                              f"({type(key).__name__})")
        if "*" in subsections:  # sub-tables named by the user (the mount's joints), each checked by the "*" rules
            if not isinstance(value, dict):
                raise PresetError(f"{file}: {key!r} in [{section}] must be a table (a [{_join(section, key)}] section), "
                                  f"got {value!r}")
            _check_named(value, _join(section, "*"), _join(section, key), file)
        elif key in subsections:
            if not isinstance(value, dict):
                raise PresetError(f"{file}: [{_join(section, key)}] must be a table (a [section]), got {value!r}")
            _check_section(value, _join(section, key), file, sections)
        elif key in rules:
            check_value(rules[key], value, f"{file}: [{section}] {key}" if section else f"{file}: {key}")
        elif (rule := _named_joint_rule(section, key)) is not None:  # a mount's joint: the loader checks the name
            check_value(rule, value, f"{file}: [{section}] {key}")
        else:
            kind = "section" if isinstance(value, dict) else "key"
            raise PresetError(f"{file}: unknown {kind} {key!r} in {where}{_nearest(key, set(rules) | subsections)}")


#: The sections of a biplane preset (:mod:`carmkin.presets.biplane`): the two planes' presets, the lateral
#: plane's placement (the forms of ``[setup]``) and the rest configuration (joint values in mm and degrees).
BIPLANE_SECTIONS: dict[str, dict[str, Rule]] = {
    "": {"name": _STRING, "description": _STRING},
    "biplane": {"frontal": _STRING, "lateral": _STRING},
    "lateral": {},
    "lateral.setup": SECTIONS["setup"],
    "rest": {},
    "rest.table": {f"{name}_{'mm' if prismatic else 'deg'}": _PRISMATIC_LIMIT if prismatic else _REVOLUTE_LIMIT
                   for name, prismatic in {"table_translation": True,
                                           **{n: KINDS[n][0] for n in CHAIN_ORDER}}.items()},
    **{f"rest.{plane}": {f"{name}_{'mm' if prismatic else 'deg'}": _PRISMATIC_LIMIT if prismatic else _REVOLUTE_LIMIT
                         for name, prismatic in {"vertical": True, "wigwag": False, "horizontal": True,
                                                 "angular": False, "orbital": False}.items()}
       for plane in ("frontal", "lateral")},
}


def check_biplane_file(data: dict, file: str) -> None:
    """:func:`check_file` for a biplane preset (:data:`BIPLANE_SECTIONS`)."""
    _check_section(data, "", file, BIPLANE_SECTIONS)


#: Keys of ``[motion]`` and ``[calibration]`` for a joint the schema cannot list: a mount's joints are named by
#: the preset (``[mount.joints.<name>]``); the loader refuses a name that is no joint of the system.
_NAMED_JOINT_KEYS = {
    "motion": re.compile(r"(?P<joint>[A-Za-z]\w*?)_(?P<rest>(speed|acceleration)_(mm|deg)_s2?)"),
    "calibration": re.compile(r"(?P<joint>[A-Za-z]\w*?)_(?P<rest>zero_offset_(mm|deg))"),
}


def _named_joint_rule(section: str, key: str) -> Rule | None:
    """The rule of ``key`` in ``[motion]`` or ``[calibration]`` for a joint named by the preset (that of the same
    key of a standard joint with the same unit), or None."""
    match = _NAMED_JOINT_KEYS[section].fullmatch(key) if section in _NAMED_JOINT_KEYS else None
    if match is None:
        return None
    return next((rule for name, rule in SECTIONS[section].items() if name.endswith("_" + match["rest"])), None)


def _check_named(data: dict, section: str, name: str, file: str) -> None:
    """A user-named sub-table ``[name]`` against the rules of ``section`` (``"….*"``)."""
    rules = SECTIONS[section]
    for key, value in data.items():
        if key not in rules:
            kind = "section" if isinstance(value, dict) else "key"
            raise PresetError(f"{file}: unknown {kind} {key!r} in [{name}]{_nearest(key, rules)}")
        check_value(rules[key], value, f"{file}: [{name}] {key}")


def check_value(rule: Rule, value, what: str) -> None:
    """Refuse ``value`` unless it has the rule's type, shape and bounds (numbers in the rule's unit)."""
    def wrong() -> PresetError:
        got = f"the string {value!r}" if isinstance(value, str) else f"{type(value).__name__} {value!r}"
        return PresetError(f"{what} must be {rule.expected()}, got {got}")

    if rule.kind == "string":
        if not isinstance(value, str):
            raise wrong()
        return
    if rule.kind == "integer" and (isinstance(value, bool) or not isinstance(value, int)):
        raise wrong()
    numbers = value if rule.kind == "vector" else [value]
    if not isinstance(numbers, list) or (rule.kind == "vector" and len(numbers) != rule.size):
        raise wrong()
    for number in numbers:
        if isinstance(number, bool) or not isinstance(number, (int, float)):
            raise wrong()
        try:
            check_real(what, number, rule.low, rule.high, rule.unit)
        except InvalidParameterError as exc:
            raise PresetError(str(exc)) from None


def check_merged(data: dict, origin: dict[str, str], file: str) -> None:
    """Cross-key checks on a preset with its base merged in: each joint's min ≤ max, one ``[setup]`` form.

    ``origin`` maps dotted keys to the file each value came from (default: ``file``).
    """
    named = [(f"mount.joints.{joint}", SECTIONS["mount.joints.*"]) for joint in _section(data, "mount.joints")]
    for section, rules in [*SECTIONS.items(), *named]:
        values = _section(data, section)
        for key in rules:
            if "_min_" not in f"_{key}" or key not in values:  # <joint>_min_<unit>, or min_<unit> of a named joint
                continue
            upper = f"_{key}".replace("_min_", "_max_")[1:]
            unit = key.rpartition("_")[2]
            if upper in values and values[key] > values[upper]:
                raise PresetError(f"{origin.get(_join(section, key), file)}: [{section}] {key} = {values[key]:g} {unit} "
                                  f"> {upper} = {values[upper]:g} {unit}")
    setup = data.get("setup", {})
    used = [form for form in SETUP_FORMS if any(k in setup for k in form)]
    if len(used) > 1:
        where = next((origin[f"setup.{key}"] for key in setup if f"setup.{key}" in origin), file)
        raise PresetError(f"{where}: [setup] mixes the table pose "
                          f"({', '.join(SETUP_FORMS[0])}) with the DH constants ({', '.join(SETUP_FORMS[1])}); "
                          "give one of the two")


def _section(data: dict, section: str) -> dict:
    for part in section.split(".") if section else ():
        data = data.get(part, {})
    return data


def _join(section: str, key: str) -> str:
    return f"{section}.{key}" if section else key
