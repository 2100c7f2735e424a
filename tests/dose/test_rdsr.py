"""carmkin.dose.read_rdsr: a report's events through a preset, on reports written here (pydicom) and on the
four vendor reports of the pyskindose wheel (skipped without the ``dose-check`` extra)."""

from __future__ import annotations

import numpy as np
import pytest

import carmkin
from carmkin import dose
from carmkin.errors import DoseError
from carmkin.interop.dicom import pose_from_xa_angles

pydicom = pytest.importorskip("pydicom", reason="read_rdsr needs pydicom (extra 'dose')")
from pydicom.dataset import Dataset, FileMetaDataset  # noqa: E402
from pydicom.uid import ExplicitVRLittleEndian, generate_uid  # noqa: E402

FLOOR = carmkin.load_preset("angio-floor")


def _concept(name: str) -> Dataset:
    code = Dataset()
    code.CodeValue, code.CodingSchemeDesignator, code.CodeMeaning = "0", "99TEST", name
    return code


def num(name: str, value: float, unit: str) -> Dataset:
    item = Dataset()
    item.ValueType = "NUM"
    item.ConceptNameCodeSequence = [_concept(name)]
    measured = Dataset()
    measured.NumericValue = str(value)
    measured.MeasurementUnitsCodeSequence = [_concept(unit)]
    measured.MeasurementUnitsCodeSequence[0].CodeValue = unit
    item.MeasuredValueSequence = [measured]
    return item


def code(name: str, meaning: str) -> Dataset:
    item = Dataset()
    item.ValueType = "CODE"
    item.ConceptNameCodeSequence = [_concept(name)]
    item.ConceptCodeSequence = [_concept(meaning)]
    return item


def container(name: str, items) -> Dataset:
    item = Dataset()
    item.ValueType = "CONTAINER"
    item.ConceptNameCodeSequence = [_concept(name)]
    item.ContentSequence = list(items)
    return item


def event_items(**changes):
    values = {"Dose (RP)": (0.002, "Gy"), "KVP": (80.0, "kV"), "Distance Source to Isocenter": (785.0, "mm"),
              "Distance Source to Detector": (1198.0, "mm"), "Collimated Field Area": (0.04, "m2"),
              "Positioner Primary Angle": (30.0, "deg"), "Positioner Secondary Angle": (20.0, "deg"),
              "Table Longitudinal Position": (10.0, "mm"), "Table Lateral Position": (-50.0, "mm"),
              "Table Height Position": (200.0, "mm")} | changes
    items = [code("Acquisition Plane", "Single Plane"), code("Irradiation Event Type", "Fluoroscopy")]
    items += [num(k, *v) for k, v in values.items() if v is not None]
    items.append(container("X-Ray Filters", [code("X-Ray Filter Material", "Copper or Copper compound"),
                                             num("X-Ray Filter Thickness Minimum", 0.3, "mm"),
                                             num("X-Ray Filter Thickness Maximum", 0.3, "mm")]))
    return items


def write(path, events, manufacturer="Siemens", model="AXIOM-Artis"):
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = "1.2.840.10008.5.1.4.1.1.88.67"  # X-Ray Radiation Dose SR
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = Dataset()
    ds.file_meta = meta
    ds.SOPClassUID, ds.SOPInstanceUID = meta.MediaStorageSOPClassUID, meta.MediaStorageSOPInstanceUID
    ds.Manufacturer, ds.ManufacturerModelName = manufacturer, model
    ds.ContentSequence = [container("Irradiation Event X-Ray Data", items) for items in events]
    ds.save_as(path, enforce_file_format=True)
    return path


def test_an_event_is_placed_by_the_vendor_convention_and_aimed_by_the_dicom_angles(tmp_path):
    report = dose.read_rdsr(write(tmp_path / "r.dcm", [event_items()]), FLOOR)
    (event,) = report.events
    assert event.kvp == 80.0 and event.k_irp_gy == 0.002 and event.filter == {"Cu": 0.3, "Al": 0.0}
    assert event.field_mm == pytest.approx((200.0, 200.0)) and event.table_transmission is not None
    # Siemens (PySkinDose's normalization): the table top's head end at (long, height, lateral) mm from the
    # isocentre along (X, Y, Z); so the isocentre sits at the head end minus that
    t = FLOOR.table
    head_end = np.array([t.top_center[0], t.top_center[1] - t.top_size[1] / 2, t.top_center[2] + t.top_size[2] / 2])
    isocentre = head_end - np.array([0.010, 0.200, -0.050])
    expected = pose_from_xa_angles(30.0, 20.0, isocentre, 0.785, "HFS")
    T = FLOOR.fk(np.asarray(event.q))
    assert np.allclose(T[:3, 3], expected[:3, 3], atol=1e-9) and np.allclose(T[:3, 2], expected[:3, 2], atol=1e-12)


def test_shutters_give_the_field_scaled_to_the_detector(tmp_path):
    shutters = container("Wedges and Shutters", [num("Left Shutter", 60.0, "mm"), num("Right Shutter", 40.0, "mm"),
                                                 num("Top Shutter", 30.0, "mm"), num("Bottom Shutter", 50.0, "mm")])
    items = event_items(**{"Collimated Field Area": None}) + [shutters]
    (event,) = dose.read_rdsr(write(tmp_path / "r.dcm", [items]), FLOOR).events
    assert event.field_mm == pytest.approx((100.0 * 1.198, 80.0 * 1.198))


@pytest.mark.parametrize("changes, missing", [
    ({"Positioner Primary Angle": None}, "Positioner Primary Angle"),
    ({"Dose (RP)": None}, "Dose \\(RP\\)"),
    ({"Table Height Position": None}, "Table Height Position"),
    ({"Collimated Field Area": None}, "Collimated Field Area"),
    ({"Distance Source to Detector": None}, "Distance Source to Detector"),
    ({"Table Head Tilt Angle": (5.0, "deg")}, "Table Head Tilt Angle 5 deg"),
    ({"KVP": (80.0, "V")}, "KVP in 'V'"),
])
def test_an_event_without_its_geometry_is_refused_by_name(tmp_path, changes, missing):
    path = write(tmp_path / "r.dcm", [event_items(), event_items(**changes)])
    with pytest.raises(DoseError, match=f"RDSR event #2 Fluoroscopy: no usable {missing}"):
        dose.read_rdsr(path, FLOOR)
    report = dose.read_rdsr(path, FLOOR, skip_incomplete=True)
    assert len(report) == 1 and [name for name, _ in report.refused] == ["#2"]


def test_a_report_that_cannot_be_placed_is_refused(tmp_path):
    with pytest.raises(DoseError, match="manufacturer 'Acme' has no table-position convention"):
        dose.read_rdsr(write(tmp_path / "r.dcm", [event_items()], manufacturer="Acme"), FLOOR)
    with pytest.raises(DoseError, match="no joint 'table_lateral'"):
        dose.read_rdsr(write(tmp_path / "r.dcm", [event_items()]), carmkin.load_preset("siremobile-iso-c3d"))
    (tmp_path / "text.dcm").write_text("not DICOM")
    with pytest.raises(DoseError, match="cannot read a DICOM structured report"):
        dose.read_rdsr(tmp_path / "text.dcm", FLOOR)
    with pytest.raises(DoseError, match="holds no 'Irradiation Event X-Ray Data'"):
        dose.read_rdsr(write(tmp_path / "r.dcm", []), FLOOR)
    with pytest.raises(DoseError, match="secondary must be one of"):
        dose.read_rdsr(tmp_path / "r.dcm", FLOOR, secondary="siemens")


# --- the four vendor reports of the pyskindose wheel ------------------------------------------------------
def test_the_vendor_reports_give_all_99_events_or_refuse_them_by_name():
    oracle = pytest.importorskip("pyskindose_oracle")
    pytest.importorskip("pyskindose", reason="the vendor reports ship in the pyskindose wheel (extra dose-check)")
    counts, refused = {}, []
    for name, preset in oracle.REPORTS.items():
        report = dose.read_rdsr(oracle.rdsr_path(name), carmkin.load_preset(preset), skip_incomplete=True)
        counts[name] = len(report) + len(report.refused)
        refused += [(name, why) for _, why in report.refused]
    assert sum(counts.values()) == 99
    # the only refusals: two fluoroscopy events of u601 at 48.6 and 48.8 kV, under the tables' 50 kV
    assert len(refused) == 2 and all("u601" in n and "kvp must be within [50, 150] kV" in w for n, w in refused)
    with pytest.raises(DoseError, match="event '#1 Fluoroscopy"):
        dose.read_rdsr(oracle.rdsr_path("philips_allura_clarity_u601.dcm"), carmkin.load_preset("angio-ceiling"))
