"""Calibration from files (``carmkin calibrate``): a phantom's beads (table frame, mm) and, per view, the joint
readings (mm, deg) and the pixels of the beads detected in its image. Each view's P is estimated from its
beads (:func:`~carmkin.calibration.simulate.estimate_projection`, at least :data:`~.reprojection.MIN_POINTS`
beads), then :func:`~carmkin.calibration.fit.identify` fits the model with the phantom's own beads as the
residual's points (its σ are then right: docs/calibration.md).

**Phantom** (CSV or JSON), table frame, mm:

* CSV: header ``bead,x_mm,y_mm,z_mm``, one row per bead;
* JSON: ``{"beads_mm": {"<bead>": [x, y, z], ...}}``.

**Views** (CSV or JSON), readings in the preset's joint order, mm for prismatic and degrees for revolute
joints, named ``<joint>_mm`` / ``<joint>_deg`` (as ``--json`` writes joints); pixels with centres at integers:

* CSV: header ``view,<joint>_<unit>...,bead,u_px,v_px``, one row per detected bead (a view's readings repeated
  on each of its rows, equal on every one);
* JSON: ``{"views": [{"view": "<name>", "q": {"<joint>_<unit>": value, ...}, "beads_px": {"<bead>": [u, v],
  ...}}, ...]}``.

Every problem is a :class:`~carmkin.errors.CalibrationError` naming the file, the line (CSV) or view, the value
and what was expected.
"""

from __future__ import annotations

import csv
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from carmkin.errors import CalibrationError

from .reprojection import MIN_POINTS

MM = 1000.0
PHANTOM_COLUMNS = ("bead", "x_mm", "y_mm", "z_mm")
BEAD_COLUMNS = ("bead", "u_px", "v_px")
#: A view's readings repeated on its CSV rows must agree to this (mm or deg): the file's own round-off.
READING_AGREEMENT = 1e-9


@dataclass(frozen=True)
class Phantom:
    """Bead names and positions ``points`` (M, 3), table frame, m."""

    beads: tuple[str, ...]
    points: np.ndarray


@dataclass(frozen=True)
class Views:
    """Per view: ``names``, joint readings ``q`` (N, nq) (m, rad) and the detected beads ``beads_px`` (a dict
    bead name -> (u, v) px per view)."""

    names: tuple[str, ...]
    q: np.ndarray
    beads_px: tuple[dict, ...]


def reading_columns(system) -> tuple[str, ...]:
    """The views file's reading columns: ``<joint>_mm`` or ``<joint>_deg`` in the preset's joint order."""
    return tuple(f"{n}_{'mm' if p else 'deg'}" for n, p in zip(system.joint_names, system.prismatic))


def _path(path, what: str) -> Path:
    if not isinstance(path, (str, os.PathLike)):
        raise CalibrationError(f"{what}: expected a file path (.csv or .json), got {type(path).__name__} {path!r:.80}")
    path = Path(path)
    if path.suffix.lower() not in (".csv", ".json"):
        raise CalibrationError(f"{what} {str(path)!r}: the file must end in .csv or .json")
    if not path.is_file():
        raise CalibrationError(f"{what} {str(path)!r}: no such file")
    return path


def _number(text, where: str, name: str, unit: str) -> float:
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise CalibrationError(f"{where}: {name} must be a number ({unit}), got {text!r:.80}") from None
    if isinstance(text, bool) or not math.isfinite(value):
        raise CalibrationError(f"{where}: {name} must be a finite number ({unit}), got {text!r:.80}")
    return value


def _csv_rows(path: Path, required: tuple[str, ...], what: str):
    """(line number, row dict) of a CSV file whose header holds ``required``."""
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise CalibrationError(f"{what} {str(path)!r}: not a UTF-8 text file") from None
    reader = csv.DictReader(text.splitlines())
    header = [h.strip() for h in (reader.fieldnames or [])]
    missing = [c for c in required if c not in header]
    if missing:
        raise CalibrationError(f"{what} {str(path)!r}: the header must name {', '.join(required)}; missing "
                               f"{', '.join(missing)} (header: {','.join(header) or 'none'})")
    reader.fieldnames = header
    rows = []
    for row in reader:
        if None in row or any(v is None for v in row.values()):
            raise CalibrationError(f"{what} {str(path)!r} line {reader.line_num}: expected {len(header)} values "
                                   f"({','.join(header)})")
        rows.append((reader.line_num, {k: v.strip() for k, v in row.items()}))
    if not rows:
        raise CalibrationError(f"{what} {str(path)!r}: no rows after the header")
    return rows


def _json(path: Path, key: str, what: str, shape: str):
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise CalibrationError(f"{what} {str(path)!r}: not valid JSON ({exc})") from None
    if not isinstance(data, dict) or key not in data:
        raise CalibrationError(f"{what} {str(path)!r}: expected an object with {key!r}: {shape}")
    return data[key]


def _pair(value, where: str, n: int, names: tuple[str, ...], unit: str) -> list[float]:
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise CalibrationError(f"{where}: expected {n} numbers [{', '.join(names)}] ({unit}), got {value!r:.80}")
    return [_number(v, where, name, unit) for v, name in zip(value, names)]


def read_phantom(path) -> Phantom:
    """The phantom file (CSV or JSON, module docstring): at least :data:`MIN_POINTS` beads, names unique."""
    path = _path(path, "phantom")
    beads, points = [], []
    if path.suffix.lower() == ".csv":
        for line, row in _csv_rows(path, PHANTOM_COLUMNS, "phantom"):
            where = f"phantom {str(path)!r} line {line}"
            beads.append((row["bead"], where))
            points.append([_number(row[c], where, c, "mm") for c in PHANTOM_COLUMNS[1:]])
    else:
        table = _json(path, "beads_mm", "phantom", '{"<bead>": [x, y, z], ...} (mm, table frame)')
        if not isinstance(table, dict):
            raise CalibrationError(f"phantom {str(path)!r}: beads_mm must map bead names to [x, y, z] (mm)")
        for name, value in table.items():
            where = f"phantom {str(path)!r} bead {name!r}"
            beads.append((name, where))
            points.append(_pair(value, where, 3, PHANTOM_COLUMNS[1:], "mm"))
    seen = set()
    for name, where in beads:
        if not name:
            raise CalibrationError(f"{where}: empty bead name")
        if name in seen:
            raise CalibrationError(f"{where}: bead {name!r} named twice")
        seen.add(name)
    if len(beads) < MIN_POINTS:
        raise CalibrationError(f"phantom {str(path)!r}: {len(beads)} beads, need at least {MIN_POINTS}")
    return Phantom(tuple(n for n, _ in beads), np.array(points) / MM)


def read_views(path, system, phantom: Phantom) -> Views:
    """The views file (CSV or JSON, module docstring) for ``system``: readings in range, beads of ``phantom``,
    at least :data:`MIN_POINTS` beads a view, each bead once a view."""
    path = _path(path, "views")
    columns = reading_columns(system)
    order: list[str] = []
    readings: dict[str, tuple[list[float], str]] = {}
    beads: dict[str, dict] = {}
    known = set(phantom.beads)

    def add_bead(view, bead, uv, where):
        if bead not in known:
            raise CalibrationError(f"{where}: bead {bead!r} is not in the phantom ({len(known)} beads: "
                                   f"{', '.join(phantom.beads[:6])}{', ...' if len(known) > 6 else ''})")
        if bead in beads[view]:
            raise CalibrationError(f"{where}: bead {bead!r} given twice for view {view!r}")
        beads[view][bead] = uv

    if path.suffix.lower() == ".csv":
        for line, row in _csv_rows(path, ("view", *columns, *BEAD_COLUMNS), "views"):
            where = f"views {str(path)!r} line {line}"
            view = row["view"]
            if not view:
                raise CalibrationError(f"{where}: empty view name")
            q = [_number(row[c], where, c, c.rsplit("_", 1)[1]) for c in columns]
            if view not in readings:
                order.append(view)
                readings[view], beads[view] = (q, where), {}
            elif np.max(np.abs(np.subtract(q, readings[view][0]))) > READING_AGREEMENT:
                raise CalibrationError(f"{where}: view {view!r} has other joint readings than on its first row "
                                       f"(its first row: {readings[view][1]}): one view, one set of readings")
            add_bead(view, row["bead"], _pair([row["u_px"], row["v_px"]], where, 2, ("u_px", "v_px"), "px"), where)
    else:
        shape = '[{"view": "<name>", "q": {"<joint>_<unit>": value, ...}, "beads_px": {"<bead>": [u, v], ...}}, ...]'
        entries = _json(path, "views", "views", shape)
        if not isinstance(entries, list) or not entries:
            raise CalibrationError(f"views {str(path)!r}: views must be a non-empty list: {shape}")
        for i, entry in enumerate(entries):
            where = f"views {str(path)!r} view #{i + 1}"
            if not isinstance(entry, dict) or not {"view", "q", "beads_px"} <= set(entry):
                raise CalibrationError(f"{where}: expected an object with view, q and beads_px: {shape}")
            view = entry["view"]
            if not isinstance(view, str) or not view:
                raise CalibrationError(f"{where}: view must be a non-empty name, got {view!r:.80}")
            if view in readings:
                raise CalibrationError(f"{where}: view {view!r} named twice")
            where = f"views {str(path)!r} view {view!r}"
            q = entry["q"]
            if not isinstance(q, dict) or set(q) != set(columns):
                raise CalibrationError(f"{where}: q must give exactly {', '.join(columns)}, got "
                                       f"{', '.join(map(str, q)) if isinstance(q, dict) else repr(q)[:80]}")
            order.append(view)
            readings[view] = ([_number(q[c], where, c, c.rsplit("_", 1)[1]) for c in columns], where)
            beads[view] = {}
            if not isinstance(entry["beads_px"], dict):
                raise CalibrationError(f"{where}: beads_px must map bead names to [u, v] (px)")
            for bead, uv in entry["beads_px"].items():
                add_bead(view, bead, _pair(uv, f"{where} bead {bead!r}", 2, ("u_px", "v_px"), "px"), where)
    scale = np.array([MM if p else 180.0 / math.pi for p in system.prismatic])
    for view in order:
        values, where = readings[view]
        for name, unit, value, joint, factor in zip(system.joint_names, columns, values, system.joint_ranges, scale):
            if float(joint.excess(value / factor)) != 0.0:
                raise CalibrationError(f"views {str(path)!r} view {view!r}: {unit} = {value:.6g} is outside "
                                       f"{name}'s range [{joint.lower * factor:.6g}, {joint.upper * factor:.6g}] "
                                       f"{unit.rsplit('_', 1)[1]}")
        if len(beads[view]) < MIN_POINTS:
            raise CalibrationError(f"views {str(path)!r} view {view!r}: {len(beads[view])} beads detected, need at "
                                   f"least {MIN_POINTS} to estimate its projection")
    Q = np.array([readings[v][0] for v in order]) / scale
    return Views(tuple(order), Q, tuple(beads[v] for v in order))


def projections(phantom: Phantom, views: Views) -> np.ndarray:
    """Each view's P (N, 3, 4) estimated from its detected beads and their phantom positions."""
    from .simulate import estimate_projection

    index = {name: i for i, name in enumerate(phantom.beads)}
    out = []
    for name, detected in zip(views.names, views.beads_px):
        rows = [index[b] for b in detected]
        try:
            out.append(estimate_projection(phantom.points[rows], np.array(list(detected.values()))))
        except CalibrationError as exc:
            raise CalibrationError(f"view {name!r}: {exc}") from None
    return np.array(out)


def calibrate(system, views_path, phantom_path, reject_outliers: bool = True):
    """``(result, views)``: :func:`~carmkin.calibration.fit.identify` of ``system`` from the files, the residual
    at the phantom's own beads; ``result.outliers`` index ``views.names``."""
    from .fit import identify

    phantom = read_phantom(phantom_path)
    views = read_views(views_path, system, phantom)
    return identify(system, views.q, projections(phantom, views), points=phantom.points,
                    reject_outliers=reject_outliers), views


def write_phantom(path, beads, points_m) -> Path:
    """Write a phantom CSV (``bead,x_mm,y_mm,z_mm``) of bead names and points (M, 3) m."""
    path = Path(path)
    with open(path, "w", newline="", encoding="utf-8") as f:
        out = csv.writer(f)
        out.writerow(PHANTOM_COLUMNS)
        for name, p in zip(beads, np.asarray(points_m, dtype=float) * MM):
            out.writerow([name, *(repr(float(v)) for v in p)])
    return path


def write_views(path, system, names, q, beads_px) -> Path:
    """Write a views CSV: view names, readings q (N, nq) (m, rad) and per view a dict bead -> (u, v) px."""
    path = Path(path)
    scale = np.array([MM if p else 180.0 / math.pi for p in system.prismatic])
    with open(path, "w", newline="", encoding="utf-8") as f:
        out = csv.writer(f)
        out.writerow(("view", *reading_columns(system), *BEAD_COLUMNS))
        for name, row, detected in zip(names, np.asarray(q, dtype=float) * scale, beads_px):
            for bead, (u, v) in detected.items():
                out.writerow([name, *(repr(float(x)) for x in row), bead, repr(float(u)), repr(float(v))])
    return path
