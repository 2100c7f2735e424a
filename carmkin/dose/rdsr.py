"""Irradiation events of a DICOM Radiation Dose Structured Report (RDSR, TID 10003) as :class:`Event` s of a
device preset (pydicom, extra ``dose``).

Per event (TID 10003 "Irradiation Event X-Ray Data"): Dose (RP) → ``k_irp_gy``; KVP; the X-Ray Filters'
copper and aluminium (mean of the minimum and maximum thickness); Distance Source to Isocenter and to
Detector (else Final Distance Source to Detector); the collimated field at the detector from the shutters
(Left + Right across, Top + Bottom along, stated at 1 m from the source and scaled to the detector) or else
from the Collimated Field Area (a square); Positioner Primary / Secondary Angle (patient-based, PS3.3
C.8.7.5.1.2: LAO +, CRA +); the table's Longitudinal / Lateral / Height Position.

The table positions are in each vendor's own reference: :data:`TABLE_CONVENTIONS` turns them, per
manufacturer, into the position of the table top's head end (centre of its upper surface) relative to the
isocentre, in the isocentre axes (X to the table's left, Y down, Z to the head) — PySkinDose's normalization
(``normalization_settings.json``), the only published one. The event's joints place the preset's isocentre
there (its prismatic table joints ``table_translation``, ``table_lateral``, ``table_height``) and aim the beam
with the angles (the angiography presets: primary = −angular, secondary = −orbital, checked back through
:func:`carmkin.interop.dicom.xa_angles`). The patient is head first supine (the reports' Patient Table
Relationship "headfirst"; another is refused).

An event whose report lacks any of these, or states a table tilt or rotation, or another plane than the
preset's, is refused by name (its index and UID) with :class:`DoseError`: never dropped in silence.
``skip_incomplete=True`` returns the others and lists the refused in ``Report.refused``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from carmkin.dose.event import Event
from carmkin.errors import DoseError

#: Per manufacturer: (offset (cm), direction signs) of (X, Y, Z) from (Longitudinal, Height, Lateral)
#: Position (mm / 10), and the sign PySkinDose gives the secondary angle (its Ap2).
# source: PySkinDose 25.1.1 normalization_settings.json (Siemens AXIOM-Artis, Philips Allura Clarity)
TABLE_CONVENTIONS = {
    "siemens": {"offset_cm": (0.0, 0.0, 0.0), "direction": (1.0, 1.0, 1.0), "pyskindose_secondary": 1.0},
    "philips": {"offset_cm": (-0.3, 105.5, -173.35), "direction": (1.0, -1.0, 1.0), "pyskindose_secondary": -1.0},
}
#: Readings of the secondary angle: ``"dicom"`` the standard's (CRA + tilts the detector towards the head),
#: ``"pyskindose"`` PySkinDose's per vendor (its Siemens reading is the opposite one).
SECONDARY_READINGS = ("dicom", "pyskindose")
#: Distance (mm) from the source at which the RDSR states the shutter positions.
# source: PySkinDose 25.1.1 geom_calc.calculate_field_size (d_shutter_in_dcm_cm = 100)
SHUTTER_DISTANCE_MM = 1000.0
#: Largest difference (deg) between the angles asked and those of the joints found, and (m) between the
#: isocentre asked and the one reached.
ANGLE_TOLERANCE_DEG = 1e-6
POSITION_TOLERANCE_M = 1e-9
EVENT = "Irradiation Event X-Ray Data"


@dataclass(frozen=True)
class Report:
    """The events of a report (iterable, so ``skin_dose(system, report, ...)`` takes it), the device, and the
    events refused (``(name, why)``; empty unless ``skip_incomplete``)."""

    events: tuple
    manufacturer: str
    model: str
    refused: tuple = field(default=())

    def __iter__(self):
        return iter(self.events)

    def __len__(self) -> int:
        return len(self.events)


def _content(items) -> dict:
    """Concept name → list of values (numbers as float with their unit, codes and text as str; containers as
    dicts of their own content)."""
    out: dict = {}
    for item in items:
        if "ConceptNameCodeSequence" not in item or not item.ConceptNameCodeSequence:
            continue
        name = str(item.ConceptNameCodeSequence[0].CodeMeaning)
        if "MeasuredValueSequence" in item and item.MeasuredValueSequence:
            mv = item.MeasuredValueSequence[0]
            value = (float(mv.NumericValue), str(mv.MeasurementUnitsCodeSequence[0].CodeValue))
        elif "ConceptCodeSequence" in item and item.ConceptCodeSequence:
            value = str(item.ConceptCodeSequence[0].CodeMeaning)
        elif "TextValue" in item:
            value = str(item.TextValue)
        elif "UID" in item:
            value = str(item.UID)
        elif "ContentSequence" in item:
            value = _content(item.ContentSequence)
        else:
            continue
        out.setdefault(name, []).append(value)
    return out


class _Missing(Exception):
    pass


def _number(content: dict, *names: str, unit: str | None = None) -> float:
    for name in names:
        for value in content.get(name, ()):
            if isinstance(value, tuple):
                number, given = value
                if unit is not None and given.replace(".", "") != unit.replace(".", ""):
                    raise _Missing(f"{name} in {given!r}, expected {unit!r}")
                if not np.isfinite(number):
                    raise _Missing(f"{name} is {number}")
                return number
    raise _Missing(" / ".join(names))


def _filters(content: dict) -> dict:
    out = {"Cu": 0.0, "Al": 0.0}
    for f in content.get("X-Ray Filters", ()):
        if not isinstance(f, dict):
            continue
        material = " ".join(v for v in f.get("X-Ray Filter Material", ()) if isinstance(v, str)).lower()
        if not material or "none" in material:
            continue
        key = "Cu" if "copper" in material else "Al" if "alumin" in material else None
        if key is None:
            raise _Missing(f"X-Ray Filter Material {material!r} (only copper and aluminium are tabulated)")
        thickness = [_number(f, name) for name in ("X-Ray Filter Thickness Minimum", "X-Ray Filter Thickness Maximum")]
        out[key] += float(np.mean(thickness))
    return out


def _field_mm(content: dict, sid_mm: float) -> tuple[float, float]:
    shutters = next((s for s in content.get("Wedges and Shutters", ()) if isinstance(s, dict)), None)
    if shutters is not None and all(k in shutters for k in ("Left Shutter", "Right Shutter", "Top Shutter",
                                                              "Bottom Shutter")):
        scale = sid_mm / SHUTTER_DISTANCE_MM
        across = _number(shutters, "Left Shutter") + _number(shutters, "Right Shutter")
        along = _number(shutters, "Top Shutter") + _number(shutters, "Bottom Shutter")
        return across * scale, along * scale
    area = _number(content, "Collimated Field Area", unit="m2")
    side = float(np.sqrt(area)) * 1e3
    return side, side


def _vendor(manufacturer: str) -> dict:
    for key, convention in TABLE_CONVENTIONS.items():
        if key in manufacturer.lower():
            return convention
    raise DoseError(f"the report's manufacturer {manufacturer!r} has no table-position convention (known: "
                    f"{', '.join(TABLE_CONVENTIONS)}): its table positions cannot be placed")


def _joint(system, name: str) -> int:
    if name not in system.joint_names:
        raise DoseError(f"the preset {system.name!r} has no joint {name!r}: a report's events need the table's "
                        f"translation, lateral and height joints and the angular and orbital joints")
    return system.joint_names.index(name)


def event_joints(system, primary_deg: float, secondary_deg: float, isocentre_in_table) -> np.ndarray:
    """Joints placing ``system``'s isocentre at ``isocentre_in_table`` (3,) m (the table's frame) with the beam
    at the patient-based angles (deg, HFS); :class:`DoseError` when the preset cannot."""
    from carmkin.interop.dicom import xa_angles

    table = [_joint(system, n) for n in ("table_translation", "table_lateral", "table_height")]
    angular, orbital = _joint(system, "angular"), _joint(system, "orbital")

    def isocentre(q):
        T = system.fk(q)
        return T[:3, 3] + system.carm.orbital_offset * T[:3, 2]

    q = np.zeros(system.nq)
    q[angular], q[orbital] = -np.radians(primary_deg), -np.radians(secondary_deg)
    base = isocentre(q)
    J = np.column_stack([isocentre(q + np.eye(system.nq)[i]) - base for i in table])  # exact: prismatic joints
    q[table] = np.linalg.solve(J, np.asarray(isocentre_in_table) - base)
    reached_p, reached_s, _ = xa_angles(system.fk(q), "HFS")
    if (abs(reached_p - primary_deg) > ANGLE_TOLERANCE_DEG or abs(reached_s - secondary_deg) > ANGLE_TOLERANCE_DEG
            or np.linalg.norm(isocentre(q) - isocentre_in_table) > POSITION_TOLERANCE_M):
        raise DoseError(f"the preset {system.name!r} does not aim its beam by primary = -angular and secondary = "
                        f"-orbital about a fixed isocentre (asked {primary_deg:g}, {secondary_deg:g} deg, reached "
                        f"{reached_p:g}, {reached_s:g} deg): use an angiography preset (angio-floor, angio-ceiling)")
    return q


def _event(system, content: dict, index: int, vendor: dict, secondary: str, model: str) -> Event:
    uid = next(iter(content.get("Irradiation Event UID", ())), "")
    kind = next(iter(content.get("Irradiation Event Type", ())), "")
    name = f"#{index + 1} {kind}".strip() + (f" {uid}" if uid else "")
    try:
        relation = [v for v in content.get("Patient Table Relationship", ()) if isinstance(v, str)]
        if relation and relation[0].replace(" ", "").lower() not in ("headfirst",):
            raise _Missing(f"Patient Table Relationship {relation[0]!r} (only head first supine is placed)")
        for tilt in ("Table Head Tilt Angle", "Table Horizontal Rotation Angle", "Table Cradle Tilt Angle"):
            if tilt in content and abs(_number(content, tilt)) > 0.0:
                raise _Missing(f"{tilt} {_number(content, tilt):g} deg (a tilted or turned table is not placed)")
        plane = next(iter(content.get("Acquisition Plane", ())), "Single Plane")
        if "plane b" in plane.lower():
            raise _Missing(f"Acquisition Plane {plane!r} (a biplane's lateral plane: not this preset's)")
        k = _number(content, "Dose (RP)", unit="Gy")
        kvp = _number(content, "KVP", unit="kV")
        dsi = _number(content, "Distance Source to Isocenter", unit="mm")
        dsd = _number(content, "Distance Source to Detector", "Final Distance Source to Detector", unit="mm")
        primary = _number(content, "Positioner Primary Angle", unit="deg")
        sec = _number(content, "Positioner Secondary Angle", unit="deg")
        positions = [_number(content, f"Table {n} Position", unit="mm") for n in ("Longitudinal", "Height", "Lateral")]
        field_mm = _field_mm(content, dsd)
        filters = _filters(content)
    except _Missing as missing:
        raise DoseError(f"RDSR event {name}: no usable {missing}; its geometry or technique is not in the report") \
            from None
    if secondary == "pyskindose":
        sec = -vendor["pyskindose_secondary"] * sec  # PySkinDose's Ap2 > 0 tilts the source to the head
    head_end = np.array(vendor["offset_cm"]) / 100 + np.array(vendor["direction"]) * np.array(positions) / 1e3
    t = system.table
    top_head = np.array([t.top_center[0], t.top_center[1] - t.top_size[1] / 2, t.top_center[2] + t.top_size[2] / 2])
    q = event_joints(system, primary, sec, top_head - head_end)
    from carmkin.dose.coefficients import table_transmission

    k_tab = table_transmission(kvp, filters["Cu"], filters["Al"], model, plane) if 50.0 <= kvp <= 150.0 else None
    return Event(q=q, kvp=kvp, k_irp_gy=k, field_mm=field_mm, filter=filters, table_transmission=k_tab,
                 source_to_isocenter_mm=dsi, source_to_detector_mm=dsd, name=name)


def read_rdsr(path, system, *, secondary: str = "dicom", skip_incomplete: bool = False) -> Report:
    """The irradiation events of the RDSR at ``path`` as events of ``system`` (an angiography preset), in the
    report's order. ``secondary``: :data:`SECONDARY_READINGS`."""
    from carmkin.model.system import require_system

    require_system(system, DoseError)
    if secondary not in SECONDARY_READINGS:
        raise DoseError(f"secondary must be one of {SECONDARY_READINGS}, got {secondary!r:.60}")
    if not isinstance(skip_incomplete, bool):
        raise DoseError(f"skip_incomplete must be True or False, got {skip_incomplete!r:.60}")
    if not isinstance(path, (str, Path)):
        raise DoseError(f"path must be the path of an RDSR file, got {type(path).__name__}")
    from carmkin.extras import require

    pydicom = require("pydicom", "dose")
    try:
        ds = pydicom.dcmread(str(path))
        items = ds.ContentSequence
    except Exception as exc:  # pydicom raises many kinds on a file that is not DICOM SR
        raise DoseError(f"path {str(path)!r:.120}: cannot read a DICOM structured report ({type(exc).__name__}: "
                        f"{str(exc)[:120]})") from None
    manufacturer, model = str(ds.get("Manufacturer", "")), str(ds.get("ManufacturerModelName", ""))
    events_content = [_content(item.ContentSequence) for item in items
                      if "ConceptNameCodeSequence" in item and item.ConceptNameCodeSequence
                      and item.ConceptNameCodeSequence[0].CodeMeaning == EVENT and "ContentSequence" in item]
    if not events_content:
        raise DoseError(f"path {str(path)!r:.120}: the report holds no {EVENT!r} item")
    vendor = _vendor(manufacturer)
    events, refused = [], []
    for index, content in enumerate(events_content):
        try:
            events.append(_event(system, content, index, vendor, secondary, model))
        except DoseError as exc:
            if not skip_incomplete:
                raise
            refused.append((f"#{index + 1}", str(exc)))
    return Report(tuple(events), manufacturer, model, tuple(refused))
