"""The numbers the dissertation (the seed, ``shared/seed/``) reports for its experiments, in one place.

Each table is quoted as printed (its units in its comment); the simulations that reproduce them
(:mod:`carmkin.reposition.experiment`, :mod:`carmkin.reproduce`, :mod:`carmkin.studies.workspace`,
:mod:`carmkin.sweeps.reconstruct`) compare against these and never type them a second time. Plain data:
nothing here imports anything of carmkin.
"""

from __future__ import annotations

#: §4.6.2 (ten tasks, 160 points, 800 × 600 images): mean, std, max, min of the repositioning errors.
SEED_RESULTS = {
    "image error (px)": (5.2, 2.6, 8.8, 2.0),
    "translation (mm)": (4.6, 1.5, 7.1, 2.8),
    "rotation (deg)": (0.37, 0.16, 0.58, 0.20),
}

#: Table 3.1: procedure -> (mean, std px, markers) without and with VDP (source: Table 3.1).
SEED_TABLE_3_1 = {"#1": ((1.85475, 1.34975, 14), (1.68037, 1.30408, 14)),
                  "#2": ((2.00565, 1.36968, 13), (1.84381, 1.17027, 13)),
                  "overall": ((1.92741, 1.36417, 27), (1.75906, 1.35613, 27))}
#: Table 3.2: actual value -> measured by (A, B, C) (source: Table 3.2; mm or degrees).
SEED_TABLE_3_2 = {"240 mm": (239.80, 239.25, 239.55), "120 mm": (119.51, 119.46, 119.61),
                  "90 deg": (89.54, 89.50, 89.46), "180 deg": (179.84, 179.72, 179.36)}

#: Table 4.6, per procedure and overall: image error mean, std (px), markers; distance error mean, std
#: (mm); angle error mean, std (deg).
SEED_TABLE_4_6 = {
    "#1": (4.8, 2.7, 33, 2.22, 0.74, 0.60, 0.42), "#2": (3.6, 2.8, 32, 1.98, 0.56, 0.60, 0.32),
    "#3": (4.9, 2.4, 35, 2.24, 0.76, 0.62, 0.35), "#4": (4.3, 2.1, 35, 1.96, 0.74, 0.54, 0.34),
    "#5": (3.8, 3.0, 33, 1.88, 0.70, 0.52, 0.37), "overall": (4.3, 2.6, 168, 2.06, 0.66, 0.58, 0.33),
}

#: Table 4.5's columns: the table translations d0 as printed (mm).
TABLE_4_5_TRANSLATIONS_MM = "0 50 100 150 200 250 300 350 400"


def _row(means, stds, maxs, mins, ks) -> dict[str, dict[str, str]]:
    return {d0: {"K": k, "mean": a, "std": s, "max": hi, "min": lo}
            for d0, a, s, hi, lo, k in zip(TABLE_4_5_TRANSLATIONS_MM.split(), means.split(), stds.split(),
                                           maxs.split(), mins.split(), ks.split())}


#: Table 4.5 exactly as printed (text, to keep its precision; excess in mm and degrees), translations
#: 0..400 mm: {"wigwag"|"horizontal": {"<translation_mm>": {"K", "mean", "std", "max", "min"}}}.
DISSERTATION_TABLE_4_5_TEXT: dict[str, dict[str, dict[str, str]]] = {
    "wigwag": _row("0 1.94 3.85 5.73 7.57 6.79 6.43 8.24 10.00",
                   "0 0.09 0.16 0.27 0.35 4.11 4.75 4.68 4.61",
                   "0 2.08 4.12 6.13 8.10 10.02 11.90 13.73 15.51",
                   "0 1.81 3.60 5.35 7.08 0.12 0.95 2.72 4.47",
                   "0 4095 4095 4095 4095 5733 8190 8190 8190"),
    "horizontal": _row("0 6.02 12.5 19.3 26.6 28.9 39.2 50.0 44.7",
                       "0 3.75 7.01 10.6 14.7 19.5 23.4 29.8 39.5",
                       "0 9.46 20.46 32.96 46.92 62.32 79.11 97.24 116.68",
                       "0 0.81 3.22 7.24 12.85 12.93 18.90 15.50 2.42",
                       "0 2457 2457 2457 2457 3276 3276 3276 4914"),
}
#: The same as numbers (K as int).
DISSERTATION_TABLE_4_5: dict[str, dict[str, dict[str, float]]] = {
    joint: {d0: {k: (int(v) if k == "K" else float(v)) for k, v in cell.items()} for d0, cell in column.items()}
    for joint, column in DISSERTATION_TABLE_4_5_TEXT.items()
}
