"""Issue 30's acceptance on every built-in preset (carmkin.list_presets()), each result checked against an
independent route: the FK against Pinocchio, plans and map cells against the FK's beam and the collision world,
the sweep's arc against its frames' beams, the DICOM angles against the joints of an angiography gimbal, the
viewer page against the URDF's bodies, the DRR's bead against P. Modest sizes here; the full ones print with
``python benchmarks/presets_acceptance.py``."""

from __future__ import annotations

import base64
import math
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import carmkin
from carmkin.cli import main
from carmkin.interop import dicom
from carmkin.studies import acceptance
from carmkin.views.maps import QP_RANK
from carmkin.world import World

PRESETS = carmkin.list_presets()
ANGIOGRAPHY = [name for name in PRESETS if acceptance.family(carmkin.load_preset(name)) == "angiography"]
#: The angiography stands at the head end (their CBCT orbit is the propeller), not a biplane's lateral plane.
HEAD_END = [name for name in ANGIOGRAPHY if acceptance.cbct_joint(carmkin.load_preset(name)) == "angular"]
#: A planned beam passes through its target and along its direction to this (m, rad): closed-form round-off.
BEAM_TOLERANCE = 1e-9
#: The same for a plan the QP solved (what a closed form left unreachable, every joint free): twice the
#: QP's stopping tolerances (m and rad), which bound its task errors, not this distance (measured: 1.03e-6 m).
QP_BEAM_TOLERANCE = 2 * max(carmkin.qp_ik.QPIKOptions().position_tolerance, carmkin.qp_ik.QPIKOptions().angle_tolerance)
#: A frame's exact clearance may fall below the sweep's certified bound by at most coal's accuracy (m).
CLEARANCE_ACCURACY = 1e-6
#: The bead drawn in a DRR vs its projection by P (px): issue 15's fiducial acceptance, at ~128 px binned images.
DRR_BEAD_PX = 0.5
#: The XA angles of an angiography gimbal equal its joints (deg) to this.
ANGLE_TOLERANCE_DEG = 1e-9


@pytest.fixture(scope="module", params=PRESETS)
def preset(request):
    system = carmkin.load_preset(request.param)
    return system, acceptance.patient_on(system)


def _beam_errors(system, q, target, direction):
    """(distance of ``target`` from the principal axis (m), angle of the axis to ``direction`` (rad)) at q."""
    T = system.fk(q)
    axis, source = T[:3, 2], T[:3, 3]
    offset = np.asarray(target) - source
    return np.linalg.norm(offset - (offset @ axis) * axis), _angle(axis, direction)


def _angle(a, b) -> float:
    """The angle (rad) between vectors a and b, accurate near 0 (atan2, not acos)."""
    return math.atan2(float(np.linalg.norm(np.cross(a, b))), float(np.dot(a, b)))


def test_fk_agrees_with_pinocchio_over_10000_configurations(preset):
    system, _ = preset
    assert acceptance.fk_agreement(system, 10_000) <= 1e-12


def test_standard_views_are_planned_and_clear_or_explained(preset):
    system, patient = preset
    result = acceptance.standard_views(system, patient)
    world = World(system, patient.obstacles())
    for name, plan in result.plans.items():
        if not plan.success:
            print(f"{system.name}: {name} unreachable: {plan.reason}")
            assert plan.reason, name
            continue
        distance, angle = _beam_errors(system, plan.q, plan.view.target, plan.view.axis)
        tolerance = QP_BEAM_TOLERANCE if plan.solver == "qp" else BEAM_TOLERANCE
        assert distance <= tolerance and angle <= tolerance, name
        assert np.all(plan.q >= system.lower - 1e-9) and np.all(plan.q <= system.upper + 1e-9), name
        assert world.clearance(plan.q[None])[0] >= carmkin.DEFAULT_MARGIN - CLEARANCE_ACCURACY, name
    assert result.planned >= 14  # today every preset plans all 16


def test_reach_map_cells_are_what_the_fk_and_the_world_say(preset):
    system, patient = preset
    reach = acceptance.reach(system, patient, np.arange(-90, 91, 15), np.arange(-45, 46, 15)).map
    world = World(system, patient.obstacles())
    cells = np.argwhere(reach.reachable)
    assert len(cells) >= 0.5 * reach.reachable.size
    for i, j in cells:
        q = reach.q[i, j]
        distance, angle = _beam_errors(system, q, reach.target, reach.directions[i, j])
        tolerance = QP_BEAM_TOLERANCE if reach.rank[i, j] == QP_RANK else BEAM_TOLERANCE
        assert distance <= tolerance and angle <= tolerance
        assert world.clearance(q[None])[0] >= carmkin.DEFAULT_MARGIN - CLEARANCE_ACCURACY


@pytest.mark.slow
def test_full_reach_map_is_91_by_46(preset):
    system, patient = preset
    reach = acceptance.reach(system, patient).map
    assert reach.reachable.shape == (91, 46) and reach.fraction >= 0.5


def test_cbct_sweep_turns_the_family_arc_about_the_isocentre_with_certified_clearance(preset):
    system, patient = preset
    sweep = acceptance.cbct_sweep(system, patient, 12)
    joint = acceptance.cbct_joint(system)
    assert sweep.success and sweep.min_clearance >= sweep.margin
    axes = sweep.poses[:, :3, 2]
    turned = sum(_angle(a, b) for a, b in zip(axes[:-1], axes[1:]))
    assert math.degrees(turned) == pytest.approx(acceptance.ARC_DEG[joint], abs=1e-6)
    world = World(system, patient.obstacles())
    assert world.clearance(sweep.q).min() >= sweep.min_clearance - CLEARANCE_ACCURACY
    for q in sweep.q:  # every frame looks at the isocentre along its own beam
        assert _beam_errors(system, q, np.zeros(3), system.fk(q)[:3, 2])[0] <= BEAM_TOLERANCE


def test_cbct_joint_is_the_rotation_about_the_table_axis():
    assert acceptance.family(carmkin.load_preset("siremobile-iso-c3d")) == "mobile"
    assert acceptance.family(carmkin.load_preset("cios-spin")) == "mobile"
    assert acceptance.family(carmkin.load_preset("angio-floor")) == "angiography"
    assert acceptance.family(carmkin.load_preset("robotic-carm")) == "robot-held"
    assert acceptance.family(carmkin.load_preset("angio-ceiling")) == "angiography"
    assert acceptance.family(carmkin.load_preset("angio-lateral")) == "angiography"  # a biplane's lateral plane


def test_dicom_angles_round_trip_through_the_joints(preset):
    system, _ = preset
    trip = acceptance.dicom_round_trip(system, 10)
    assert trip.planned == trip.count and trip.worst_deg <= 1e-9


@pytest.mark.parametrize("name", HEAD_END)
@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_angiography_primary_and_secondary_are_the_propeller_and_c_joints(name, data):
    """Wigwag and table at rest: primary = −angular (LAO +), secondary = −orbital (CRA +), both ways."""
    system = carmkin.load_preset(name)
    names = system.joint_names
    angular = data.draw(st.floats(max(system.carm.angular.lower, -math.pi + 1e-3), min(system.carm.angular.upper, math.pi - 1e-3)))
    orbital = data.draw(st.floats(system.carm.orbital.lower + 1e-3, system.carm.orbital.upper - 1e-3))
    q = np.zeros(system.nq)
    q[names.index("angular")], q[names.index("orbital")] = angular, orbital
    primary, secondary, _ = dicom.xa_angles(system.fk(q), "HFS")
    assert abs(math.remainder(primary + math.degrees(angular), 360.0)) <= ANGLE_TOLERANCE_DEG
    assert abs(secondary + math.degrees(orbital)) <= ANGLE_TOLERANCE_DEG
    T = dicom.pose_from_xa_angles(-math.degrees(angular), -math.degrees(orbital), np.zeros(3),
                                  system.carm.orbital_offset, "HFS")
    np.testing.assert_allclose(T[:3, 2:], system.fk(q)[:3, 2:], atol=1e-12)  # beam and source position


def test_viewer_page_draws_every_body(preset):
    system, _ = preset
    from carmkin.viz import CArmViewer

    umsgpack = pytest.importorskip("umsgpack")
    html = CArmViewer(system).static_html()
    blobs = re.findall(r'data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"', html)
    paths = {umsgpack.unpackb(base64.b64decode(b))["path"] for b in blobs}
    visuals = {g.name for g in system.pinocchio()[2].geometryObjects}
    links = {system.pinocchio()[0].frames[g.parentFrame].name for g in system.pinocchio()[2].geometryObjects}
    cart = set() if system.mount.joints else {"carm_cart"}  # a robot carries the C-arm base: no cart
    assert {"table", "floor", "dh_frame_6", "xray_source", "detector"} | cart <= links
    assert {f"/meshcat/carmkin/robot/visuals/{name}" for name in visuals} <= paths


def test_ceiling_mount_hangs_the_stand_from_the_ceiling():
    """The cart box of a floor stand lies below the arm, the ceiling carriage above it, at the ceiling."""
    import pinocchio as pin

    for name, above in (("angio-floor", False), ("angio-ceiling", True)):
        system = carmkin.load_preset(name)
        model, _, visual = system.pinocchio()
        data, gdata = model.createData(), pin.GeometryData(visual)
        pin.updateGeometryPlacements(model, data, visual, gdata, pin.neutral(model))
        cart = next(i for i, g in enumerate(visual.geometryObjects) if g.name.startswith("carm_cart"))
        base = system.carm_base_pose
        up = base[:3, 2]  # the vertical axis in the table frame
        height = (gdata.oMg[cart].translation - base[:3, 3]) @ up
        if above:
            top = height + visual.geometryObjects[cart].geometry.halfSide[2]
            assert top == pytest.approx(system.body.ceiling_height, abs=1e-9)
        else:
            assert height < 0


@pytest.mark.parametrize("name", [n for n in ANGIOGRAPHY if n != "angio-biplane"] + ["cios-spin"])
def test_cli_plans_a_standard_view_and_a_sweep(name, capsys):
    """(A biplane preset is refused outside ``carmkin biplane``: tests/commands/test_first_hour_again.py.)"""
    assert main(["views", "plan", "--preset", name, "--standard", "lao-40-cranial-30"]) == 0
    assert main(["sweep", "plan", "--preset", name, "--views", "10",
                 "--joint", acceptance.cbct_joint(carmkin.load_preset(name)),
                 "--arc-deg", str(acceptance.ARC_DEG[acceptance.cbct_joint(carmkin.load_preset(name))])]) == 0
    assert "feasible" in capsys.readouterr().out


def test_drr_bead_is_drawn_where_p_projects_it(preset):
    """A bead in a small air volume at the isocentre, rendered at about 128 px: its drawn centre is P's."""
    system, _ = preset
    pytest.importorskip("torch", reason="rendering needs torch (the drr extra)")
    pytest.importorskip("nanodrr", reason="rendering needs nanodrr (the drr extra)")
    from carmkin import imaging
    from carmkin.interop import drr

    q = np.zeros(system.nq)
    q[system.joint_names.index("angular")] = math.radians(20)
    T = system.fk(q)
    iso = T[:3, 3] + system.carm.orbital_offset * T[:3, 2]
    affine = np.diag([0.5, 0.5, 0.5, 1.0])
    affine[:3, 3] = -20.0 + 0.25
    volume = drr.Volume(np.full((80, 80, 80), -1000.0, dtype=np.float32), affine)
    T_table_ct = volume.in_table("HFS", iso)
    bead = iso + 0.01 * T[:3, 0] - 0.008 * T[:3, 1]
    bead_ct = volume.voxel_centre((np.linalg.inv(T_table_ct) @ np.r_[bead, 1.0])[:3] * 1000)[0]
    bead = (T_table_ct @ np.r_[bead_ct / 1000, 1.0])[:3]
    scale = 128 / min(system.carm.detector_columns, system.carm.detector_rows)
    scale = next(s for s in (1.0, 0.5, 0.25, 0.2, 0.125, 0.1, 0.0625) if s <= scale * 1.01)
    plain = drr.Renderer(system, volume, T_table_ct, scale=scale, n_samples=200, device="cpu")
    beaded = drr.Renderer(system, volume.with_fiducials(bead_ct), T_table_ct, scale=scale, n_samples=200, device="cpu")
    m = imaging.projection_from_pose(plain.K, T) @ np.r_[bead, 1.0]
    assert np.linalg.norm(drr.blob_centre(beaded.render(T), plain.render(T)) - m[:2] / m[2]) <= DRR_BEAD_PX


def test_pose_ik_closed_form_at_rest_and_qp_with_the_table_moved(preset):
    """Poses of collision-free in-range configurations: with the extra table joints at rest the closed form
    solves them (single-axis on a motorized table, the 6-DOF one otherwise), exactly; with them moved, the QP."""
    from carmkin import qp_ik
    from carmkin.transforms import pose_error

    system, _ = preset
    Q = acceptance.in_range_configurations(system, 6, seed=3)
    extra = [i for i, n in enumerate(system.joint_names) if n.startswith("table_") and n != "table_translation"]
    Q[:3, extra] = 0.0
    world = World(system)
    for k, q in enumerate(Q):
        if world.clearance(q[None])[0] < 0.02:
            continue
        result = qp_ik.solve(system, system.fk(q))
        assert result.success, k
        position, angle = pose_error(system.fk(result.q), system.fk(q))
        options = qp_ik.QPIKOptions()  # the QP's own tolerances; the closed form is exact
        exact = k < 3 and not system.mount.joints  # a robot-held C-arm has no closed form: the QP solves it
        assert position <= (1e-12 if exact else options.position_tolerance), k
        assert angle <= (1e-12 if exact else options.angle_tolerance), k
        if exact:
            assert result.path != qp_ik.Path.QP, k


def test_perpendicular_view_of_a_segment_is_planned(preset):
    """A 6 cm segment through the isocentre, oblique: the planned beam passes through its midpoint, at right
    angles to it, clear of the patient."""
    from carmkin.views import plan_perpendicular

    system, patient = preset
    a, b = np.array([0.0, 0.02, -0.02]), np.array([0.03, 0.0, 0.03])
    plan = plan_perpendicular(system, a, b, patient)
    assert plan.success
    axis = system.fk(plan.q)[:3, 2]
    tolerance = QP_BEAM_TOLERANCE if plan.solver == "qp" else BEAM_TOLERANCE
    assert abs(axis @ (b - a)) / np.linalg.norm(b - a) <= tolerance
    assert _beam_errors(system, plan.q, 0.5 * (a + b), axis)[0] <= tolerance
    assert World(system, patient.obstacles()).clearance(plan.q[None])[0] >= carmkin.DEFAULT_MARGIN - CLEARANCE_ACCURACY


def test_every_preset_reaches_its_own_zero_view(preset):
    """AP through the table origin, no patient: the beam goes up through the origin (FK, not the planner)."""
    system, _ = preset
    plan = acceptance.zero_view(system)
    distance, angle = _beam_errors(system, plan.q, np.zeros(3), np.array([0.0, -1.0, 0.0]))
    tolerance = QP_BEAM_TOLERANCE if plan.solver == "qp" else BEAM_TOLERANCE
    assert distance <= tolerance and angle <= tolerance


def test_a_preset_that_cannot_reach_its_zero_view_is_refused(tmp_path, capsys):
    """Angular and orbital ranges of 30–60° leave no roll that points the beam up: a PresetError naming the
    preset and the ranges; `carmkin verify` prints it and exits 1."""
    from carmkin.errors import PresetError

    path = tmp_path / "tilted.toml"
    path.write_text('base = "siremobile-iso-c3d"\n[carm]\nangular_min_deg = 30.0\nangular_max_deg = 60.0\n'
                    'orbital_min_deg = 30.0\norbital_max_deg = 60.0\n')
    with pytest.raises(PresetError, match=r"'tilted'.*zero view.*(angular|orbital)"):
        acceptance.zero_view(carmkin.load_preset(path))
    assert main(["verify", "--preset", str(path), "--samples", "20"]) == 1
    assert "zero view: FAIL" in capsys.readouterr().out
