"""PySkinDose 25.1.1 (extra ``dose-check``) as an oracle for carmkin.dose on its own example reports.

For one of the four RDSRs shipped in its wheel: PySkinDose's pipeline (parse, normalize, HVL, corrections,
plane phantom on its table and pad) on the events carmkin accepts, and carmkin's map on *the same skin cells*
(PySkinDose's plane, moved into the preset's table frame: its head end at the table top's head end, on its
4 cm pad) with the same secondary-angle reading (``secondary="pyskindose"``). Printed by
``python tests/dose/pyskindose_oracle.py``.
"""

from __future__ import annotations

import copy
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

import carmkin
from carmkin import dose

#: The reports and the preset each is read with (docs/PRESETS.md: the Siemens geometry is angio-floor's, the
#: Philips angio-ceiling's).
REPORTS = {"siemens_axiom_artis.dcm": "angio-floor", "siemens_axiom_example_procedure.dcm": "angio-floor",
           "philips_allura_clarity_u104.dcm": "angio-ceiling", "philips_allura_clarity_u601.dcm": "angio-ceiling"}


def rdsr_path(name: str) -> Path:
    import pyskindose

    return Path(pyskindose.__file__).parent / "example_data" / "RDSR" / name


def _settings(db: str) -> dict:
    import pyskindose

    settings = json.loads((Path(pyskindose.__file__).parent / "settings_example.json").read_text())
    settings.update(mode="calculate_dose", estimate_k_tab=False, corrections_db_path=db)
    settings["phantom"]["model"] = "plane"
    settings["plot"]["notebook_mode"] = False
    return settings


def pyskindose_map(path: Path, keep: list[int], db: str):
    """PySkinDose's plane phantom (its reference cells, cm) and dose map (mGy) for the events ``keep``."""
    import logging

    from pyskindose.calculate_dose.calculate_dose import calculate_dose
    from pyskindose.helpers.calculate_rotation_matrices import calculate_rotation_matrices
    from pyskindose.helpers.read_and_normalize_rdsr_data import read_and_normalise_rdsr_data
    from pyskindose.phantom_class import Phantom
    from pyskindose.settings import initialize_settings

    import pyskindose.calculate_dose.perform_calculations_for_new_geometries as geometries

    logging.getLogger("pyskindose").setLevel(logging.ERROR)
    # PySkinDose 25.1.1's calculate_k_isq takes the norm along the wrong axis when 1-3 cells are hit
    # (`if len(cells) > 3 ... else axis=0`), which fails on the small fields of these reports: the oracle uses
    # its formula on every cell count.
    geometries.calculate_k_isq = lambda source, cells, dref: np.square(dref / np.linalg.norm(cells - source, axis=1))
    settings = initialize_settings(_settings(db))
    data = read_and_normalise_rdsr_data(rdsr_filepath=str(path), settings=settings)
    data = data.iloc[keep].reset_index(drop=True)
    data = calculate_rotation_matrices(data)
    table = Phantom(phantom_model="table", phantom_dim=settings.phantom.dimension)
    pad = Phantom(phantom_model="pad", phantom_dim=settings.phantom.dimension)
    patient, output = calculate_dose(normalized_data=data, settings=settings, table=table, pad=pad)
    hits = [np.asarray(h, bool) for h in output["hits"]]
    return np.asarray(patient.r_ref, float), np.asarray(output["dose_map"], float), hits


def compare(name: str) -> dict:
    """carmkin against PySkinDose on report ``name``: PSD (Gy) of each, their ratio, the distance (mm) of the
    PSD cells and the largest distance (mm) between the two field centres (centroid of the cells hit) of an
    event, over the events carmkin accepts (the refused are counted)."""
    system = carmkin.load_preset(REPORTS[name])
    path = rdsr_path(name)
    report = dose.read_rdsr(path, system, secondary="pyskindose", skip_incomplete=True)
    accepted = [int(e.name.split()[0][1:]) - 1 for e in report.events]
    with tempfile.TemporaryDirectory() as tmp:
        r_ref, psd_map, hits = pyskindose_map(path, accepted, str(Path(tmp) / "corrections.db"))
    pad = 0.04  # PySkinDose settings_example.json "pad_thickness": 4 (cm); its plane lies on the pad at y = -4 cm
    t = system.table
    top = t.top_center[1] - t.top_size[1] / 2
    head = t.top_center[2] + t.top_size[2] / 2
    points = np.column_stack((r_ref[:, 0] / 100, top + r_ref[:, 1] / 100, head + r_ref[:, 2] / 100))
    assert np.allclose(points[:, 1], top - pad)
    skin = dose.Skin(points, np.tile([0.0, -1.0, 0.0], (len(points), 1)), two_sided=True, name="pyskindose plane")
    ours = dose.skin_dose(system, report, skin)
    theirs_gy = psd_map / 1e3
    offsets = []
    for part, hit in zip(ours.events, hits):
        if len(part.cells) and hit.any():
            offsets.append(float(np.linalg.norm(points[part.cells].mean(axis=0) - points[hit].mean(axis=0))) * 1e3)
        elif len(part.cells) or hit.any():
            offsets.append(float("inf"))
    return {"report": name, "preset": system.name, "events": len(report.events) + len(report.refused),
            "refused": len(report.refused), "psd_carmkin_gy": ours.psd_gy, "psd_pyskindose_gy": float(theirs_gy.max()),
            "psd_ratio": ours.psd_gy / float(theirs_gy.max()) if theirs_gy.max() > 0 else float("nan"),
            "psd_cells_mm": float(np.linalg.norm(ours.psd_point - points[int(np.argmax(theirs_gy))]) * 1e3),
            "max_cell_difference_gy": float(np.max(np.abs(ours.dose_gy - theirs_gy))),
            "events_compared": len(offsets), "max_field_centre_offset_mm": max(offsets, default=0.0)}


if __name__ == "__main__":
    for name in (sys.argv[1:] or REPORTS):
        row = compare(name)
        print(json.dumps({k: (round(v, 6) if isinstance(v, float) else v) for k, v in row.items()}))
