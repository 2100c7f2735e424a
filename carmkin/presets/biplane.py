"""Biplane presets: a TOML file that names two one-plane presets and places the lateral plane.

::

    name = "angio-biplane"
    description = "..."

    [biplane]
    frontal = "angio-floor"     # a built-in preset's name, or a .toml path (relative to this file)
    lateral = "angio-ceiling"   # the same; its table must be the frontal's (the planes share one table)

    [lateral.setup]             # optional: the lateral plane's placement, in either form of a preset's [setup];
    table_origin_in_xray_mm = [0.0, 0.0, 785.0]   # without it the lateral preset's own [setup] holds
    table_x_axis_in_xray = [0.0, -1.0, 0.0]
    table_z_axis_in_xray = [1.0, 0.0, 0.0]

    [rest.table]                # optional: the rest configuration (mm, deg); a joint not named rests at 0
    table_translation_mm = 0.0  # where 0 is in its range, else at the middle of its range
    [rest.frontal]
    angular_deg = 0.0
    [rest.lateral]
    angular_deg = 90.0

Every value carries its provenance comment as in a one-plane preset. :func:`carmkin.load_preset` reads a
biplane preset as its **frontal plane** (a :class:`~carmkin.CArmSystem` named after the biplane), so every
one-plane tool runs on it unchanged; :func:`carmkin.presets.read_biplane` reads both planes as a
:class:`~carmkin.model.biplane.Biplane`, and :func:`carmkin.biplane.load_biplane` adds the check that the
planes are clear of each other at rest. This module holds the pieces that need no file access.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from carmkin.errors import BiplaneError, PresetError

from .schema import check_biplane_file

if TYPE_CHECKING:
    from carmkin.model.biplane import Biplane

#: The top-level section that makes a preset file a biplane preset.
SECTION = "biplane"


def is_biplane(data: dict) -> bool:
    """True for the parsed TOML of a biplane preset (it has a ``[biplane]`` section)."""
    return isinstance(data, dict) and SECTION in data


def check(data: dict, label: str) -> None:
    """The file's keys and values (:data:`~carmkin.presets.schema.BIPLANE_SECTIONS`) and both planes named."""
    check_biplane_file(data, label)
    for plane in ("frontal", "lateral"):
        if plane not in data[SECTION]:
            raise PresetError(f"{label}: missing key [biplane] {plane} (the name or path of the {plane} plane's preset)")


def _joint_value(name: str, prismatic: bool, section: dict, where: str, label: str):
    key = f"{name}_{'mm' if prismatic else 'deg'}"
    if key not in section:
        return None
    return section[key] * (1e-3 if prismatic else math.pi / 180)


def rest_vector(data: dict, frontal, lateral, label: str) -> np.ndarray:
    """The biplane rest configuration (nq,) of ``[rest.*]`` (m, rad); joints not named take
    :func:`~carmkin.model.biplane.default_rest`."""
    rest = data.get("rest", {})
    from carmkin.model.biplane import default_rest, table_joint_count  # on first use: `import carmkin` stays light

    k, k_lateral = table_joint_count(frontal), table_joint_count(lateral)  # (equal tables: checked by Biplane)
    f, lat = default_rest(frontal), default_rest(lateral)
    named = [(rest.get("table", {}), "table", frontal, range(k), (f, lat) if k == k_lateral else (f,)),
             (rest.get("frontal", {}), "frontal", frontal, range(k, frontal.nq), (f,)),
             (rest.get("lateral", {}), "lateral", lateral, range(k_lateral, lateral.nq), (lat,))]
    for section, where, system, indices, targets in named:
        known = set()
        for j in indices:
            name = system.joint_names[j]
            known.add(f"{name}_{'mm' if system.prismatic[j] else 'deg'}")
            value = _joint_value(name, system.prismatic[j], section, where, label)
            if value is not None:
                for target in targets:
                    target[j] = value
        for key in section:
            if key not in known:
                raise PresetError(f"{label}: [rest.{where}] {key}: this biplane has no such joint (its {where} "
                                  f"joints: {', '.join(sorted(known))})")
    return np.concatenate((f, lat[k_lateral:]))


def assemble(data: dict, label: str, frontal, lateral) -> "Biplane":
    """The :class:`~carmkin.model.biplane.Biplane` of a checked file, its planes loaded (the lateral already
    placed); a model error is re-raised naming the file."""
    name = data.get("name", label.rsplit("/", 1)[-1].removesuffix(".toml"))
    try:
        from carmkin.model.biplane import Biplane

        return Biplane(frontal, lateral, tuple(rest_vector(data, frontal, lateral, label).tolist()), name)
    except BiplaneError as exc:
        raise BiplaneError(f"{label}: {exc}") from None
