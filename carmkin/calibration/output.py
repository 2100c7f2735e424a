"""The calibrated preset: the calibrated system written by :func:`carmkin.presets.to_toml` (``[carm]``,
``[setup]`` and ``[calibration]`` carry the fitted values), each fitted key's comment giving its provenance
(``# source: carmkin.calibration ... 1σ ...``) and each held key's why it stayed nominal (``# assumption:
...``), as :func:`carmkin.presets.preset_provenance` reads them."""

from __future__ import annotations

import os
from pathlib import Path

from carmkin.errors import CalibrationError
from carmkin.presets import to_toml

from .report import held_reason

#: The preset key (section, key) each parameter is written to; joint zero offsets go to [calibration].
_KEYS = {"source_to_detector": ("carm", "source_to_detector_mm"), "principal_point_u": ("carm", "principal_point_px"),
         "principal_point_v": ("carm", "principal_point_px"), "detector_rotation": ("calibration", "detector_rotation_deg"),
         "length_offset": ("carm", "length_offset_mm"), "orbital_offset": ("carm", "orbital_offset_mm"),
         "a1": ("carm", "a1_mm"), "a2": ("carm", "a2_mm"), "sag_cos": ("calibration", "sag_cos_mm"),
         "sag_sin": ("calibration", "sag_sin_mm"),
         **{f"gamma{i}": ("setup", f"gamma{i}_deg") for i in (1, 2, 3)},
         **{f"D{i}": ("setup", f"D{i}_mm") for i in (1, 2, 3)}}


def preset_text(result) -> str:
    """The TOML text of the calibrated preset, with provenance comments."""
    import tomlkit

    document = tomlkit.parse(to_toml(result.system))
    notes: dict[tuple[str, str], list[str]] = {}
    for name, unit, std in zip(result.names, result.units, result.std):
        notes.setdefault(_key(result.system, name, unit), []).append(f"{name} 1σ {std:.2g} {unit}")
    for held in result.identifiability.held:
        notes.setdefault(_key(result.system, held.name, None), []).append(f"{held.name} nominal: {held_reason(held)}")
    fitted = set(result.names)
    for (section, key), texts in notes.items():
        if section in document and key in document[section]:
            kind = "source" if any(t.split()[0] in fitted for t in texts) else "assumption"
            views = len(result.residual_px)
            document[section][key].comment(f"{kind}: carmkin.calibration from {views} views; " + "; ".join(texts))
    return tomlkit.dumps(document)


def save_calibrated_preset(result, path) -> Path:
    """Write :func:`preset_text` to ``path`` (``*.toml``)."""
    if not isinstance(path, (str, os.PathLike)):
        raise CalibrationError(f"path must be a file path ending in .toml, got {type(path).__name__} {path!r:.80}")
    path = Path(path)
    if path.suffix != ".toml":
        raise CalibrationError(f"path must end in .toml, got {str(path)!r}")
    path.write_text(preset_text(result))
    return path


def _key(system, name: str, unit) -> tuple[str, str]:
    if name.endswith("_zero_offset"):
        joint = name[: -len("_zero_offset")]
        prismatic = system.prismatic[system.joint_names.index(joint)]
        return "calibration", f"{name}_{'mm' if prismatic else 'deg'}"
    return _KEYS[name]
