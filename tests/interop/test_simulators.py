"""Simulator conventions (carmkin.interop.simulators): round trips over random non-isocentric systems without
any simulator installed, and — when the packages are present — the same conventions against the real code
(nanodrr's K⁻¹, DiffDRR's perspective_projection, killeengeo's CameraProjection)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import PRESET, configurations, systems

import carmkin
from carmkin import imaging
from carmkin.interop import simulators as sim

#: Round-trip tolerance of issue 15 (relative for pixels and mm).
ROUND_TRIP = 1e-9
#: Agreement with a simulator computing in float32 (killeengeo, torch float32), relative.
FLOAT32 = 2e-5

finite = dict(allow_nan=False, allow_infinity=False)


@st.composite
def cameras(draw):
    """A system with a random principal point and its K, size, SDD (mm)."""
    system = draw(systems())
    carm = system.carm
    pp = (draw(st.floats(-50, carm.detector_columns + 50, **finite)),
          draw(st.floats(-50, carm.detector_rows + 50, **finite)))
    system = system.replace(carm=dataclasses.replace(carm, principal_point=pp))
    K, size = imaging.intrinsics(system)
    return system, K, size, system.carm.source_to_detector * sim.MM


def world_points(data, T_mm, n=6):
    """Points (n, 3) in front of the source (mm)."""
    local = np.array(data.draw(st.lists(st.tuples(st.floats(-80, 80, **finite), st.floats(-80, 80, **finite),
                                                   st.floats(300, 900, **finite)), min_size=n, max_size=n)))
    return local @ T_mm[:3, :3].T + T_mm[:3, 3]


def pixels(P, X):
    m = np.column_stack((X, np.ones(len(X)))) @ P.T
    return m[:, :2] / m[:, 2:]


@given(cameras())
def test_nanodrr_and_diffdrr_detectors_round_trip(camera):
    _, K, size, sdd = camera
    for forward, backward in ((sim.nanodrr_detector, sim.intrinsics_from_nanodrr),
                              (sim.diffdrr_detector, sim.intrinsics_from_diffdrr)):
        detector = forward(K, size, sdd)
        assert (detector.width, detector.height) == size and detector.sdd == sdd
        assert np.abs(backward(detector) - K).max() <= ROUND_TRIP * np.abs(K).max()


@given(st.data())
def test_diffdrr_pose_is_an_involution_and_a_half_turn_about_the_principal_axis(data):
    system = data.draw(systems())
    T = sim.to_millimetres(system.fk(data.draw(configurations(system))))
    D = sim.diffdrr_pose(T)
    assert np.array_equal(sim.diffdrr_pose(D), T)
    assert np.array_equal(D[:3, 2], T[:3, 2]) and np.array_equal(D[:3, 3], T[:3, 3])
    assert np.array_equal(D[:3, 0], -T[:3, 0]) and np.array_equal(D[:3, 1], -T[:3, 1])


@given(st.data())
def test_deepdrr_camera_projection_round_trip_and_half_pixel(data):
    system, K, _, _ = data.draw(cameras())
    T = sim.to_millimetres(system.fk(data.draw(configurations(system))))
    intrinsic, extrinsic = sim.deepdrr_camera_projection(K, T)
    K2, T2 = sim.from_deepdrr_camera_projection(intrinsic, extrinsic)
    assert np.abs(K2 - K).max() <= ROUND_TRIP * np.abs(K).max()
    assert np.abs(T2 - T).max() <= ROUND_TRIP * max(1.0, np.abs(T).max())
    X = world_points(data, T)
    ours = pixels(imaging.projection_from_pose(K, T), X)
    theirs = pixels(intrinsic @ extrinsic[:3], X)
    assert np.abs(theirs - ours - 0.5).max() <= ROUND_TRIP * np.abs(ours).max()


@st.composite
def mobile_carm_systems(draw):
    """Random systems with a1 = 0 (a2, l1, l2 and the table setup random)."""
    system = draw(systems())
    return system.replace(carm=dataclasses.replace(system.carm, a1=0.0))


@given(st.data())
def test_deepdrr_mobile_carm_reproduces_the_chain(data):
    system = data.draw(mobile_carm_systems())
    q = data.draw(configurations(system, beyond=0.5))
    state = sim.deepdrr_mobile_carm(system, q)
    T = sim.mobile_carm_source_pose(state)
    expected = sim.to_millimetres(system.fk(q))
    assert np.abs(T - expected).max() <= ROUND_TRIP * max(1.0, np.abs(expected).max())


def test_deepdrr_mobile_carm_on_the_motorized_table():
    system = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = system.lower + rng.random(system.nq) * (system.upper - system.lower)
        T = sim.mobile_carm_source_pose(sim.deepdrr_mobile_carm(system, q))
        assert np.abs(T - sim.to_millimetres(system.fk(q))).max() <= ROUND_TRIP * 1e3


def test_deepdrr_mobile_carm_refuses_an_offset_orbital_axis():
    system = PRESET.replace(carm=dataclasses.replace(PRESET.carm, a1=0.05))
    with pytest.raises(sim.SimulatorConventionError, match="a1 must be 0"):
        sim.deepdrr_mobile_carm(system, 0.5 * (system.lower + system.upper))


def test_bad_detector_inputs_raise():
    K, size = imaging.intrinsics(PRESET)
    with pytest.raises(sim.SimulatorConventionError, match="sdd_mm"):
        sim.nanodrr_detector(K, size, -1.0)
    skewed = K.copy()
    skewed[0, 1] = 1.0
    with pytest.raises(sim.SimulatorConventionError, match="skew"):
        sim.diffdrr_detector(skewed, size, 980.0)


# --- against the real packages (optional) -------------------------------------------------------------------
@settings(max_examples=20)
@given(cameras())
def test_nanodrr_inverse_intrinsics_match(camera):
    pytest.importorskip("torch", reason="nanodrr's intrinsics need torch (the drr extra)")
    intrinsics = pytest.importorskip("nanodrr.camera.intrinsics", reason="needs nanodrr (the drr extra)")
    _, K, size, sdd = camera
    d = sim.nanodrr_detector(K, size, sdd)
    import torch

    k_inv = intrinsics.make_k_inv(d.sdd, d.delx, d.dely, d.x0, d.y0, d.height, d.width,
                                  dtype=torch.float64)[0].numpy()
    shifted = K.copy()
    shifted[:2, 2] += 0.5
    assert np.abs(k_inv @ shifted - np.eye(3)).max() <= ROUND_TRIP


@settings(max_examples=10)
@given(st.data())
def test_killeengeo_camera_projection_matches(data):
    kg = pytest.importorskip("killeengeo", reason="needs DeepDRR's geometry package (pip install killeengeo)")
    system, K, _, _ = data.draw(cameras())
    T = sim.to_millimetres(system.fk(data.draw(configurations(system))))
    intrinsic, extrinsic = sim.deepdrr_camera_projection(K, T)
    projection = kg.CameraProjection(intrinsic, extrinsic)
    X = world_points(data, T)
    theirs = np.array([np.array(projection @ kg.point(*x))[:2] for x in X])
    ours = pixels(imaging.projection_from_pose(K, T), X) + 0.5
    assert np.abs(theirs - ours).max() <= FLOAT32 * np.abs(ours).max()


def test_diffdrr_perspective_projection_matches():
    """DiffDRR's own projection of points, with our pose and detector converted, lands on our pixels."""
    torch = pytest.importorskip("torch", reason="DiffDRR needs torch (the drr extra)")
    drr_module = pytest.importorskip("diffdrr.drr", reason="needs DiffDRR with its dependencies")
    data_module = pytest.importorskip("diffdrr.data")
    from torchio import ScalarImage

    from diffdrr.pose import RigidTransform

    system = PRESET.replace(carm=dataclasses.replace(PRESET.carm, principal_point=(380.0, 310.0)))
    K, size = imaging.intrinsics(system)
    volume = ScalarImage(tensor=torch.zeros(1, 8, 8, 8), affine=np.diag([10.0, 10.0, 10.0, 1.0]))
    subject = data_module.read(volume=volume, orientation=None, center_volume=False)
    d = sim.diffdrr_detector(K, size, system.carm.source_to_detector * sim.MM)
    drr = drr_module.DRR(subject, sdd=d.sdd, height=d.height, delx=d.delx, width=d.width, dely=d.dely,
                         x0=d.x0, y0=d.y0)
    rng = np.random.default_rng(0)
    for _ in range(5):
        q = system.lower + rng.random(6) * (system.upper - system.lower)
        T = sim.to_millimetres(system.fk(q))
        X = T[:3, 3] + (rng.uniform(-60, 60, (6, 3)) + (0, 0, 600)) @ T[:3, :3].T
        pose = RigidTransform(torch.tensor(sim.diffdrr_pose(T), dtype=torch.float64)[None])
        drr = drr.to(torch.float64)
        theirs = drr.perspective_projection(pose, torch.tensor(X, dtype=torch.float64)[None])[0].numpy()
        ours = pixels(imaging.projection_from_pose(K, T), X) + 0.5
        assert np.abs(theirs - ours).max() <= 1e-6 * np.abs(ours).max()


# --- issue 19: a K whose last row is not (0, 0, 1) is refused, never dropped ----------------------------
@pytest.mark.parametrize("make", ["nanodrr_detector", "diffdrr_detector"])
@pytest.mark.parametrize("row", [(0.0, 0.0, 5.0), (0.0, 0.0, 0.2), (1e-3, 0.0, 1.0), (0.0, 0.0, 0.0)])
def test_detector_refuses_a_k_with_a_wrong_last_row(make, row):
    # before: K[2] was dropped, a focal length 5x off in the simulator for K[2, 2] = 5
    from carmkin.errors import SimulatorConventionError
    from carmkin.interop import simulators

    system = carmkin.load_preset("siremobile-iso-c3d")
    K = system.carm.intrinsics().copy()
    K[2] = row
    with pytest.raises(SimulatorConventionError, match="K"):
        getattr(simulators, make)(K, (system.carm.detector_columns, system.carm.detector_rows), 1000.0)


@pytest.mark.parametrize("size", [None, "ab", (0, 10), (True, 10), (10.5, 10), (10,)])
def test_detector_refuses_bad_sizes(size):
    from carmkin.errors import SimulatorConventionError
    from carmkin.interop import simulators

    with pytest.raises(SimulatorConventionError):
        simulators.nanodrr_detector(np.diag([1000.0, 1000.0, 1.0]), size, 1000.0)


# --- xvr and flashdrr (issue 28) -----------------------------------------------------------------------------
@st.composite
def poses_mm(draw):
    """A source pose (mm) in a CT world."""
    from strategies import poses

    T = draw(poses())
    T[:3, 3] *= 400.0
    return T


@settings(max_examples=60)
@given(poses_mm(), st.sampled_from(["AP", None]), st.lists(st.floats(-200, 200, **finite), min_size=3, max_size=3))
def test_xvr_pose_round_trip(T, orientation, iso):
    rotation, translation = sim.xvr_pose(T, orientation, iso)
    assert np.allclose(sim.from_xvr_pose(rotation, translation, orientation, iso), T, atol=ROUND_TRIP * 1e3, rtol=0)
    assert -90.0 <= rotation[1] <= 90.0


def test_xvr_pose_is_nanodrrs_make_rt_inv():
    """The parameters read back rebuild our pose through nanodrr's own make_rt_inv (what xvr samples)."""
    torch = pytest.importorskip("torch", reason="needs torch (the drr extra)")
    extrinsics = pytest.importorskip("nanodrr.camera.extrinsics", reason="needs nanodrr (the drr extra)")
    rng = np.random.default_rng(2)
    for orientation in ("AP", None):
        for _ in range(10):
            rotation = rng.uniform(-180, 180, 3) * np.array([1.0, 0.45, 1.0])
            translation, iso = rng.uniform(-500, 500, 3), rng.uniform(-100, 100, 3)
            theirs = extrinsics.make_rt_inv(torch.tensor(rotation[None]), torch.tensor(translation[None]), orientation,
                                            torch.tensor(iso))[0].numpy()
            ours = sim.from_xvr_pose(rotation, translation, orientation, iso)
            assert np.allclose(ours, theirs, atol=1e-9, rtol=0)
            back = sim.xvr_pose(theirs, orientation, iso)
            assert np.allclose(back[1], translation, atol=1e-9)


def test_xvr_refuses_an_unknown_orientation_and_the_mirrored_pa():
    with pytest.raises(sim.SimulatorConventionError, match="orientation must be"):
        sim.xvr_pose(np.eye(4), "LAT")
    assert np.isclose(np.linalg.det(sim.XVR_ORIENTATIONS["PA"][:3, :3]), -1.0)
    with pytest.raises(sim.SimulatorConventionError, match="reflection"):
        sim.from_xvr_pose([0, 0, 0], [0, 0, 0], "PA")


@settings(max_examples=60)
@given(poses_mm())
def test_flashdrr_view_matrix_round_trip_and_vtk_axes(T):
    M = sim.flashdrr_view_matrix(T)
    assert np.allclose(sim.from_flashdrr_view_matrix(M), T, atol=ROUND_TRIP, rtol=0)
    right, up, forward = M[:3, 0], M[:3, 1], M[:3, 2]  # get_vtk_view_mat: right = forward × up
    assert np.allclose(np.cross(forward, up), right, atol=1e-12) and np.isclose(np.linalg.det(M[:3, :3]), -1.0)


@settings(max_examples=40)
@given(st.floats(5.0, 60.0), st.integers(2, 900), st.integers(2, 900), st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_flashdrr_rays_land_on_their_pixels(fov, width, height, fx, fy):
    """flashdrr's ray through pixel (j, i), re-derived from set_fov, projects by our K to (j, i)."""
    K = sim.intrinsics_from_flashdrr(fov, (width, height))
    j, i = fx * (width - 1), fy * (height - 1)
    x, y = -1 + 2 * j / (width - 1), -1 + 2 * i / (height - 1)
    t = np.tan(np.radians(fov) / 2)
    ray_vtk = np.array([x * t * width / height, -y * t, 1.0])  # camera axes (right, up, forward)
    ray_ours = np.diag([1.0, -1.0, 1.0]) @ ray_vtk
    m = K @ ray_ours
    assert np.allclose(m[:2] / m[2], [j, i], atol=1e-9 * max(width, height))
    assert np.isclose(sim.flashdrr_fov_deg(K, (width, height)), fov, atol=1e-9)


def test_flashdrr_refuses_an_off_centre_principal_point():
    K = sim.intrinsics_from_flashdrr(20.0, (200, 150))
    K[0, 2] += 1.0
    with pytest.raises(sim.SimulatorConventionError, match="image centre"):
        sim.flashdrr_fov_deg(K, (200, 150))


@settings(max_examples=60)
@given(st.floats(300, 1200), st.floats(-80, 80), st.floats(-85, 85), st.floats(-100, 100),
       st.lists(st.floats(-200, 200, **finite), min_size=3, max_size=3))
def test_flashdrr_carm_round_trip(sid, ap, lat, si, centre):
    T = sim.flashdrr_carm_pose(sid, ap, lat, centre, si)
    # carm_to_camera_params re-derived: source at R (0, −sid, 0) + centre', looking at centre', up R (0, 0, 1).
    a, b = np.radians(ap), np.radians(lat)
    R_ap = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    R_lat = np.array([[np.cos(b), -np.sin(b), 0], [np.sin(b), np.cos(b), 0], [0, 0, 1]])
    c = np.array(centre) + [0, 0, si]
    assert np.allclose(T[:3, 3], R_ap @ R_lat @ [0, -sid, 0] + c, atol=1e-9)
    assert np.allclose(T[:3, 2], (c - T[:3, 3]) / sid, atol=1e-12)
    assert np.allclose(-T[:3, 1], R_ap @ R_lat @ [0, 0, 1], atol=1e-12)
    assert np.allclose(sim.flashdrr_carm_parameters(T, centre), (sid, ap, lat, si), atol=1e-7)


def test_flashdrr_refuses_a_pose_it_cannot_take():
    T = sim.flashdrr_carm_pose(800.0, 10.0, 20.0, (0, 0, 0))
    rolled = T.copy()
    rolled[:3, :2] = T[:3, :2] @ np.array([[0.0, -1.0], [1.0, 0.0]])
    with pytest.raises(sim.SimulatorConventionError, match="not one of flashdrr"):
        sim.flashdrr_carm_parameters(rolled, (0, 0, 0))
