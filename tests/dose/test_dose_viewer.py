"""The dose map in the browser viewer: the skin as a coloured mesh (one square per cell, the hot scale from 0 to the
PSD), `carmkin dose plan --html` / `dose map --html`, and the page rendered by headless Chromium."""

import base64
import re

import numpy as np
import pytest
import umsgpack
from hypothesis import given, settings
from hypothesis import strategies as st

import carmkin
from carmkin import dose
from carmkin.cli import main
from carmkin.errors import VisualizationError
from carmkin.viz.dose import HOT_STOPS, NO_DOSE_RGB, dose_colours, dose_page

SYSTEM = carmkin.load_preset("angio-floor")
#: Colours travel as float32 in the page.
FLOAT32 = 1e-6


@pytest.fixture(scope="module")
def patient():
    from carmkin.patient import ParametricPatient

    return ParametricPatient.on_table(SYSTEM, height=1.7)


@pytest.fixture(scope="module")
def ap_map(patient):
    """Three runs of the AP view (source above) on the parametric patient: a field on the anterior trunk."""
    from carmkin.views import View, plan_view

    view = plan_view(SYSTEM, View.from_angles(180.0, 0.0, [0.0, 0.03, 0.0], position=patient), patient)
    assert view.success
    lateral = plan_view(SYSTEM, View.from_angles(90.0, 0.0, [0.0, 0.03, 0.0], position=patient), patient)
    plan = dose.plan_dose(SYSTEM, [view, view, lateral], patient, dose.Technique(frames=10, field_mm=(250, 250)),
                          spacing=0.02)
    return view.q, plan.map


def page_commands(html: str) -> list[dict]:
    blobs = re.findall(r'data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"', html)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def skin_mesh(html: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices (V, 3), colours (V, 3), faces (F, 3)) of the dose node's skin mesh in a page."""
    (command,) = [c for c in page_commands(html) if c["type"] == "set_object" and c["path"].endswith("/dose/skin")]
    (geometry,) = command["object"]["geometries"]
    attrs = geometry["data"]["attributes"]

    def array(packed, dtype):
        return np.frombuffer(packed["array"].data, dtype=dtype).reshape(-1, packed["itemSize"])

    return (array(attrs["position"], np.float32), array(attrs["color"], np.float32),
            array(geometry["data"]["index"], np.uint32))


def test_the_page_holds_one_coloured_square_per_cell_on_the_hot_scale(ap_map):
    q, m = ap_map
    html = dose_page(SYSTEM, m, q)
    vertices, colours, faces = skin_mesh(html)
    n = len(m.cells)
    assert vertices.shape == (4 * n, 3) and colours.shape == (4 * n, 3) and faces.shape == (2 * n, 3)
    # each cell's four vertices surround it and share its colour
    assert np.allclose(vertices.reshape(n, 4, 3).mean(axis=1), m.cells, atol=1e-6)
    cell_rgb = colours[::4]
    assert np.array_equal(colours.reshape(n, 4, 3), np.repeat(cell_rgb[:, None], 4, axis=1))
    hit = m.dose_gy > 0
    assert hit.sum() > 20 and (~hit).sum() > 20
    assert np.allclose(cell_rgb[~hit], NO_DOSE_RGB, atol=FLOAT32)
    # monotone in dose: sorted by dose, every channel non-decreasing
    order = np.argsort(m.dose_gy[hit], kind="stable")
    assert np.all(np.diff(cell_rgb[hit][order], axis=0) >= -FLOAT32)
    # the hottest cell is the scale's top (white, stated independently of the scale's code) and the legend says
    # the max is the PSD
    assert np.allclose(cell_rgb[np.argmax(m.dose_gy)], (1.0, 1.0, 1.0), atol=FLOAT32)
    assert HOT_STOPS[-1][1] == (1.0, 1.0, 1.0)
    assert f'<span id="carmkin-dose-max">{m.psd_gy * 1e3:.4g}</span> mGy (max)' in html
    # the PSD marked where the map says
    (mark,) = [c for c in page_commands(html) if c["type"] == "set_transform" and c["path"].endswith("/dose/psd")]
    assert np.allclose(np.array(mark["matrix"]).reshape(4, 4).T[:3, 3], m.psd_point, atol=1e-6)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(0.0, 10.0, allow_nan=False), min_size=2, max_size=40))
def test_dose_colours_are_monotone_and_reach_the_top_at_the_max(doses):
    d = np.array(doses)
    top = max(float(d.max()), 1e-3)
    rgb = dose_colours(d, top)
    order = np.argsort(d, kind="stable")
    dosed = order[d[order] > 0]
    assert np.all(np.diff(rgb[dosed], axis=0) >= 0)
    assert np.all(rgb[d == 0] == NO_DOSE_RGB)
    if d.max() == top:
        assert np.allclose(rgb[np.argmax(d)], (1.0, 1.0, 1.0))


@pytest.mark.parametrize("doses, top, words", [
    ([0.0, 2.0], 1.0, "dose_gy must lie in [0, max_gy = 1000 mGy]"),
    ([0.0, -1.0], 1.0, "dose_gy must lie in"),
    ([0.0, 1.0], 0.0, "max_gy must be a positive finite dose"),
])
def test_dose_colours_refuse_a_dose_off_the_scale(doses, top, words):
    with pytest.raises(VisualizationError, match=re.escape(words)):
        dose_colours(np.array(doses), top)


def test_dose_plan_html_writes_the_map_on_the_skin(tmp_path, capsys):
    page = tmp_path / "plan.html"
    argv = ["dose", "plan", "--view-deg", "0,0", "--target-mm", "0,30,0", "--frames", "5", "--spacing-mm", "30",
            "--patient-height-mm", "1700", "--json", str(tmp_path / "p.json"), "--html", str(page)]
    assert main(argv) == 0
    assert f"wrote {page}" in capsys.readouterr().out
    import json

    data = json.loads((tmp_path / "p.json").read_text())
    vertices, colours, _ = skin_mesh(page.read_text())
    assert len(vertices) == 4 * data["cells"]
    assert np.allclose(colours.max(axis=0), (1.0, 1.0, 1.0), atol=FLOAT32)  # the PSD's cell at the scale's top
    assert f'<span id="carmkin-dose-max">{data["psd_mgy"]:.4g}</span>' in page.read_text()


def test_dose_map_html_writes_the_report_on_the_plane(tmp_path, capsys):
    pytest.importorskip("pydicom", reason="carmkin dose map reads reports with pydicom (extra dose)")
    from test_rdsr import event_items, write

    path = write(tmp_path / "r.dcm", [event_items()] * 2)
    page = tmp_path / "map.html"
    assert main(["dose", "map", "--rdsr", str(path), "--spacing-mm", "20", "--html", str(page)]) == 0
    expected = dose.skin_dose(SYSTEM, dose.read_rdsr(path, SYSTEM), dose.plane(SYSTEM, spacing=0.02))
    vertices, colours, _ = skin_mesh(page.read_text())
    assert len(vertices) == 4 * len(expected.cells)
    assert np.allclose(colours[::4][np.argmax(expected.dose_gy)], (1.0, 1.0, 1.0), atol=FLOAT32)


def test_dose_html_to_a_missing_folder_is_one_line(tmp_path, capsys):
    assert main(["dose", "plan", "--view-deg", "0,0", "--html", str(tmp_path / "no" / "p.html")]) == 2
    err = capsys.readouterr().err
    assert "--html" in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_headless_chromium_shows_the_dosed_skin(ap_map, tmp_path):
    """The page rendered: the field's cells change the picture against the same map with no dose (negative
    control: the map's cells all drawn in the no-dose colour)."""
    from carmkin.errors import BrowserNotFoundError
    from carmkin.viz import find_chromium, screenshot

    try:
        find_chromium()
    except BrowserNotFoundError as exc:
        pytest.skip(f"headless browser test skipped: {exc}")
    import dataclasses

    from PIL import Image

    q, m = ap_map
    pages = {"dose": m, "none": dataclasses.replace(m, dose_gy=np.zeros_like(m.dose_gy), psd_gy=0.0)}
    images = {}
    for name, shown in pages.items():
        html = tmp_path / f"{name}.html"
        html.write_text(dose_page(SYSTEM, shown, q), encoding="utf-8")
        images[name] = np.asarray(Image.open(screenshot(html, tmp_path / f"{name}.png")).convert("RGB"), float)
    assert images["dose"].std() > 10, "blank screenshot"
    legend = 100  # rows of the legend, which states the two scales' maxima
    changed = np.abs(images["dose"][legend:] - images["none"][legend:]).max(axis=-1) > 30
    assert changed.sum() > 100, f"only {changed.sum()} pixels show the dose"


def test_a_surface_skin_is_drawn_as_its_own_triangles_coloured_by_vertex():
    """A closed surface's map (an octahedron of 5 cm about the isocentre, in the AP beam) keeps its faces; the page
    draws them, one vertex per cell, each in its cell's colour."""
    vertices = 0.05 * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    faces = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    skin = dose.from_surface(vertices, faces)
    event = dose.Event(np.zeros(SYSTEM.nq), kvp=80.0, k_irp_gy=0.01, field_mm=(200.0, 200.0), filter={"Cu": 0.3})
    m = dose.skin_dose(SYSTEM, [event], skin)
    assert np.array_equal(m.faces, faces) and 0 < np.count_nonzero(m.dose_gy) < 6
    drawn, colours, triangles = skin_mesh(dose_page(SYSTEM, m))
    assert np.allclose(drawn, vertices, atol=1e-7) and np.array_equal(triangles, faces)
    assert np.allclose(colours, dose_colours(m.dose_gy, m.psd_gy), atol=FLOAT32)
    assert np.allclose(colours[np.argmax(m.dose_gy)], (1.0, 1.0, 1.0), atol=FLOAT32)
