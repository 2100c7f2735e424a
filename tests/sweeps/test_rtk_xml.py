"""RTK's geometry file without RTK (carmkin.sweeps.rtk_xml): each written matrix takes a world point to where
its ray from the source meets the detector plane, in coordinates from the detector position along the detector's
row and column directions (an oracle of plain geometry), the source to the matrix's null space; with the cbct extra, RTK's own reader reads
the file back to the matrices RTK's ``AddProjection`` makes, and RTK's own writer writes the same numbers."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import carmkin
from carmkin.errors import SweepError
from carmkin.sweeps import export, plan_sweep, rtk_xml

PRESET = carmkin.load_preset("siremobile-iso-c3d")


def matrices(path) -> np.ndarray:
    root = ET.parse(path).getroot()
    assert root.tag == "RTKThreeDCircularGeometry" and root.get("version") == str(rtk_xml.VERSION)
    return np.array([np.array(p.find("Matrix").text.split(), float).reshape(3, 4) for p in root.iter("Projection")])


def frame(seed: int):
    rng = np.random.default_rng(seed)
    R = Rotation.random(random_state=rng).as_matrix()
    source = rng.normal(size=3) * 600.0
    detector = source + R[:, 2] * rng.uniform(300.0, 1500.0) + R[:, :2] @ rng.normal(size=2) * 30.0
    return source, detector, R[:, 0], R[:, 1]


@settings(max_examples=60)
@given(st.integers(0, 2**32 - 1))
def test_a_written_matrix_projects_through_the_source_onto_the_detector(tmp_path_factory, seed):
    source, detector, row, column = frame(seed)
    path = rtk_xml.write(tmp_path_factory.mktemp("rtk") / "g.xml", [source], [detector], [row], [column])
    M = matrices(path)[0]
    scale = np.abs(M).max()
    assert np.abs(M @ np.r_[source, 1.0]).max() <= 1e-9 * scale * np.linalg.norm(source)
    normal = np.cross(row, column)
    for point in np.random.default_rng(seed).normal(size=(5, 3)) * 200.0:
        t = ((detector - source) @ normal) / ((point - source) @ normal)
        if abs((point - source) @ normal) < 1e-6 or t < 0:
            continue
        hit = source + t * (point - source)  # where the ray meets the detector plane
        m = M @ np.r_[point, 1.0]
        np.testing.assert_allclose(m[:2] / m[2], [(hit - detector) @ row, (hit - detector) @ column], rtol=1e-8,
                                   atol=1e-6)


def test_gimbal_locked_frames_are_written():
    """A detector whose column direction is the world's Z (out-of-plane angle ±90°) needs the fallback angles."""
    for column in ([0.0, 0.0, 1.0], [0.0, 0.0, -1.0]):
        p = rtk_xml.projection_parameters([0, -600.0, 0], [0, 400.0, 0], [1.0, 0.0, 0.0], column)
        rebuilt = rtk_xml.zxy_matrix(-p["OutOfPlaneAngle"], -p["GantryAngle"], -p["InPlaneAngle"])
        np.testing.assert_allclose(rebuilt, [[1, 0, 0], column, np.cross([1.0, 0.0, 0.0], column)], atol=1e-12)


def test_non_orthogonal_detector_axes_are_refused():
    with pytest.raises(SweepError, match="orthogonal"):
        rtk_xml.projection_parameters([0, 0, -600.0], [0, 0, 400.0], [1.0, 0, 0], [0.1, 1.0, 0])


def test_shared_values_are_written_once(tmp_path):
    sweep = plan_sweep(PRESET, [0.0, 0.0, 0.0], n_views=12)
    export.write_rtk_xml(sweep, tmp_path / "g.xml")
    text = (tmp_path / "g.xml").read_text()
    assert text.count("<GantryAngle>") == 12 and text.count("<Matrix>") == 12
    for name, _ in rtk_xml.FIELDS:
        assert text.count(f"<{name}>") in (0, 1, 12), name


@pytest.fixture(scope="module")
def rtk():
    pytest.importorskip("itk", reason="comparing with RTK needs the cbct extra (itk-rtk)")
    return export._rtk()[1]


@pytest.mark.parametrize("layout", export.RTK_LAYOUTS)
@pytest.mark.parametrize("views", [5, 40])
def test_rtk_reads_our_file_as_its_own_geometry(rtk, tmp_path, layout, views):
    sweep = plan_sweep(PRESET, [0.0, 0.0, 0.0], n_views=views)
    export.write_rtk_xml(sweep, tmp_path / "ours.xml", layout=layout)
    reader = rtk.ThreeDCircularProjectionGeometryXMLFileReader.New()
    reader.SetFilename(str(tmp_path / "ours.xml"))
    reader.GenerateOutputInformation()
    theirs = export.rtk_geometry(sweep, layout=layout)
    expected = export.rtk_matrices(theirs)
    np.testing.assert_allclose(export.rtk_matrices(reader.GetOutputObject()), expected, rtol=0,
                               atol=1e-12 * np.abs(expected).max())
    writer = rtk.ThreeDCircularProjectionGeometryXMLFileWriter.New()
    writer.SetFilename(str(tmp_path / "theirs.xml"))
    writer.SetObject(theirs)
    writer.WriteFile()
    ours, theirs_text = (tmp_path / "ours.xml").read_text(), (tmp_path / "theirs.xml").read_text()
    number = r"[-+]?\d[\d.]*(?:e[-+]?\d+)?"

    def layout_of(text: str) -> str:  # the elements and their order; number widths aside
        return re.sub(r"[ ]+", " ", re.sub(number, "N", text))

    assert layout_of(ours) == layout_of(theirs_text)
    a, b = (np.array(re.findall(number, t), float) for t in (ours, theirs_text))
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)
