"""Panorama planning (Table 4.3, §4.4.1–4.4.4), the simulated parallax check and the `panorama` CLI."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import configurations, finite, systems

import carmkin
from carmkin import imaging
from carmkin.cli import main
from carmkin.panorama import CATEGORIES, PanoramaError, PanoramaPlanner, phantom
from carmkin.transforms import pose_residual

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")
PLANNER = PanoramaPlanner(SYSTEM, fallback=False)
K = SYSTEM.carm.intrinsics()
MODEL = SYSTEM.pinocchio()[0]
CENTRE = np.array([K[0, 2], K[1, 2]])
W, H = SYSTEM.carm.detector_columns, SYSTEM.carm.detector_rows

principal_points = st.tuples(st.floats(-3 * W, 4 * W, **finite), st.floats(-2 * H, 3 * H, **finite))


def pixel(K_, X):
    m = K_ @ X
    return m[:2] / m[2]


def test_reference_shot_is_the_reference_pose():
    shot = PLANNER.shot(CENTRE)
    np.testing.assert_allclose(shot.R, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(shot.target, PLANNER.P_ref, atol=1e-15)
    assert shot.valid and shot.reasons == () and shot.path == "closed_form"
    np.testing.assert_allclose(shot.moves, 0.0, atol=1e-12)
    # the documented default reference: mid-range joints (0° for the revolute joints of this preset)
    np.testing.assert_allclose(PLANNER.q_reference, [0.0, 0.2, 0.0, 0.1, 0.0, 0.0], atol=1e-15)


@given(principal_points)
def test_shot_geometry(p):
    """Target = P_ref·[R 0; 0 1]: same source position, principal axis through K⁻¹p, H maps the shot's
    principal point onto p, and the shot image seen by the target pose lines up with H."""
    shot = PLANNER.shot(p, fallback=False)
    T = shot.target
    np.testing.assert_allclose(T[:3, 3], PLANNER.P_ref[:3, 3], atol=1e-15)
    axis_in_ref = PLANNER.P_ref[:3, :3].T @ T[:3, 2]
    np.testing.assert_allclose(pixel(K, axis_in_ref), p, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(imaging.apply_homography(shot.H, CENTRE)[0], p, rtol=1e-9, atol=1e-6)
    # a world point in front of both views: image of the shot mapped by H = image of the reference
    X = T[:3, 3] + 0.4 * T[:3, 2] + 0.01 * T[:3, 0]
    if (X - PLANNER.P_ref[:3, 3]) @ PLANNER.P_ref[:3, 2] > 0.05:
        np.testing.assert_allclose(imaging.apply_homography(shot.H, imaging.project(K, T, X)),
                                   imaging.project(K, PLANNER.P_ref, X), rtol=1e-9, atol=1e-6)
    # the roll is the minimal one: the rotation angle equals the tilt of the axis
    angle = np.arccos(np.clip((np.trace(shot.R) - 1) / 2, -1, 1))
    assert angle == pytest.approx(np.arccos(shot.axis[2]), abs=1e-7)


@given(principal_points)
def test_planned_joints_reach_the_target_and_invalid_shots_say_why(p):
    shot = PLANNER.shot(p, fallback=False)
    assert np.all(np.isfinite(shot.q))
    T = SYSTEM.fk(shot.q)
    np.testing.assert_allclose(T, shot.target, rtol=0, atol=1e-9)
    # and through Pinocchio's FK of the generated URDF (independent of the closed form)
    data = MODEL.createData()
    pin.framesForwardKinematics(MODEL, data, shot.q)
    np.testing.assert_allclose(data.oMf[MODEL.getFrameId("xray_source")].homogeneous, shot.target, atol=1e-9)
    if shot.valid:
        assert shot.reasons == () and shot.category == "valid"
        assert np.all(shot.q >= SYSTEM.lower) and np.all(shot.q <= SYSTEM.upper)
    else:
        assert shot.reasons and shot.category in CATEGORIES[1:]
        if shot.category == "joint out of range":
            assert np.any(shot.q < SYSTEM.lower) or np.any(shot.q > SYSTEM.upper)
            assert any("out of range" in r for r in shot.reasons)
        if shot.category == "collision":
            assert any("intersects" in r for r in shot.reasons)
    np.testing.assert_allclose(shot.moves, shot.q - PLANNER.q_reference, atol=1e-15)


@settings(max_examples=25)
@given(st.data())
def test_planned_joints_reach_the_target_on_non_isocentric_systems(data):
    """Random non-isocentric systems and reference configurations: FK(q) = P_ref·[R 0; 0 1] to 1e-9."""
    system = data.draw(systems())
    planner = PanoramaPlanner(system, q_reference=data.draw(configurations(system)), fallback=False)
    shot = planner.shot(data.draw(principal_points), fallback=False)
    if shot.path == "none":  # the closed form could not solve a singular pose: it must say so
        assert shot.reasons and not shot.valid
        return
    np.testing.assert_allclose(system.fk(shot.q, check_units=False), shot.target, rtol=0, atol=1e-9)
    assert shot.valid == (shot.reasons == ())


def test_erratum_table_4_3_step_4_homography():
    """Table 4.3 step 4 prints H = K⁻¹RK: it does not put the shot's principal point at p; K R K⁻¹ does."""
    p = np.array([900.0, 450.0])
    shot = PLANNER.shot(p)
    printed = np.linalg.inv(K) @ shot.R @ K
    assert np.linalg.norm(imaging.apply_homography(printed, CENTRE)[0] - p) > 100.0
    np.testing.assert_allclose(imaging.apply_homography(K @ shot.R @ np.linalg.inv(K), CENTRE)[0], p, atol=1e-9)


def test_erratum_rotation_direction_of_eq_4_19():
    """§4.4.1: "R … from V_p to [0; 0; 1]" read as the rotation taking V_p to e_z, used in eq. 4.19, aims
    the beam at the principal point mirrored through the image centre, not at p."""
    p = np.array([900.0, 450.0])
    V = np.linalg.solve(K, [p[0], p[1], 1.0])
    R_text = imaging.rotation_between(V, [0.0, 0.0, 1.0])
    axis = R_text @ [0.0, 0.0, 1.0]  # principal axis of P_ref·[R_text 0; 0 1] in the reference frame
    assert np.linalg.norm(pixel(K, axis) - p) > 100.0
    np.testing.assert_allclose(pixel(K, R_text.T @ [0.0, 0.0, 1.0]), p, atol=1e-9)


def test_plan_covers_the_length_without_gaps():
    plan = PLANNER.plan(0.4, overlap=0.0)
    lo, hi = plan.extents[:, 0], plan.extents[:, 1]
    assert lo[0] == pytest.approx(-0.2, abs=1e-9) and hi[-1] >= 0.2
    np.testing.assert_allclose(lo[1:], hi[:-1], atol=1e-9)  # overlap 0: consecutive shots abut
    assert plan.valid and len(plan.shots) >= 3
    # each interval end is seen on the image border of its shot (checked by projecting the 3D point)
    for shot, (a, b) in zip(plan.shots, plan.extents):
        T = SYSTEM.fk(shot.q)
        for s in (a, b):
            X_ref = np.array([0.0, 0.0, plan.distance]) + s * plan.direction
            X = PLANNER.P_ref[:3, :3] @ X_ref + PLANNER.P_ref[:3, 3]
            u, v = imaging.project(K, T, X)[0]
            assert min(abs(u + 0.5), abs(u - (W - 0.5)), abs(v + 0.5), abs(v - (H - 0.5))) < 1e-6
    # the moves chain: the sum of Δd0 is the last shot's d0 minus the reference's
    assert plan.table_translations.sum() == pytest.approx(plan.shots[-1].q[0] - PLANNER.q_reference[0])


@pytest.mark.parametrize("overlap", [0.1, 0.3])
def test_plan_overlap(overlap):
    plan = PLANNER.plan(0.4, overlap=overlap)
    width = plan.extents[:-1, 1] - plan.extents[:-1, 0]
    shared = plan.extents[:-1, 1] - plan.extents[1:, 0]
    np.testing.assert_allclose(shared / width, overlap, atol=1e-9)


def test_plan_rejects_bad_input():
    for kwargs in (dict(length=0.0), dict(length=0.4, overlap=1.0), dict(length=0.4, overlap=-0.1),
                   dict(length=float("nan")), dict(length=0.4, distance=-1.0),
                   dict(length=0.4, direction=np.array([0.0, 0.0, 1.0]))):
        with pytest.raises(PanoramaError):
            PLANNER.plan(**kwargs)
    with pytest.raises(PanoramaError, match="principal point"):
        PLANNER.shot((1.0, float("nan")))


def test_parallax_free_and_one_plane_stitching():
    """Noiseless phantom: parallax-free ≤ 1e-6 px everywhere; one-plane exact only on its plane."""
    plan = PLANNER.plan(0.4, overlap=0.2)
    markers = phantom.marker_phantom(PLANNER)
    assert len(markers.offsets) == 3
    np.testing.assert_allclose(np.diff(markers.offsets), -0.08, atol=1e-12)  # 8 cm apart (Y0 points down)
    report = phantom.parallax_check(PLANNER, plan, markers, stitch_plane=1)
    assert np.all(report.seen > 0)
    assert np.nanmax(report.parallax_free) <= 1e-6
    assert report.parallax_free_pairs[1] > 0 and report.parallax_free_pairs[0] <= 1e-6
    assert report.one_plane[1] <= 1e-6
    assert report.one_plane[0] > 10.0 and report.one_plane[2] > 10.0
    assert report.one_plane_pairs[0] > 10.0


def test_noise_propagates_monotonically():
    plan = PLANNER.plan(0.4, overlap=0.2)
    markers = phantom.marker_phantom(PLANNER)
    rows = phantom.noise_propagation(PLANNER, plan, markers, [(0, 0), (0.1, 0), (1, 0), (0, 0.1), (0, 1)],
                                     trials=5, seed=1)
    assert rows[0]["max_px"] <= 1e-6
    assert 0 < rows[1]["rms_px"] < rows[2]["rms_px"]
    assert 0 < rows[3]["rms_px"] < rows[4]["rms_px"]
    # first-order scale: a 1° error moves points by about f·σ px (within a factor 3)
    assert rows[4]["rotation_px"] / 3 < rows[4]["rms_px"] < 3 * rows[4]["rotation_px"]


def test_validity_map_agrees_with_shots():
    us, vs = np.linspace(-800, 1600, 5), np.linspace(-300, 900, 4)
    grid = PLANNER.validity_map(us, vs)
    assert grid.shape == (4, 5)
    for i, j in [(0, 0), (1, 2), (3, 4)]:
        assert CATEGORIES[grid[i, j]] == PLANNER.shot((us[j], vs[i]), fallback=False).category
    assert CATEGORIES[PLANNER.validity_map([CENTRE[0]], [CENTRE[1]])[0, 0]] == "valid"


def test_motorized_table_through_the_one_solve():
    """Extra table joints: the 6-DOF closed form does not apply; the single-axis closed form of the one
    solve plans the shot, and with the closed form off the QP IK does."""
    system = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
    planner = PanoramaPlanner(system)
    shot = planner.shot(CENTRE + [150.0, 0.0])
    assert shot.path == "single_axis" and shot.valid
    assert shot.residual < 1e-5
    assert shot.q.shape == (system.nq,)
    from carmkin import qp_ik

    qp = qp_ik.solve(system, shot.target, q_current=planner.q_reference, world=planner.scene, closed_form=False,
                     accept=lambda report: report.valid)
    assert qp.path == "qp" and qp.success and qp.validity.valid
    assert pose_residual(system.fk(qp.q), shot.target) < 1e-5


def test_cli_shot_plan_map_parallax(tmp_path, capsys):
    assert main(["panorama", "shot", "--principal-point", "600,300"]) == 0
    out = capsys.readouterr().out
    assert "VALID" in out and "table top moves" in out
    assert main(["panorama", "shot", "--principal-point", "399.5,900", "--no-fallback"]) == 1
    assert "why:" in capsys.readouterr().out
    assert main(["panorama", "plan", "--length-mm", "400", "--overlap", "0"]) == 0
    assert "plan VALID" in capsys.readouterr().out
    png = tmp_path / "map.png"
    assert main(["panorama", "map", "--grid", "9", "--png", str(png)]) == 0
    assert png.stat().st_size > 1000
    assert main(["panorama", "parallax", "--trials", "2", "--noise", "0.1,0"]) == 0
    assert "stitching plane" in capsys.readouterr().out
    assert main(["panorama", "shot", "--principal-point", "1,2,3"]) == 2
