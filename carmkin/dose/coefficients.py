"""The dosimetric coefficients of the entrance skin dose, each from its published table (numpy and scipy only).

- **Backscatter factor** ``B(kVp, HVL, field side)``: the polynomial fit of Benmakhlouf, Bosmans and Sandborg,
  "Influence of phantom thickness and material on the backscatter factors for diagnostic x-ray beam
  dosimetry", Phys. Med. Biol. 58 (2013) 247 (doi:10.1088/0031-9155/58/2/247), eq. (8) with its coefficients
  for field sides 5, 10, 20, 25 and 35 cm (:data:`BACKSCATTER_COEFFICIENTS`), interpolated in field side by a
  cubic spline as PySkinDose 25.1.1 does (``corrections.calculate_k_bs``).
- **Air-to-water conversion** ``f = (μen/ρ)_water / (μen/ρ)_air``: the same paper's table 2, shipped by
  PySkinDose as ``correction_medium_and_backscatter.csv`` (column ``mu_en_quotient``), looked up at the
  nearest tabulated kVp, HVL and field side, as PySkinDose does (``calculate_k_med``).
- **Half-value layer** (mm Al) from kVp and added Cu / Al filtration: PySkinDose's SpekCalc-simulated table
  (``hvl_tables/hvl_combined.csv``), kept for an inherent filtration of 3.1 mm Al (PySkinDose's
  ``settings_example.json`` "inherent_filtration": 3.1) and, where its two anode angles both list a filtration,
  its first row (PySkinDose's ``iloc[0]``): ``data/hvl_inherent_3.1mmAl.csv``.
- **Table and pad transmission** ``T``: PySkinDose's measured ``correction_table_and_pad_attenuation.csv``
  (AXIOM-Artis and Allura Clarity, by kVp and filtration), or, for a device it does not list, PySkinDose's
  stated estimate :data:`DEFAULT_TABLE_TRANSMISSION`.

The three CSV files in ``carmkin/dose/data`` are PySkinDose's (MIT licence, ``LICENSE-pyskindose.txt`` beside
them), unchanged but for the HVL subset. Every function refuses a value outside its table with
:class:`carmkin.errors.DoseError` naming the argument, the value and the table's range.
"""

from __future__ import annotations

import csv
from functools import cache
from pathlib import Path

import numpy as np

from carmkin.errors import DoseError
from carmkin.validation import real_array, real_scalar

DATA = Path(__file__).with_name("data")

#: Benmakhlouf et al. 2013 eq. (8): rows c0..c8, columns the field sides :data:`BACKSCATTER_FIELD_SIDES_CM`;
#: B = (c0 + c1 kVp + c2 kVp²) + (c3 + c4 kVp + c5 kVp²) HVL + (c6 + c7 kVp + c8 kVp²) HVL².
# source: Benmakhlouf et al., Phys. Med. Biol. 58 (2013) 247, eq. (8); as typed in PySkinDose 25.1.1 corrections.py
BACKSCATTER_COEFFICIENTS = np.array([
    [+1.00870e0, +9.29969e-1, +8.65442e-1, +8.58665e-1, +8.57065e-1],
    [+2.35816e-3, +4.08549e-3, +5.36739e-3, +5.51579e-3, +5.55933e-3],
    [-9.48937e-6, -1.66271e-5, -2.21494e-5, -2.27532e-5, -2.28004e-5],
    [+1.03143e-1, +1.53605e-1, +1.72418e-1, +1.70826e-1, +1.66418e-1],
    [-1.04881e-3, -1.45187e-3, -1.46088e-3, -1.38540e-3, -1.28180e-3],
    [+3.59731e-6, +5.05312e-6, +5.17430e-6, +4.91192e-6, +4.53036e-6],
    [-7.31303e-3, -9.32427e-3, -8.30138e-3, -7.64330e-3, -6.81574e-3],
    [+7.93272e-5, +9.40568e-5, +7.13576e-5, +6.13126e-5, +4.94197e-5],
    [-2.74296e-7, -3.28449e-7, -2.54885e-7, -2.21399e-7, -1.79074e-7],
])
# source: Benmakhlouf et al. 2013, the square field sides (cm) of eq. (8)'s fits
BACKSCATTER_FIELD_SIDES_CM = (5.0, 10.0, 20.0, 25.0, 35.0)
#: Tube voltages (kV) the fits and table 2 cover.
# source: Benmakhlouf et al. 2013 table 2 (50-150 kV), correction_medium_and_backscatter.csv
KVP_RANGE = (50.0, 150.0)
#: Field sides (cm, square-equivalent, at the skin) the backscatter spline is used over: the fits' 5–35 cm
#: extended by the spline (as PySkinDose extrapolates) to 0.5–45 cm, where it stays within 1.07–1.6 at 50–150 kV
#: (B tends to 1 as the field shrinks); beyond, :class:`DoseError`.
FIELD_SIDE_RANGE_CM = (0.5, 45.0)
#: Table transmission for a device PySkinDose has not measured.
# source: PySkinDose 25.1.1 settings_example.json "k_tab_val": 0.8 (its estimate_k_tab)
DEFAULT_TABLE_TRANSMISSION = 0.8
#: Inherent filtration (mm Al) of the HVL table kept.
# source: PySkinDose 25.1.1 settings_example.json "inherent_filtration": 3.1
INHERENT_FILTRATION_MM_AL = 3.1


@cache
def _rows(name: str) -> tuple[dict, ...]:
    with open(DATA / name, newline="") as handle:
        return tuple(csv.DictReader(handle))


def check_kvp(kvp, name: str = "kvp") -> float:
    """``kvp`` (kV) within :data:`KVP_RANGE`, or :class:`DoseError` naming ``name``."""
    return real_scalar(kvp, name, error=DoseError, low=KVP_RANGE[0], high=KVP_RANGE[1], unit="kV")


def backscatter(kvp, hvl_mm_al, field_side_cm) -> np.ndarray:
    """Backscatter factor (dimensionless) at tube voltage ``kvp`` (kV), half-value layer ``hvl_mm_al`` (mm Al)
    and square-equivalent field sides ``field_side_cm`` (cm, any shape, at the skin)."""
    kvp = check_kvp(kvp)
    hvl = real_scalar(hvl_mm_al, "hvl_mm_al", error=DoseError, low=0.0, high=20.0, unit="mm Al")
    side = real_array(field_side_cm, "field_side_cm", error=DoseError, unit="cm")
    if side.size and (side.min() < FIELD_SIDE_RANGE_CM[0] or side.max() > FIELD_SIDE_RANGE_CM[1]):
        raise DoseError(f"field_side_cm must be within [{FIELD_SIDE_RANGE_CM[0]:g}, {FIELD_SIDE_RANGE_CM[1]:g}] cm "
                        f"(the backscatter fits cover 5-35 cm), got {side.min():.3g} to {side.max():.3g} cm")
    return _backscatter_spline(kvp, hvl)(side)


@cache
def _backscatter_spline(kvp: float, hvl: float):
    from scipy.interpolate import CubicSpline

    c = BACKSCATTER_COEFFICIENTS
    powers = np.array([1.0, kvp, kvp * kvp])
    at_sides = powers @ c[0:3] + (powers @ c[3:6]) * hvl + (powers @ c[6:9]) * hvl * hvl
    return CubicSpline(BACKSCATTER_FIELD_SIDES_CM, at_sides)


def _nearest(values, target: float) -> float:
    return min(values, key=lambda v: abs(v - target))


def medium_factor(kvp, hvl_mm_al, field_side_cm) -> float:
    """``(μen/ρ)_water / (μen/ρ)_air`` at the nearest tabulated field side (cm), kVp and HVL (in this order,
    PySkinDose's lookup)."""
    kvp = check_kvp(kvp)
    hvl = real_scalar(hvl_mm_al, "hvl_mm_al", error=DoseError, low=0.0, high=20.0, unit="mm Al")
    side = real_scalar(field_side_cm, "field_side_cm", error=DoseError, low=0.0, unit="cm")
    return _medium(kvp, hvl, _nearest(BACKSCATTER_FIELD_SIDES_CM, side))


@cache
def _medium(kvp: float, hvl: float, fsl: float) -> float:
    rows = _rows("correction_medium_and_backscatter.csv")
    rows = [r for r in rows if float(r["field_side_length_cm"]) == fsl]
    k = _nearest({float(r["kvp_kv"]) for r in rows}, kvp)
    rows = [r for r in rows if float(r["kvp_kv"]) == k]
    h = _nearest([float(r["hvl_mmal"]) for r in rows], hvl)
    return next(float(r["mu_en_quotient"]) for r in rows if float(r["hvl_mmal"]) == h)


def half_value_layer(kvp, cu_mm=0.0, al_mm=0.0) -> float:
    """HVL (mm Al) of a beam at ``kvp`` (kV, rounded to 1 kV) with added filtration ``cu_mm`` (mm Cu) and
    ``al_mm`` (mm Al, rounded to 1 mm), inherent :data:`INHERENT_FILTRATION_MM_AL`; :class:`DoseError` naming
    the filtration the table lacks."""
    kvp = check_kvp(kvp)
    cu = real_scalar(cu_mm, "filter Cu", error=DoseError, low=0.0, unit="mm")
    al = real_scalar(al_mm, "filter Al", error=DoseError, low=0.0, unit="mm")
    return _hvl(round(kvp), cu, round(al))


@cache
def _hvl(kvp: int, cu: float, al: int) -> float:
    rows = _rows("hvl_inherent_3.1mmAl.csv")
    for r in rows:
        if (round(float(r["kvp_kv"])) == kvp and float(r["filtration_added_mmcu"]) == cu
                and round(float(r["filtration_added_mmal"])) == al):
            return float(r["hvl_mmal"])
    cus = sorted({float(r["filtration_added_mmcu"]) for r in rows})
    als = sorted({round(float(r["filtration_added_mmal"])) for r in rows})
    raise DoseError(f"filter (Cu {cu:g} mm, Al {al:g} mm) at {kvp:g} kV is not in the HVL table (Cu one of "
                    f"{cus} mm, Al one of {als} mm); pass hvl_mm_al= to the Event")


def table_transmission(kvp, cu_mm, al_mm, model: str, plane: str = "Single Plane") -> float | None:
    """Measured table-and-pad transmission of device ``model`` (PySkinDose's table, e.g. ``"AXIOM-Artis"``,
    ``"Allura Clarity"``) for the acquisition ``plane``, or None where it has no such row."""
    kvp = check_kvp(kvp)
    key = str(model).replace(" ", "")
    for r in _rows("correction_table_and_pad_attenuation.csv"):
        if (r["device_model"].replace(" ", "") == key and r["acquisition_plane"].lower() == str(plane).lower()
                and round(float(r["kvp_kv"])) == round(kvp) and float(r["filtration_added_mmcu"]) == float(cu_mm)
                and float(r["filtration_added_mmal"]) == float(al_mm)):
            return float(r["k_patient_support"])
    return None
