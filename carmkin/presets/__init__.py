"""Presets: TOML files with units in the key names (mm, deg), checked strictly against :mod:`.schema`.

Built-in presets live in ``carmkin/presets/``; :func:`load_preset` also reads a user's ``.toml`` file and
:func:`parse_preset` a TOML text. Each value's trailing comment is its provenance (:func:`preset_provenance`):
``# source: ...`` for a number taken from a cited source, ``# assumption: ...`` for one the source does not
give. See docs/PRESETS.md.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from carmkin.errors import InvalidParameterError, PresetError, UnknownPresetError
from carmkin.model import kinematics
from carmkin.model.calibration import Calibration
from carmkin.model.motion import JointMotion, Motion
from carmkin.model.mount_joints import AXIS_TOLERANCE
from carmkin.model.params import (
    BodyGeometry,
    CArmGeometry,
    JointRange,
    TableGeometry,
    TableSetup,
)
from carmkin.model.mount_joints import MountGeometry, MountJoint
from carmkin.model.system import CArmSystem
from carmkin.model.table_joints import CHAIN_ORDER, KINDS, standard_joints
from carmkin.transforms import inverse

from . import biplane as _biplane
from .schema import SETUP_FORMS as _SETUP_FORMS
from .schema import check_file, check_merged
from .writer import save_preset, to_toml

_MM = 1e-3
_CARM_JOINTS = {"vertical": _MM, "wigwag": math.pi / 180, "horizontal": _MM, "angular": math.pi / 180,
                "orbital": math.pi / 180}
#: Longest chain of ``base = "..."`` inheritance followed (a longer one is taken for a cycle).
MAX_BASE_DEPTH = 8


@dataclass(frozen=True)
class Provenance:
    """Where one preset value came from.

    Attributes:
        file: the path of the preset file that set the value (a base's keys name the base's file).
        key: the dotted key, e.g. ``"carm.a1_mm"``.
        kind: ``"source"`` (comment ``# source: ...``, a cited source), ``"assumption"`` (``# assumption:
            ...``), ``"comment"`` (any other comment) or ``"none"`` (no comment).
        note: the comment's text after the kind, e.g. ``'dissertation Table 4.4 "length offset: 1350 mm"'``.
    """

    file: str
    key: str
    kind: str
    note: str


def _preset_dir() -> Path:
    """The built-in preset files' folder: this package's own (package data; no importlib.resources, whose import
    costs ``import carmkin`` tempfile and random)."""
    return Path(__file__).resolve().parent


def list_presets() -> list[str]:
    """Names of the built-in presets (the preset files' stems), sorted."""
    return sorted(p.name[: -len(".toml")] for p in _preset_dir().iterdir() if p.name.endswith(".toml"))


def load_preset(name_or_path: str | Path) -> CArmSystem:
    """Load a built-in preset by name, or a preset file by path (``*.toml``).

    A biplane preset (:mod:`carmkin.presets.biplane`) loads as its frontal plane, named after the biplane
    (:func:`read_biplane` reads both planes).

    Raises :class:`~carmkin.errors.PresetError` (naming the file, the key and the nearest valid name) for
    malformed TOML, an unknown section or key, a wrong type or a value out of bounds, and
    :class:`~carmkin.errors.UnknownPresetError` for an unknown preset or ``base``.
    """
    _check_name(name_or_path)
    data, origin, label = _read(name_or_path)
    return _build(data, origin, label)


def _check_name(name_or_path) -> None:
    if not isinstance(name_or_path, (str, os.PathLike)) or (
            isinstance(name_or_path, os.PathLike) and not isinstance(os.fspath(name_or_path), str)):
        raise PresetError(f"preset must be a preset name ({', '.join(list_presets())}) or the path of a .toml "
                          f"file, got {name_or_path!r:.80}")


def parse_preset(text: str, source: str = "<text>") -> CArmSystem:
    """Build a system from the text of a preset file; ``source`` names it in error messages."""
    if not isinstance(text, str) or not isinstance(source, str):
        raise PresetError(f"text and source must be strings (the TOML text and its name), got {text!r:.40} and "
                          f"{source!r:.40}")
    return _build(*_resolve_base(*_parse(text, source), source), source)


def system_from_dict(data: dict, default_name: str = "custom", source: str = "<dict>") -> CArmSystem:
    """Build a :class:`CArmSystem` from a parsed preset (mm/deg keys, see ``siremobile-iso-c3d.toml``),
    checked as strictly as a file; ``source`` names it in error messages."""
    if not isinstance(data, dict):
        raise PresetError(f"{source}: a preset must be a dict of sections (as parsed from TOML), got {data!r:.80}")
    if not isinstance(default_name, str) or not isinstance(source, str):
        raise PresetError(f"default_name and source must be strings, got {default_name!r:.40} and {source!r:.40}")
    check_file(data, source)
    return _build(*_resolve_base(data, _origin(data, source), source), source, default_name)


def preset_provenance(name_or_path: str | Path) -> dict[str, Provenance]:
    """Provenance of every value of a preset (its base's included), by dotted key (``"carm.a1_mm"``).

    Read from each key's trailing comment in the file that set it (parsed with tomlkit, which keeps them).
    """
    _check_name(name_or_path)
    label = _read_label(str(name_or_path))
    if _biplane.is_biplane(_toml(_text(label), label)):
        return _biplane_provenance(label)
    _, origin, _ = _read(name_or_path)
    comments = {file: _comments(_text(file)) for file in set(origin.values())}
    provenance = {}
    for key, file in origin.items():
        provenance[key] = _provenance(file, key, comments[file].get(key, ""))
    return provenance


def _provenance(file: str, key: str, comment: str) -> Provenance:
    """The provenance of ``key`` set in ``file`` with its trailing ``comment`` (without ``#``)."""
    kind, _, note = comment.partition(":")
    kind = kind.strip().lower()
    if kind not in ("source", "assumption"):
        kind, note = ("comment" if comment else "none"), comment
    return Provenance(file, key, kind, note.strip())


def _biplane_provenance(label: str) -> dict[str, Provenance]:
    """A biplane preset's own keys, then each plane's keys prefixed ``frontal.`` / ``lateral.``."""
    data, planes = _biplane_file(label)
    own = _origin(data, label)
    comments = _comments(_text(label))
    out = {key: _provenance(label, key, comments.get(key, "")) for key in own}
    placed = "setup" in data.get("lateral", {})  # [lateral.setup] replaces the lateral preset's [setup]
    for plane, value in planes.items():
        for key, p in preset_provenance(value).items():
            if key not in ("name", "description") and not (plane == "lateral" and placed and key.startswith("setup.")):
                out[f"{plane}.{key}"] = Provenance(p.file, f"{plane}.{key}", p.kind, p.note)
    return out


def _build(data: dict, origin: dict[str, str], label: str, default_name: str | None = None) -> CArmSystem:
    check_merged(data, origin, label)
    try:
        return _system(data, default_name or Path(label).stem)
    except PresetError as exc:  # named by the file (or text) it came from
        if str(exc).startswith(label):
            raise
        raise PresetError(f"{label}: {exc}") from None
    except InvalidParameterError as exc:  # a cross-key check of the model (e.g. the setup axes)
        raise PresetError(f"{label}: {exc}") from None


def _read(name_or_path: str | Path) -> tuple[dict, dict[str, str], str]:
    """The merged values of a preset, the file each dotted key came from, and the preset's file label."""
    path = Path(name_or_path)
    if path.suffix == ".toml":
        if not path.is_file():
            raise UnknownPresetError(f"no preset file {str(path)!r}")
        label = str(path)
    else:
        label = _builtin_file(str(name_or_path), "preset")
    text = _text(label)
    if _biplane.is_biplane(_toml(text, label)):  # a biplane preset reads as its frontal plane
        data, plane = _biplane_file(label)
        merged, origin, _ = _read(plane["frontal"])
        return {**merged, "name": data.get("name", Path(label).stem)}, origin, label
    return (*_resolve_base(*_parse(text, label), label), label)


def _text(label: str) -> str:
    """A preset file's text (TOML is UTF-8); a file that is not UTF-8 is a :class:`PresetError` naming it."""
    try:
        return Path(label).read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise PresetError(f"{label}: not a UTF-8 text file (TOML is UTF-8): byte {exc.start}: {exc.reason}") from None


def _toml(text: str, label: str) -> dict:
    import tomllib  # on first use: import carmkin stays light

    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:  # the message says "(at line L, column C)"
        raise PresetError(f"{label}: malformed TOML: {exc}") from None
    except ValueError as exc:  # an integer of more digits than Python converts (issue 41: 5000 digits)
        raise PresetError(f"{label}: a value TOML cannot hold as a number: {str(exc).split(';')[0]}") from None


def _biplane_file(label: str) -> tuple[dict, dict[str, str]]:
    """A biplane preset's checked values and its planes' preset names or paths (relative paths resolved
    against the biplane file's folder)."""
    data = _toml(_text(label), label)
    _biplane.check(data, label)
    planes = {}
    for plane, value in data[_biplane.SECTION].items():
        path = Path(value)
        planes[plane] = str(path if path.is_absolute() or path.suffix != ".toml" else Path(label).parent / path)
        if _biplane.is_biplane(_toml(_text(_read_label(planes[plane])), planes[plane])):
            raise PresetError(f"{label}: [biplane] {plane} = {value!r} is itself a biplane preset; name a one-plane "
                              "preset")
    return data, planes


def _read_label(name_or_path: str) -> str:
    path = Path(name_or_path)
    if path.suffix == ".toml":
        if not path.is_file():
            raise UnknownPresetError(f"no preset file {str(path)!r}")
        return str(path)
    return _builtin_file(name_or_path, "preset")


def biplane_planes(name_or_path: str | Path) -> dict[str, str] | None:
    """``{"frontal": ..., "lateral": ...}``: the one-plane presets (names or paths) a biplane preset names, or
    ``None`` for a one-plane preset (which :func:`load_preset` reads whole). Lets a caller that models one plane
    refuse a biplane preset rather than drop its lateral plane (the command line does)."""
    _check_name(name_or_path)
    label = _read_label(str(name_or_path))
    if not _biplane.is_biplane(_toml(_text(label), label)):
        return None
    return _biplane_file(label)[1]


def read_biplane(name_or_path: str | Path):
    """Both planes of a biplane preset (built-in name or ``.toml`` path) as a
    :class:`~carmkin.model.biplane.Biplane`: the frontal plane's preset, the lateral plane's preset placed by
    ``[lateral.setup]`` (default: its own ``[setup]``), the rest configuration of ``[rest.*]``. The planes must
    share one table and one isocentre (:class:`~carmkin.errors.BiplaneError` naming the field). The planes'
    clearance at rest is checked by :func:`carmkin.biplane.load_biplane`, which calls this."""
    _check_name(name_or_path)
    label = _read_label(str(name_or_path))
    if not _biplane.is_biplane(_toml(_text(label), label)):
        raise PresetError(f"{label}: not a biplane preset (it has no [biplane] section); carmkin.load_preset reads it")
    data, planes = _biplane_file(label)
    frontal = load_preset(planes["frontal"])
    lateral = load_preset(planes["lateral"])
    if "setup" in data.get("lateral", {}):
        section = data["lateral"]["setup"]
        used = [form for form in _SETUP_FORMS if any(k in section for k in form)]
        if len(used) > 1:
            raise PresetError(f"{label}: [lateral.setup] mixes the table pose with the DH constants; give one of the two")
        try:
            lateral = lateral.replace(setup=_setup(section, lateral.carm))
        except (PresetError, InvalidParameterError) as exc:
            raise PresetError(f"{label}: [lateral.setup] {exc}") from None
    return _biplane.assemble(data, label, frontal, lateral)


def _builtin_file(name: str, what: str) -> str:
    """The path of the built-in preset ``name`` (its file label in messages and provenance)."""
    names = list_presets()
    if name not in names:
        import difflib

        hint = difflib.get_close_matches(name, names, n=1)
        raise UnknownPresetError(f"unknown {what} {name!r}" + (f"; did you mean {hint[0]!r}?" if hint else "")
                                 + f"; available: {', '.join(names)}")
    return str(_preset_dir() / f"{name}.toml")


def _parse(text: str, label: str) -> tuple[dict, dict[str, str]]:
    """One file's values, checked by :func:`.schema.check_file`, and its dotted keys mapped to ``label``."""
    data = _toml(text, label)
    check_file(data, label)
    return data, _origin(data, label)


def _origin(data: dict, label: str, prefix: str = "") -> dict[str, str]:
    """Every dotted key of ``data`` (leaves only) mapped to ``label``."""
    out = {}
    for key, value in data.items():
        out.update(_origin(value, label, f"{prefix}{key}.") if isinstance(value, dict) else {prefix + key: label})
    return out


def _comments(text: str) -> dict[str, str]:
    """Each dotted key's trailing comment (without ``#``) in a preset's text."""
    import tomlkit  # only here: comments and writing need it, loading does not

    out = {}

    def walk(table, prefix: str) -> None:
        for key, item in table.items():
            if isinstance(item, dict):
                walk(item, f"{prefix}{key}.")
            else:
                out[prefix + key] = item.trivia.comment.lstrip("#").strip()

    walk(tomlkit.parse(text), "")
    return out


def _resolve_base(data: dict, origin: dict[str, str], label: str, depth: int = 0) -> tuple[dict, dict[str, str]]:
    """Merge a preset over the built-in preset named by its ``base`` key; also merge the keys' origins.

    Sections merge key by key, except ``[setup]``, which a preset replaces whole (its two forms are
    alternatives, :data:`.schema.SETUP_FORMS`); ``name`` and ``description`` are not inherited.
    """
    if "base" not in data:
        return data, origin
    if depth >= MAX_BASE_DEPTH:
        raise PresetError(f"{label}: 'base' chain longer than {MAX_BASE_DEPTH} (a cycle?)")
    base_label = _builtin_file(data["base"], "base preset")
    base, base_origin = _resolve_base(*_parse(_text(base_label), base_label), base_label, depth + 1)
    replaces_setup = "setup" in data or any(key in data.get("mount", {}) for key in MOUNT_CARM_BASE)
    dropped = ("name", "description", "setup") if replaces_setup else ("name", "description")
    base = {k: v for k, v in base.items() if k not in dropped}
    base_origin = {k: v for k, v in base_origin.items() if k.partition(".")[0] in base}
    merged = _merge(base, {k: v for k, v in data.items() if k != "base"})
    return merged, {**base_origin, **{k: v for k, v in origin.items() if k != "base"}}


def _merge(base: dict, override: dict) -> dict:
    out = dict(base)
    for key, value in override.items():
        out[key] = _merge(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


def _get(section: dict, key: str, where: str):
    """``section[key]``, or a :class:`PresetError` naming ``[where] key``: a key that changes the geometry has no
    default unless docs/PRESETS.md states one (:data:`OPTIONAL_KEYS`)."""
    try:
        return section[key]
    except KeyError:
        raise PresetError(f"missing key [{where}] {key}") from None


#: The keys a preset may leave out, each with the default docs/PRESETS.md states (dotted, as in
#: :func:`preset_provenance`): every other key that the loader reads is required (``missing key [section] key``),
#: so that an incomplete file never loads with a geometry of silent defaults. ``[calibration]`` (absent = 0),
#: the accelerations of ``[motion]`` (absent = not known), ``principal_point_px`` (absent = the detector
#: centre) and ``c_radius_mm`` (absent = the source to orbital axis distance) are optional as well;
#: ``ceiling_height_mm`` is required with ``mount = "ceiling"`` (unused by a floor stand).
OPTIONAL_KEYS = {"carm.a1_mm": 0.0, "carm.a2_mm": 0.0, "body.mount": BodyGeometry.mount}
#: The keys of ``[body]`` that every preset gives (mm): the collision and visual primitives.
BODY_KEYS = ("floor_height_mm", "cart_size_mm", "column_width_mm", "c_thickness_mm", "c_depth_mm",
             "source_housing_mm", "detector_thickness_mm")


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
        a1=section.get("a1_mm", OPTIONAL_KEYS["carm.a1_mm"]) * _MM,
        a2=section.get("a2_mm", OPTIONAL_KEYS["carm.a2_mm"]) * _MM,
        source_to_detector=_get(section, "source_to_detector_mm", "carm") * _MM,
        detector_width=_get(section, "detector_width_mm", "carm") * _MM,
        detector_height=_get(section, "detector_height_mm", "carm") * _MM,
        detector_columns=_get(section, "detector_columns", "carm"),
        detector_rows=_get(section, "detector_rows", "carm"),
        principal_point=tuple(pp) if pp is not None else None,
        **ranges,
    )


def _setup(section: dict, carm: CArmGeometry) -> TableSetup:
    if any(key in section for key in _SETUP_FORMS[0]):
        _get(section, "table_origin_in_xray_mm", "setup")
        T = kinematics.table_pose_from_xray(
            carm,
            np.asarray(section["table_origin_in_xray_mm"], float) * _MM,
            _get(section, "table_x_axis_in_xray", "setup"),
            _get(section, "table_z_axis_in_xray", "setup"),
        )
        return TableSetup.from_pose(T)
    deg = math.pi / 180
    return TableSetup(*(_get(section, f"gamma{i}_deg", "setup") * deg for i in (1, 2, 3)),
                      *(_get(section, f"D{i}_mm", "setup") * _MM for i in (1, 2, 3)))


def _mm3(values, key: str) -> tuple[float, float, float]:
    if len(values) != 3:
        raise InvalidParameterError(f"preset: {key} needs three values, got {len(values)}")
    return tuple(v * _MM for v in values)


def _unit(prismatic: bool) -> tuple[str, float]:
    """A joint's preset unit and its factor to SI: ``("mm", 1e-3)`` (prismatic) or ``("deg", π/180)``."""
    return ("mm", _MM) if prismatic else ("deg", math.pi / 180)


def _table_joints(section: dict) -> tuple:
    """Extra table joints from ``[table.joints]``: ``<name>_min/max_mm|deg``, ``up_in_table``, ``pivot_mm``."""
    if not section:
        return ()
    ranges = {}
    for name in CHAIN_ORDER:
        unit, scale = _unit(KINDS[name][0])
        if f"{name}_min_{unit}" in section or f"{name}_max_{unit}" in section:
            ranges[name] = _range(section, name, scale, unit, "table.joints")
    return standard_joints(ranges, _get(section, "up_in_table", "table.joints"),
                           _mm3(_get(section, "pivot_mm", "table.joints"), "pivot_mm"))


#: Keys of ``[mount]`` that place the C-arm base on the robot at rest; given, they replace ``[setup]``.
MOUNT_CARM_BASE = ("carm_base_origin_mm", "carm_base_x_axis", "carm_base_z_axis")


def _mount(section: dict, carm_base=None) -> MountGeometry:
    """The mount of ``[mount]`` and its ``[mount.joints.<name>]`` sub-tables (floor up, in file order)."""
    if not section:
        return MountGeometry()
    joints = []
    for name, keys in section.get("joints", {}).items():
        where = f"mount.joints.{name}"
        kinds = [unit for unit in ("mm", "deg") if f"min_{unit}" in keys or f"max_{unit}" in keys]
        if len(kinds) != 1:
            raise PresetError(f"[{where}] needs min_deg and max_deg (a revolute joint) or min_mm and max_mm (a "
                              f"prismatic one), got {sorted(keys)}")
        unit = kinds[0]
        axis = _get(keys, "axis", where)
        if abs(math.fsum(v * v for v in axis) - 1.0) > 2 * AXIS_TOLERANCE:
            raise PresetError(f"[{where}] axis must be a unit vector, got {axis} (length "
                              f"{math.sqrt(math.fsum(v * v for v in axis)):.12g})")
        scale = _MM if unit == "mm" else math.pi / 180
        joint_range = JointRange(_get(keys, f"min_{unit}", where) * scale, _get(keys, f"max_{unit}", where) * scale, name)
        joints.append(MountJoint(name, unit == "mm", tuple(axis), _mm3(_get(keys, "point_mm", where), "point_mm"),
                                 joint_range))
    if not joints:
        raise PresetError("[mount] needs its joints: one [mount.joints.<name>] table per joint, floor up")
    return MountGeometry(
        tuple(joints),
        base_origin=_mm3(_get(section, "base_origin_in_table_mm", "mount"), "base_origin_in_table_mm"),
        base_x_axis=tuple(_get(section, "base_x_axis_in_table", "mount")),
        base_z_axis=tuple(_get(section, "base_z_axis_in_table", "mount")),
        link_width=_get(section, "link_width_mm", "mount") * _MM, carm_base=carm_base)


def _mount_setup(section: dict, mount: MountGeometry) -> tuple[TableSetup, tuple]:
    """The setup of a mounted C-arm from its base at rest in the robot base frame (``[mount] carm_base_*``):
    eq. 4.3's common normals of the table frame seen from that base, ``inverse(T_0B · T_BC)``; and that base
    as :attr:`MountGeometry.carm_base <carmkin.model.mount_joints.MountGeometry.carm_base>`."""
    missing = [key for key in MOUNT_CARM_BASE if key not in section]
    if missing:
        raise PresetError(f"[mount] gives the C-arm base at rest with {', '.join(MOUNT_CARM_BASE)}; missing "
                          f"{', '.join(missing)}")
    x, z = (np.asarray(section[key], dtype=float) for key in MOUNT_CARM_BASE[1:])
    if abs(np.linalg.norm(x) - 1) > AXIS_TOLERANCE or abs(np.linalg.norm(z) - 1) > AXIS_TOLERANCE or abs(x @ z) > AXIS_TOLERANCE:
        raise PresetError(f"[mount] carm_base_x_axis and carm_base_z_axis must be orthonormal, got {x.tolist()} and "
                          f"{z.tolist()}")
    T_BC = np.eye(4)
    T_BC[:3, :3] = np.column_stack((x, np.cross(z, x), z))
    T_BC[:3, 3] = np.asarray(section["carm_base_origin_mm"], dtype=float) * _MM
    carm_base = (tuple(T_BC[:3, 3]), tuple(x), tuple(z))
    return TableSetup.from_pose(inverse(mount.base_pose @ T_BC)), carm_base


def _system(data: dict, default_name: str) -> CArmSystem:
    """The system of a checked, merged preset."""
    carm = _carm(_get(data, "carm", "top level"))
    mount_section = data.get("mount", {})
    mount = _mount(mount_section)
    if any(key in mount_section for key in MOUNT_CARM_BASE):
        if "setup" in data:
            raise PresetError(f"[mount] {', '.join(MOUNT_CARM_BASE)} place the C-arm base and replace [setup]; "
                              "give one of the two")
        setup, carm_base = _mount_setup(mount_section, mount)
        mount = _mount(mount_section, carm_base)
    else:
        setup = _setup(_get(data, "setup", "top level"), carm)
    t = _get(data, "table", "top level")
    table = TableGeometry(
        joints=_table_joints(t.get("joints", {})),
        translation=_range(t, "translation", _MM, "mm", "table", "table_translation"),
        top_size=_mm3(_get(t, "top_size_mm", "table"), "top_size_mm"),
        top_center=_mm3(_get(t, "top_center_mm", "table"), "top_center_mm"),
    )
    body = _body(_get(data, "body", "top level"))
    system = CArmSystem(carm=carm, setup=setup, table=table, body=body, name=data.get("name", default_name),
                        mount=mount)
    if "calibration" in data:
        system = system.replace(calibration=_calibration(data["calibration"], system))
    return system.replace(motion=_motion(data["motion"], system)) if "motion" in data else system


def _body(section: dict) -> BodyGeometry:
    """``[body]``: every key of :data:`BODY_KEYS`, ``ceiling_height_mm`` with a ceiling mount, the optional
    ``mount`` and ``c_radius_mm``."""
    required = BODY_KEYS + (("ceiling_height_mm",) if section.get("mount") == "ceiling" else ())
    for key in required:
        _get(section, key, "body")
    return BodyGeometry(**{key.removesuffix("_mm"): value if isinstance(value, str) else
                           _mm3(value, key) if isinstance(value, list) else value * _MM
                           for key, value in section.items()})


def _calibration(section: dict, system: CArmSystem) -> Calibration:
    """``[calibration]``: ``<joint>_zero_offset_mm|deg`` (absent = 0), ``detector_rotation_deg``, ``sag_*_mm``."""
    units = {name: _unit(prismatic) for name, prismatic in zip(system.joint_names, system.prismatic)}
    offsets = [section.get(f"{name}_zero_offset_{unit}", 0.0) * scale for name, (unit, scale) in units.items()]
    known = {f"{name}_zero_offset_{unit}" for name, (unit, _) in units.items()}
    for key in section:
        if "_zero_offset_" in key and key not in known:
            raise PresetError(f"[calibration] {key}: the system has no such joint (joints: "
                              f"{', '.join(system.joint_names)})")
    return Calibration(tuple(offsets), math.radians(section.get("detector_rotation_deg", 0.0)),
                       section.get("sag_cos_mm", 0.0) * _MM, section.get("sag_sin_mm", 0.0) * _MM)


def _motion(section: dict, system: CArmSystem) -> Motion:
    """``[motion]``: every joint's ``<joint>_speed_mm_s|deg_s`` (required) and
    ``<joint>_acceleration_mm_s2|deg_s2`` (optional: not known), converted to SI."""
    units = {name: _unit(prismatic) for name, prismatic in zip(system.joint_names, system.prismatic)}
    known = {f"{name}_{kind}_{unit}_s{'2' if kind == 'acceleration' else ''}"
             for name, (unit, _) in units.items() for kind in ("speed", "acceleration")}
    extra = sorted(set(section) - known)
    if extra:
        raise PresetError(f"[motion] {extra[0]}: the system has no such joint (joints: {', '.join(system.joint_names)})")
    joints = []
    for name, (unit, scale) in units.items():
        acceleration = section.get(f"{name}_acceleration_{unit}_s2")
        joints.append(JointMotion(_get(section, f"{name}_speed_{unit}_s", "motion") * scale,
                                  None if acceleration is None else acceleration * scale, name))
    return Motion(tuple(joints))
