"""Exports re-projected by each receiving package's own convention: RTK's GetMatrix (itk-rtk, the cbct extra;
skipped without it), ASTRA's cone_vec projectPoint and TIGRE's computeDeltas_Siddon formulas (numpy, written
here from the packages' sources), DICOM XA angles back to poses. Acceptance (issue 22): RTK's matrix equals
our P (normalised) to 1e-9 relative; ASTRA and TIGRE land within 1e-6 px of P."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from strategies import PRESET

from carmkin.interop.dicom import pose_from_xa_angles
from carmkin.sweeps import astra_vectors, export, plan_sweep, positioner_angles, tigre_geometry

RTK_RELATIVE = 1e-9
PIXEL_TOLERANCE = 1e-6


@pytest.fixture(scope="module")
def sweeps():
    """The preset's sweep and a non-isocentric one with an off-centre principal point and square-ish pixels."""
    odd = PRESET.replace(carm=dataclasses.replace(PRESET.carm, a1=0.05, a2=0.04, principal_point=(390.3, 310.7),
                                                  detector_rows=500))
    return [plan_sweep(PRESET, [0.0, 0.0, 0.0], n_views=100),
            plan_sweep(odd, [0.1, -0.2, 0.0], n_views=37, joint={"orbital": 1.0, "angular": 0.2}, arc_deg=120.0)]


def _points(sweep, n=50):
    return sweep.target + np.random.default_rng(1).uniform(-0.07, 0.07, size=(n, 3))


def _project(P, X):
    m = np.c_[X, np.ones(len(X))] @ P.T
    return m[:, :2] / m[:, 2:]


def _on_detector(source, corner, du, dv, X):
    """(a, b) with the ray source→X meeting the detector plane at corner + a du + b dv."""
    n = np.cross(du, dv)
    t = ((corner - source) @ n) / ((X - source) @ n)
    hit = source + t[:, None] * (X - source)
    return np.linalg.lstsq(np.c_[du, dv], (hit - corner).T, rcond=None)[0].T


def test_astra_vectors_project_like_P(sweeps):
    for sweep in sweeps:
        V = astra_vectors(sweep)
        assert V.shape == (sweep.n_views, 12)
        rows, cols = sweep.system.carm.detector_rows, sweep.system.carm.detector_columns
        X = _points(sweep)
        worst = 0.0
        for k in range(sweep.n_views):
            src, d, u, v = V[k, :3], V[k, 3:6], V[k, 6:9], V[k, 9:]
            corner = d - 0.5 * rows * v - 0.5 * cols * u  # ASTRA: fDetS (pixel (0, 0)'s corner)
            uv = _on_detector(src, corner, u, v, X * 1e3) - 0.5  # projectPoint: "−0.5 shifts corner to centre"
            worst = max(worst, np.abs(uv - _project(sweep.P[k], X)).max())
        print(f"\nASTRA cone_vec vs P: {worst:.2e} px over {sweep.n_views} frames")
        assert worst < PIXEL_TOLERANCE


def _zyz(a, t, p):
    ca, sa, ct, st, cp, sp = math.cos(a), math.sin(a), math.cos(t), math.sin(t), math.cos(p), math.sin(p)
    return np.array([[ca * ct * cp - sa * sp, -ca * ct * sp - sa * cp, ca * st],
                     [sa * ct * cp + ca * sp, -sa * ct * sp + ca * cp, sa * st], [-st * cp, st * sp, ct]])


def test_tigre_arrays_project_like_P(sweeps):
    for sweep in sweeps:
        G = tigre_geometry(sweep)
        nV, nU = G["nDetector"]
        dV, dU = G["dDetector"]
        X = _points(sweep)
        worst = 0.0
        for k in range(sweep.n_views):
            DSO, DSD = G["DSO"][k], G["DSD"][k]
            off = G["offOrigin"][k][::-1]  # Python (z, y, x) -> (x, y, z)
            ov, ou = G["offDetector"][k]
            R = _zyz(*G["angles"][k])
            # computeDeltas_Siddon with rotDetector = 0, COR = 0, before the voxel scaling
            source = R @ [DSO, 0.0, 0.0] - off
            corner = R @ [-(DSD - DSO), dU * (-nU / 2 + 0.5) + ou, dV * (nV / 2 - 0.5) + ov] - off
            pixel_u, pixel_v = _on_detector(source, corner, R @ [0.0, dU, 0.0], R @ [0.0, 0.0, -dV],
                                            (X - sweep.target) * 1e3).T
            row = nV - 1 - pixel_v  # kernelPixelDetector: pixelV = nDetecV − v − 1
            ours = np.c_[pixel_u, nV - 1 - row]  # TIGRE's rows are ours flipped
            worst = max(worst, np.abs(ours - _project(sweep.P[k], X)).max())
        print(f"\nTIGRE arrays vs P: {worst:.2e} px over {sweep.n_views} frames")
        assert worst < PIXEL_TOLERANCE


def test_dicom_angles_give_back_the_poses(sweeps):
    for sweep in sweeps[:1]:  # the target is the isocentre of every frame
        angles = positioner_angles(sweep)
        for (primary, secondary, rotation), T in zip(angles, sweep.poses):
            back = pose_from_xa_angles(primary, secondary, sweep.target, sweep.distance, rotation_deg=rotation)
            np.testing.assert_allclose(back, T, atol=1e-9)


def _rtk_or_skip():
    return pytest.importorskip("itk", reason="the RTK export needs the cbct extra (itk-rtk)")


@pytest.mark.parametrize("layout", export.RTK_LAYOUTS)
def test_rtk_matrix_equals_P(sweeps, layout):
    _rtk_or_skip()
    for sweep in sweeps if layout == "image" else sweeps[:1]:
        M = export.rtk_matrices(export.rtk_geometry(sweep, layout=layout))
        A = export.pixel_from_detector(sweep, layout=layout)
        worst = 0.0
        for k in range(sweep.n_views):
            ours = sweep.P[k] / np.linalg.norm(sweep.P[k])
            theirs = A @ M[k] @ np.diag([1e3, 1e3, 1e3, 1.0])  # world m -> mm, detector mm -> px
            theirs /= np.linalg.norm(theirs) * np.sign(np.vdot(theirs, ours))
            worst = max(worst, np.abs(theirs - ours).max())
        print(f"\nRTK GetMatrix ({layout}) vs P: {worst:.2e} relative over {sweep.n_views} frames")
        assert worst < RTK_RELATIVE


def test_rtk_xml_round_trip(sweeps, tmp_path):
    _rtk_or_skip()
    from itk import RTK as rtk

    sweep = sweeps[1]
    export.write_rtk_xml(sweep, tmp_path / "geometry.xml")
    reader = rtk.ThreeDCircularProjectionGeometryXMLFileReader.New()
    reader.SetFilename(str(tmp_path / "geometry.xml"))
    reader.GenerateOutputInformation()
    read = export.rtk_matrices(reader.GetOutputObject())
    np.testing.assert_allclose(read, export.rtk_matrices(export.rtk_geometry(sweep)), rtol=1e-9, atol=1e-9)


def test_rtk_stack_order_matches_the_grid(sweeps):
    """to_rtk_stack puts our pixel (c, r) at the RTK index whose physical (u, v) maps back to (c, r)."""
    sweep = sweeps[0]
    rows, cols = sweep.system.carm.detector_rows, sweep.system.carm.detector_columns
    images = np.zeros((1, rows, cols))
    images[0, 17, 503] = 1.0
    for layout in export.RTK_LAYOUTS:
        stack = export.to_rtk_stack(sweep, images, layout)
        j, i = np.argwhere(stack[0] == 1.0)[0]
        origin, spacing, size = export.rtk_projection_grid(sweep, layout=layout)
        assert stack.shape[1:] == (size[1], size[0])
        u, v = origin[0] + i * spacing[0], origin[1] + j * spacing[1]
        np.testing.assert_allclose(export.pixel_from_detector(sweep, layout=layout) @ [u, v, 1.0], [503, 17, 1], atol=1e-9)


def test_rtk_without_the_extra_is_a_typed_error(sweeps, monkeypatch):
    import sys

    from carmkin.errors import MissingExtraError

    monkeypatch.setitem(sys.modules, "itk", None)  # as if itk-rtk were not installed
    with pytest.raises(MissingExtraError, match=r'pip install "carmkin\[cbct\]"'):
        export.rtk_geometry(sweeps[0])


def test_a_failed_sweep_is_never_exported(tmp_path):
    """Issue 31: a failed sweep's frames include poses the machine cannot take (here frames inside the table):
    every export refuses it, naming the failure, and the CLI writes no geometry file (exit 1)."""
    import carmkin
    from carmkin.cli import main
    from carmkin.errors import SweepError
    from carmkin.sweeps import export, plan_sweep

    system = carmkin.load_preset("siremobile-iso-c3d")
    failed = plan_sweep(system, (0.010, -0.040, 0.020), 120, 15, joint="angular")
    assert not failed.success and np.nanmin(failed.frame_clearance) < 0
    for call in (export.astra_vectors, export.tigre_geometry, export.positioner_angles, export.rtk_detector_axes,
                 export.pixel_from_detector):
        with pytest.raises(SweepError, match="failed sweep"):
            call(failed)
    with pytest.raises(SweepError, match="failed sweep"):
        export.write_rtk_xml(failed, tmp_path / "g.xml")
    astra = tmp_path / "vec.npy"
    code = main(["sweep", "plan", "--target-mm", "10,-40,20", "--arc-deg", "120", "--views", "15", "--joint",
                 "angular", "--astra", str(astra)])
    assert code == 1 and not astra.exists()
