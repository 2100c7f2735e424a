"""carmkin.dose: the entrance skin dose, checked by hand, against the published tables and by properties."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import carmkin
from carmkin import dose
from carmkin.dose import coefficients
from carmkin.dose.compute import crosses_box
from carmkin.errors import CarmkinError, DoseError, PatientModelError
from carmkin.patient import ParametricPatient

SYSTEM = carmkin.load_preset("angio-floor")
#: Relative agreement of a hand computation with the map (the acceptance's 1e-9).
HAND = 1e-9


def flat(y: float, half: float = 0.3, spacing: float = 0.01) -> dose.Skin:
    """A sheet at height y (table frame, Y0 down) centred on the isocentre, two-sided."""
    xs = np.arange(-half, half + spacing / 2, spacing)
    X, Z = np.meshgrid(xs, xs)
    points = np.column_stack((X.ravel(), np.full(X.size, y), Z.ravel()))
    return dose.Skin(points, np.tile([0.0, -1.0, 0.0], (len(points), 1)), two_sided=True)


def ap_event(side_at_skin_cm: float, d_skin: float, **kw) -> dose.Event:
    """An upward beam (all joints 0: the source 785 mm under the isocentre) whose square field has the side
    ``side_at_skin_cm`` at ``d_skin`` m from the source."""
    side_mm = side_at_skin_cm * 10 * SYSTEM.carm.source_to_detector / d_skin
    args = dict(q=np.zeros(SYSTEM.nq), kvp=80.0, k_irp_gy=0.01, field_mm=(side_mm, side_mm), hvl_mm_al=4.08)
    return dose.Event(**(args | kw))


def test_one_perpendicular_event_on_a_flat_phantom_by_hand():
    # the sheet 40 mm above the table top (the top's surface 150 mm under the isocentre): the beam crosses the top
    top = SYSTEM.table.top_center[1] - SYSTEM.table.top_size[1] / 2
    y = top - 0.04
    d_skin = 0.785 - y  # the source at y = +0.785 (Y0 down), the sheet above it
    d_irp = 0.785 - 0.15
    event = ap_event(10.0, d_skin, table_transmission=0.7)
    m = dose.skin_dose(SYSTEM, [event], flat(y))
    centre = int(np.argmin(np.linalg.norm(m.cells - [0.0, y, 0.0], axis=1)))
    # Benmakhlouf et al. 2013 eq. (8), 10 cm column, typed again here
    c = [9.29969e-1, 4.08549e-3, -1.66271e-5, 1.53605e-1, -1.45187e-3, 5.05312e-6, -9.32427e-3, 9.40568e-5,
         -3.28449e-7]
    kv, h = 80.0, 4.08
    bsf = (c[0] + c[1] * kv + c[2] * kv**2) + (c[3] + c[4] * kv + c[5] * kv**2) * h + (c[6] + c[7] * kv + c[8] * kv**2) * h**2
    assert bsf == pytest.approx(1.371, rel=0.005)  # the paper's table 2 (80 kV, HVL 4.08 mm, 10 cm): 1.371
    f = 1.023  # table 2's mu_en quotient at 80 kV, HVL 4.08 mm Al, 10 cm
    expected = 0.01 * (d_irp / d_skin) ** 2 * bsf * f * 0.7
    assert m.dose_gy[centre] == pytest.approx(expected, rel=HAND)
    assert m.psd_gy == pytest.approx(expected, rel=1e-3)  # off-axis cells are farther: the centre is the peak
    assert np.allclose(m.psd_point, m.cells[centre], atol=0.0101)


def test_the_backscatter_fit_reproduces_the_papers_table_within_half_a_percent():
    with open(coefficients.DATA / "correction_medium_and_backscatter.csv") as handle:
        rows = list(csv.DictReader(handle))
    ratios = [coefficients.backscatter(float(r["kvp_kv"]), float(r["hvl_mmal"]), float(r["field_side_length_cm"]))
              / float(r["backscatter"]) for r in rows]
    assert len(ratios) == 715 and max(abs(r - 1) for r in ratios) < 0.005


@given(st.floats(0.3, 0.7), st.floats(1e-4, 1.0))
def test_dose_scales_with_kerma_and_inverse_square(y_sheet, kerma):
    """Moving the sheet changes only the inverse-square factor and the field side at the skin (whose
    backscatter the map reports): dose / (K × B × f × T) = (d_IRP / d)²."""
    event = ap_event(10.0, 0.785 - y_sheet, k_irp_gy=kerma, table_transmission=1.0)
    m = dose.skin_dose(SYSTEM, [event], flat(y_sheet, half=0.05))
    part = m.events[0]
    d = np.linalg.norm(m.cells[part.cells] - (SYSTEM.fk(np.zeros(SYSTEM.nq))[:3, 3]), axis=1)
    k = part.dose_gy / (kerma * part.backscatter * part.medium)
    assert np.allclose(k, (0.635 / d) ** 2, rtol=1e-12)


def test_table_transmission_applies_only_through_the_table_top():
    top = SYSTEM.table.top_center[1] - SYSTEM.table.top_size[1] / 2
    below = flat(top + 0.1, half=0.05)  # under the top: the upward beam reaches it before the table
    above = flat(top - 0.05, half=0.05)
    for skin, crossing in ((below, False), (above, True)):
        part = dose.skin_dose(SYSTEM, [ap_event(10.0, 0.5, table_transmission=0.6)], skin).events[0]
        assert len(part.cells) and np.all(part.table == (0.6 if crossing else 1.0))


def test_a_cell_resting_on_the_table_top_seen_from_above_is_not_behind_it():
    source = np.array([0.0, -1.0, 0.0])
    top = SYSTEM.table.top_center[1] - SYSTEM.table.top_size[1] / 2
    on_top = np.array([[0.0, top, 0.0]])
    assert not crosses_box(source, on_top, SYSTEM.table.top_center, SYSTEM.table.top_size)[0]
    assert crosses_box(-source * 2, on_top, SYSTEM.table.top_center, SYSTEM.table.top_size)[0]


def test_overlap_counts_the_entrance_fields_and_the_map_sums_them():
    skin = flat(0.0, half=0.2)
    e = ap_event(10.0, 0.785)
    one = dose.skin_dose(SYSTEM, [e], skin)
    three = dose.skin_dose(SYSTEM, [e, e, e], skin)
    assert three.overlap.max() == 3 and np.array_equal(three.overlap > 0, one.overlap > 0)
    assert np.allclose(three.dose_gy, 3 * one.dose_gy, rtol=1e-12)
    assert three.psd_gy == pytest.approx(3 * one.psd_gy, rel=1e-12)
    # a field moved half its width along the table shares half its cells with the first (hand count on the grid)
    q = np.zeros(SYSTEM.nq)
    q[SYSTEM.joint_names.index("table_translation")] = 0.05  # the C-arm 50 mm along the table (Z0)
    moved = ap_event(10.0, 0.785, q=q)
    shared = dose.skin_dose(SYSTEM, [e, moved], skin).shared_cells()
    n = len(one.events[0].cells)
    side = int(round(np.sqrt(n)))
    assert side * side == n and shared[0, 0] == shared[1, 1] == n
    assert shared[0, 1] == shared[1, 0] == side * (side - 5)  # 5 rows of 10 mm leave the field, 5 enter


def test_the_field_at_the_skin_is_the_detector_field_scaled_by_distance():
    """The cells hit span the detector field × d / SID (a 300 × 200 mm field, the sheet at the isocentre)."""
    skin = flat(0.0, half=0.3, spacing=0.002)
    e = dose.Event(np.zeros(SYSTEM.nq), 80.0, 0.01, (300.0, 200.0), hvl_mm_al=4.0)
    part = dose.skin_dose(SYSTEM, [e], skin).events[0]
    hit = skin.points[part.cells]
    scale = 0.785 / SYSTEM.carm.source_to_detector
    # image X = table X0, image Y = table Z0 at rest (docs/PRESETS.md, angiography frames)
    assert np.ptp(hit[:, 0]) == pytest.approx(0.300 * scale, abs=0.0041)
    assert np.ptp(hit[:, 2]) == pytest.approx(0.200 * scale, abs=0.0041)


def test_the_parametric_patient_takes_the_beam_on_its_back_through_the_table():
    patient = ParametricPatient.on_table(SYSTEM, chest_z=-0.1)
    skin = dose.from_patient(patient, spacing=0.02)
    # outward normals: from the trunk's centre towards each cell, on the trunk box's cells
    assert np.all(np.isfinite(skin.normals)) and np.allclose(np.linalg.norm(skin.normals, axis=1), 1.0)
    m = dose.skin_dose(SYSTEM, [ap_event(10.0, 0.6)], patient, spacing=0.02)
    part = m.events[0]
    hit_normals = m.normals[part.cells]
    assert len(part.cells) > 10 and np.all(hit_normals[:, 1] > 0)  # the back faces down, towards the source
    assert np.all(part.table == coefficients.DEFAULT_TABLE_TRANSMISSION)
    top = SYSTEM.table.top_center[1] - SYSTEM.table.top_size[1] / 2
    assert m.psd_point[1] == pytest.approx(top, abs=2e-3)  # the PSD on the back, resting on the top


def test_a_beam_that_misses_gives_a_zero_map_not_an_error():
    skin = flat(0.0, half=0.1)
    skin = dose.Skin(skin.points + [0.0, 0.0, 3.0], skin.normals, two_sided=True)
    m = dose.skin_dose(SYSTEM, [ap_event(10.0, 0.785)], skin)
    assert m.psd_gy == 0.0 and m.overlap.max() == 0 and m.summary()["events_hitting_skin"] == 0


@pytest.mark.parametrize("changes, match", [
    (dict(k_irp_gy=-1e-3), "k_irp_gy must be within"),
    (dict(k_irp_gy=math.nan), "k_irp_gy must be finite"),
    (dict(kvp=40.0), r"kvp must be within \[50, 150\] kV, got 40"),
    (dict(kvp=200.0), "kvp"),
    (dict(field_mm=(0.0, 100.0)), "field_mm must be two positive sides"),
    (dict(field_mm=(100.0,)), "field_mm"),
    (dict(filter={"Pb": 1.0}), "filter must be a dict"),
    (dict(filter={"Cu": -0.1}), "filter Cu"),
    (dict(table_transmission=1.5), "table_transmission"),
    (dict(table_transmission=0.0), "table_transmission"),
    (dict(q="abc"), "q must be"),
    (dict(source_to_isocenter_mm=5.0), "source_to_isocenter_mm"),
])
def test_bad_events_are_refused_naming_the_field(changes, match):
    args = dict(q=np.zeros(SYSTEM.nq), kvp=80.0, k_irp_gy=0.01, field_mm=(100.0, 100.0), name="e1")
    with pytest.raises(DoseError, match=match) as info:
        dose.Event(**(args | changes))
    assert isinstance(info.value, CarmkinError) and "event 'e1'" in str(info.value)


def test_bad_calls_are_refused():
    e = ap_event(10.0, 0.785)
    with pytest.raises(DoseError, match="at least one"):
        dose.skin_dose(SYSTEM, [], flat(0.0))
    with pytest.raises(DoseError, match=r"events\[1\] must be a carmkin.dose.Event"):
        dose.skin_dose(SYSTEM, [e, "x"], flat(0.0))
    with pytest.raises(DoseError, match="patient must be"):
        dose.skin_dose(SYSTEM, [e], "patient")
    with pytest.raises(DoseError, match="joints"):
        dose.skin_dose(SYSTEM, [dose.Event(np.zeros(6), 80.0, 0.01, (100.0, 100.0), hvl_mm_al=4.0)], flat(0.0))
    with pytest.raises(PatientModelError, match="patient: the patient floats"):
        dose.skin_dose(SYSTEM, [e], ParametricPatient())  # its back at the isocentre, above the table top
    with pytest.raises(DoseError, match="spacing"):
        dose.skin_dose(SYSTEM, [e], ParametricPatient.on_table(SYSTEM), spacing=0.0)
    with pytest.raises(DoseError, match=r"not in the HVL table"):
        dose.skin_dose(SYSTEM, [dose.Event(np.zeros(SYSTEM.nq), 80.0, 0.01, (100.0, 100.0), filter={"Cu": 0.25})],
                       flat(0.0))


def test_the_hvl_and_table_lookups_return_the_tables_rows():
    assert coefficients.half_value_layer(77.0, 0.6, 0.0) > coefficients.half_value_layer(77.0, 0.0, 0.0)
    assert coefficients.table_transmission(50, 0, 0, "AXIOM-Artis", "Single Plane") == 0.5974  # the CSV's first row
    assert coefficients.table_transmission(80, 0, 0, "Unknown C-arm") is None


def test_plane_and_cylinder_phantoms_lie_on_the_table_top():
    top = SYSTEM.table.top_center[1] - SYSTEM.table.top_size[1] / 2
    head = SYSTEM.table.top_center[2] + SYSTEM.table.top_size[2] / 2
    p = dose.plane(SYSTEM)
    assert np.allclose(p.points[:, 1], top - 0.04) and p.points[:, 2].max() == pytest.approx(head)
    c = dose.cylinder(SYSTEM)
    assert c.points[:, 1].max() == pytest.approx(top - 0.04, abs=1e-3)  # its lowest line on the pad
    centre = np.array([0.0, top - 0.04 - 0.10])
    assert np.all(np.einsum("ij,ij->i", c.normals[:, :2], c.points[:, :2] - centre) > 0)  # outward
