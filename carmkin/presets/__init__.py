"""Built-in presets: TOML files in ``carmkin/presets/`` with units in the key names (mm, deg)."""

from __future__ import annotations

import math
import tomllib
from importlib import resources
from pathlib import Path

import numpy as np

from carmkin.errors import InvalidParameterError, UnknownPresetError
from carmkin.model import kinematics
from carmkin.model.params import (
    BodyGeometry,
    CArmGeometry,
    JointRange,
    TableGeometry,
    TableSetup,
)
from carmkin.model.system import CArmSystem
from carmkin.model.table_joints import CHAIN_ORDER, KINDS, standard_joints

_MM = 1e-3
_CARM_JOINTS = {"vertical": _MM, "wigwag": math.pi / 180, "horizontal": _MM, "angular": math.pi / 180,
                "orbital": math.pi / 180}


def _preset_dir():
    return resources.files("carmkin.presets")


def list_presets() -> list[str]:
    """Names of the built-in presets (the preset files' stems), sorted."""
    return sorted(p.name[: -len(".toml")] for p in _preset_dir().iterdir() if p.name.endswith(".toml"))


def load_preset(name_or_path: str | Path) -> CArmSystem:
    """Load a built-in preset by name, or a preset file by path (``*.toml``)."""
    path = Path(name_or_path)
    if path.suffix == ".toml" and path.is_file():
        text, name = path.read_text(), path.stem
    else:
        name = str(name_or_path)
        if name not in list_presets():
            raise UnknownPresetError(f"unknown preset {name!r}; available: {', '.join(list_presets())}")
        text = (_preset_dir() / f"{name}.toml").read_text()
    return system_from_dict(_resolve_base(tomllib.loads(text)), default_name=name)


def _resolve_base(data: dict, depth: int = 0) -> dict:
    """Merge a preset over the preset named by its ``base`` key (sections merged key by key)."""
    if "base" not in data:
        return data
    if depth > 8:
        raise InvalidParameterError("preset: 'base' chain too deep (a cycle?)")
    base_name = data["base"]
    if base_name not in list_presets():
        raise UnknownPresetError(f"unknown base preset {base_name!r}; available: {', '.join(list_presets())}")
    merged = _resolve_base(tomllib.loads((_preset_dir() / f"{base_name}.toml").read_text()), depth + 1)
    return _merge(merged, {k: v for k, v in data.items() if k != "base"})


def _merge(base: dict, override: dict) -> dict:
    out = dict(base)
    for key, value in override.items():
        out[key] = _merge(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


def _get(section: dict, key: str, where: str):
    try:
        return section[key]
    except KeyError:
        raise InvalidParameterError(f"preset: missing key [{where}] {key}") from None


def _range(section: dict, joint: str, scale: float, unit: str, where: str, name: str | None = None) -> JointRange:
    lower = _get(section, f"{joint}_min_{unit}", where) * scale
    upper = _get(section, f"{joint}_max_{unit}", where) * scale
    return JointRange(lower, upper, name or joint)


def _carm(section: dict) -> CArmGeometry:
    ranges = {j: _range(section, j, s, "mm" if s == _MM else "deg", "carm") for j, s in _CARM_JOINTS.items()}
    pp = section.get("principal_point_px")
    return CArmGeometry(
        length_offset=_get(section, "length_offset_mm", "carm") * _MM,
        orbital_offset=_get(section, "orbital_offset_mm", "carm") * _MM,
        a1=section.get("a1_mm", 0.0) * _MM,
        a2=section.get("a2_mm", 0.0) * _MM,
        source_to_detector=_get(section, "source_to_detector_mm", "carm") * _MM,
        detector_width=_get(section, "detector_width_mm", "carm") * _MM,
        detector_height=_get(section, "detector_height_mm", "carm") * _MM,
        detector_columns=_get(section, "detector_columns", "carm"),
        detector_rows=_get(section, "detector_rows", "carm"),
        principal_point=tuple(pp) if pp is not None else None,
        **ranges,
    )


def _setup(section: dict, carm: CArmGeometry) -> TableSetup:
    if "table_origin_in_xray_mm" in section:
        T = kinematics.table_pose_from_xray(
            carm,
            np.asarray(section["table_origin_in_xray_mm"], float) * _MM,
            section.get("table_x_axis_in_xray", (1.0, 0.0, 0.0)),
            section.get("table_z_axis_in_xray", (0.0, 0.0, 1.0)),
        )
        return TableSetup.from_pose(T)
    deg = math.pi / 180
    return TableSetup(*(_get(section, f"gamma{i}_deg", "setup") * deg for i in (1, 2, 3)),
                      *(_get(section, f"D{i}_mm", "setup") * _MM for i in (1, 2, 3)))


def _mm3(values, key: str) -> tuple[float, float, float]:
    if len(values) != 3:
        raise InvalidParameterError(f"preset: {key} needs three values, got {len(values)}")
    return tuple(v * _MM for v in values)


def _table_joints(section: dict) -> tuple:
    """Extra table joints from ``[table.joints]``: ``<name>_min/max_mm|deg``, ``up_in_table``, ``pivot_mm``."""
    if not section:
        return ()
    ranges = {}
    for name in CHAIN_ORDER:
        prismatic = KINDS[name][0]
        unit, scale = ("mm", _MM) if prismatic else ("deg", math.pi / 180)
        if f"{name}_min_{unit}" in section or f"{name}_max_{unit}" in section:
            ranges[name] = _range(section, name, scale, unit, "table.joints")
    known = {f"{n}_{b}_{'mm' if KINDS[n][0] else 'deg'}" for n in CHAIN_ORDER for b in ("min", "max")}
    unknown = set(section) - known - {"up_in_table", "pivot_mm"}
    if unknown:
        raise InvalidParameterError(f"preset: unknown key(s) in [table.joints]: {sorted(unknown)}")
    return standard_joints(ranges, _get(section, "up_in_table", "table.joints"),
                           _mm3(_get(section, "pivot_mm", "table.joints"), "pivot_mm"))


def system_from_dict(data: dict, default_name: str = "custom") -> CArmSystem:
    """Build a :class:`CArmSystem` from a parsed preset (mm/deg keys, see ``siremobile-iso-c3d.toml``)."""
    carm = _carm(_get(data, "carm", "top level"))
    setup = _setup(_get(data, "setup", "top level"), carm)
    t = data.get("table", {})
    table_defaults = TableGeometry()
    table = TableGeometry(
        joints=_table_joints(t.get("joints", {})),
        translation=_range(t, "translation", _MM, "mm", "table", "table_translation")
        if "translation_min_mm" in t else table_defaults.translation,
        top_size=_mm3(t["top_size_mm"], "top_size_mm") if "top_size_mm" in t else table_defaults.top_size,
        top_center=_mm3(t["top_center_mm"], "top_center_mm") if "top_center_mm" in t else table_defaults.top_center,
    )
    b = data.get("body", {})
    body_kwargs = {}
    for key, value in b.items():
        if not key.endswith("_mm"):
            raise InvalidParameterError(f"preset: [body] {key} must end in _mm")
        field_name = key[: -len("_mm")]
        body_kwargs[field_name] = _mm3(value, key) if isinstance(value, list) else value * _MM
    try:
        body = BodyGeometry(**body_kwargs)
    except TypeError as exc:
        raise InvalidParameterError(f"preset: unknown key in [body]: {exc}") from None
    return CArmSystem(carm=carm, setup=setup, table=table, body=body, name=data.get("name", default_name))
