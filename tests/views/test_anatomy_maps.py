"""Optimal-view maps and valve-plane views that know the C-arm (issue 29), and the anatomy's bad input.

On random synthetic coronary trees with a parametric patient: the best reachable view is reachable (the FK beam
passes through the target along the cell's direction, exact clearance ≥ margin), and no reachable cell scores
better — the score recomputed with an independent foreshortening (a loop over the points) and spot-checked
overlaps. ``CARMKIN_ANATOMY_TREES`` sets the number of trees (default 50, the full check).
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from test_anatomy_metrics import K, oracle_foreshortening, oracle_overlap

import carmkin
from carmkin.errors import AnatomyPlacementError, CarmkinError, CentrelineError, PlaneError
from carmkin.interop.dicom import pose_from_xa_angles
from carmkin.patient import ParametricPatient
from carmkin.robot import validity
from carmkin.views import (
    Centreline,
    DEFAULT_MARGIN,
    centreline_from_patient,
    optimal_view_map,
    plane_from_points,
    plane_views,
    skeleton_centreline,
)
from carmkin.views.anatomy import synthetic_tree
from carmkin.views.metrics import subdivisions

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")
PATIENT = ParametricPatient.on_table(SYSTEM)
#: The synthetic heart's centre (table frame, m): inside the parametric patient's chest, near the isocentre.
HEART = np.array([0.02, 0.05, -0.02])
TREES = int(os.environ.get("CARMKIN_ANATOMY_TREES", "50"))
PRIMARY, SECONDARY = np.arange(-90, 91, 10), np.arange(-45, 46, 10)
#: Agreement of beam directions and points on the beam (m).
GEOMETRY_TOLERANCE = 1e-9


def _check_reachable_plan(plan, target, direction):
    assert plan.success
    T = SYSTEM.fk(plan.q)
    assert np.linalg.norm(T[:3, 2] - direction) < GEOMETRY_TOLERANCE
    assert np.linalg.norm(np.cross(target - T[:3, 3], T[:3, 2])) < GEOMETRY_TOLERANCE  # beam through the target
    report = validity.check(SYSTEM, plan.q, PATIENT.obstacles(), margin=DEFAULT_MARGIN)
    assert report.reachable and report.min_distance >= DEFAULT_MARGIN


@pytest.mark.parametrize("seed", range(TREES))
def test_best_reachable_view_of_a_random_tree(seed):
    tree = synthetic_tree(HEART, seed)
    others = [c.points for c in tree[1:]]
    m = optimal_view_map(SYSTEM, tree[0], PRIMARY, SECONDARY, PATIENT, others)
    assert m.foreshortening.shape == m.overlap.shape == m.reachable.shape == (len(PRIMARY), len(SECONDARY))
    assert np.all(np.isfinite(m.foreshortening)) and np.all(np.isfinite(m.overlap))  # every cell, reachable or not
    assert np.array_equal(m.target, tree[0].midpoint)
    assert m.best_reachable is not None
    i, j = m.cell(m.best_reachable)
    assert m.reachable[i, j]
    _check_reachable_plan(m.plan, m.target, m.reach.directions[i, j])
    # the score again, with an independent foreshortening, at every reachable cell
    distance = SYSTEM.carm.orbital_offset
    points = tree[0].points.tolist()
    rescored = {}
    for a, b in zip(*np.nonzero(m.reachable)):
        pose = pose_from_xa_angles(PRIMARY[a], SECONDARY[b], m.target, distance, "HFS")
        f, w = oracle_foreshortening(points, pose.tolist(), distance)
        assert abs(f - m.foreshortening[a, b]) < 1e-9 and abs(w - m.worst_foreshortening[a, b]) < 1e-9
        rescored[(a, b)] = 0.5 * f + 0.5 * m.overlap[a, b]
    assert min(rescored.values()) >= rescored[(i, j)] - 1e-12
    # overlap spot checks against the oracle (the best cell and two others), each with its view's own subdivision
    rng = np.random.default_rng(seed)
    for a, b in [(i, j), *zip(rng.integers(len(PRIMARY), size=2), rng.integers(len(SECONDARY), size=2))]:
        pose = pose_from_xa_angles(PRIMARY[a], SECONDARY[b], m.target, distance, "HFS")
        counts = subdivisions(tree[0].points, pose[None], K)
        want = oracle_overlap(points, [o.tolist() for o in others], 1.5e-3, pose.tolist(), counts.tolist())
        assert abs(want - m.overlap[a, b]) < 1e-9
    # the plan's own metrics, at the source pose where it stands (its distance along the beam, its roll)
    T = SYSTEM.fk(m.plan.q)
    there = float(T[:3, 2] @ (m.target - T[:3, 3]))
    f, w = oracle_foreshortening(points, T.tolist(), there)
    counts = subdivisions(tree[0].points, T[None], K)
    want = oracle_overlap(points, [o.tolist() for o in others], 1.5e-3, T.tolist(), counts.tolist())
    got = m.plan_metrics
    assert abs(got["distance"] - there) < 1e-12 and abs(got["foreshortening"] - f) < 1e-9
    assert abs(got["worst_foreshortening"] - w) < 1e-9 and abs(got["overlap"] - want) < 1e-9
    o = m.cell(m.optimal)
    assert m.score[o] == m.score.min()
    assert m.loss["score"] >= 0 and m.loss["score"] == pytest.approx(m.score[i, j] - m.score[o], abs=0)
    text = "\n".join(m.summary())
    assert ("the optimal view is unreachable" in text) == (not m.reachable[o])


#: Overlap of one view alone and of the same view in a whole map (fraction): the same pixels, so equal exactly.
CELL_AGREEMENT = 0.0


@pytest.mark.parametrize("seed", range(3))
def test_a_cells_overlap_does_not_depend_on_the_maps_grid(seed):
    """Issue 41: the centreline's subdivision was taken over every view of the map, so a cell's overlap
    depended on the grid (0.0789 alone, 0.0733 in a full map). Each view now samples by its own projection."""
    tree = synthetic_tree(HEART, seed)
    others = [c.points for c in tree[1:]]
    full = optimal_view_map(SYSTEM, tree[0], PRIMARY, SECONDARY, None, others, plan=False)
    rng = np.random.default_rng(seed)
    for a, b in zip(rng.integers(len(PRIMARY), size=4), rng.integers(len(SECONDARY), size=4)):
        alone = optimal_view_map(SYSTEM, tree[0], [PRIMARY[a]], [SECONDARY[b]], None, others, plan=False)
        assert abs(alone.overlap[0, 0] - full.overlap[a, b]) <= CELL_AGREEMENT
        assert alone.foreshortening[0, 0] == full.foreshortening[a, b]
    assert np.any(full.overlap > 0)  # the test sees overlaps


def test_unreachable_optimum_is_said_with_its_loss():
    # tree 1's optimum (30° RAO, 15° CAU on the 10° grid) is out of this C-arm's reach with the patient
    tree = synthetic_tree(HEART, 1)
    m = optimal_view_map(SYSTEM, tree[0], PRIMARY, SECONDARY, PATIENT, [c.points for c in tree[1:]])
    assert not m.optimum_reachable and not m.reachable[m.cell(m.optimal)]
    assert m.best_reachable is not None and m.loss["score"] > 0
    assert any("the optimal view is unreachable" in line for line in m.summary())


def test_plane_family_is_edge_on_and_best_separates_the_cusps():
    rng = np.random.default_rng(29)
    for _ in range(3):
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        e1 = np.cross(normal, rng.normal(size=3))
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(normal, e1)
        angles = rng.uniform(0, 2 * np.pi) + np.array([0, 2.1, 4.2])
        cusps = HEART + 0.012 * (np.cos(angles)[:, None] * e1 + np.sin(angles)[:, None] * e2)
        pv = plane_views(SYSTEM, cusps, PATIENT, count=72)
        assert np.max(np.abs(pv.directions @ pv.plane.normal)) <= 1e-12
        assert abs(abs(pv.plane.normal @ normal) - 1) < 1e-12
        assert np.max(pv.angle) <= 1e-12
        if pv.best is None:
            continue
        assert pv.reachable[pv.best]
        assert pv.separation[pv.best] == np.max(pv.separation[pv.reachable])
        _check_reachable_plan(pv.plan, pv.target, pv.directions[pv.best])


def test_skeleton_centreline_is_placed_as_the_ct_patient():
    pytest.importorskip("skimage")
    labels = np.zeros((30, 30, 40), dtype=np.uint8)
    i, j = np.ogrid[:30, :30]
    labels[((i - 12) ** 2 + (j - 17) ** 2 <= 9)[:, :, None] & (np.arange(40) >= 5)[None, None] & (
        np.arange(40) < 35)[None, None]] = 1
    affine = np.diag([0.8, 0.8, 1.25, 1.0])
    affine[:3, 3] = (-10.0, 20.0, 100.0)
    origin = (0.01, 0.02, -0.03)
    line = skeleton_centreline(labels, affine, "HFS", origin)
    # independently: voxel (12, 17, k) -> RAS mm -> LPS about the volume's centre -> table (HFS: identity)
    centre = affine[:3, :3] @ ((np.array(labels.shape) - 1) / 2) + affine[:3, 3]
    ras = affine[:3, :3] @ np.array([12.0, 17.0, 0.0]) + affine[:3, 3]
    lps = np.array([-1.0, -1.0, 1.0]) * (ras - centre)
    expected_xy = lps[:2] / 1000 + origin[:2]
    assert np.max(np.abs(line.points[:, :2] - expected_xy)) < 1e-4  # on the tube's axis (to a voxel)
    assert 0.025 < line.length < 0.04  # 30 slices of 1.25 mm, minus the skeleton's ends
    assert np.all(np.diff(line.points[:, 2]) * np.sign(line.points[-1, 2] - line.points[0, 2]) > 0)  # ordered


def test_centreline_from_patient_places_lps_mm():
    pts_mm = np.array([[10.0, -80.0, 0.0], [15.0, -85.0, 30.0]])
    line = centreline_from_patient(pts_mm, PATIENT)
    T = PATIENT.pose()
    assert np.allclose(line.points, pts_mm / 1000 @ T[:3, :3].T + T[:3, 3], atol=1e-15)
    c, s = math.cos(0.1), math.sin(0.1)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    turned = centreline_from_patient(pts_mm, PATIENT, rotation=R)
    assert np.allclose(turned.points, (pts_mm / 1000 @ R.T) @ T[:3, :3].T + T[:3, 3], atol=1e-15)


@pytest.mark.parametrize("points, match", [
    ([[0.0, 0.0, 0.0]], "at least 2 points"),
    ([[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0]], "finite"),
    ([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.01, 0.0, 0.0]], "repeat"),
    ([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]], "zero"),
    ([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.01, 0.01, 0.0], [0.0, 0.0, 0.0]], "repeats an earlier point"),
    ([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]], "3 m long|were millimetres"),
    ([[0.0, 0.0, 0.0], [0.0001, 0.0, 0.0]], "long"),
    ("abc", "centreline"),
])
def test_bad_centrelines_are_refused(points, match):
    with pytest.raises(CentrelineError, match=match) as info:
        optimal_view_map(SYSTEM, points, [0], [0])
    assert "centreline" in str(info.value)


def test_bad_radii_others_and_weights_are_refused():
    line = HEART + np.array([[0.0, 0.0, -0.02], [0.0, 0.0, 0.02]])
    with pytest.raises(CentrelineError, match="radii"):
        Centreline(line, [-0.001, 0.001])
    with pytest.raises(CentrelineError, match="radius"):
        optimal_view_map(SYSTEM, line, [0], [0], others=[line + 0.01], radius=-1e-3)
    with pytest.raises(CentrelineError, match=r"others\[0\]"):
        optimal_view_map(SYSTEM, line, [0], [0], others=[[[0, 0, 0]]])
    with pytest.raises(CarmkinError, match="others"):
        optimal_view_map(SYSTEM, line, [0], [0], others=line)
    with pytest.raises(CarmkinError, match="weights"):
        optimal_view_map(SYSTEM, line, [0], [0], weights=(0, 0))


def test_anatomy_outside_the_patient_or_ct_is_refused():
    outside = np.array([[0.0, -0.5, 0.0], [0.0, -0.5, 0.05]])  # 0.5 m above the table, in the air
    with pytest.raises(AnatomyPlacementError, match="outside the patient"):
        optimal_view_map(SYSTEM, outside, [0], [0], PATIENT)
    from carmkin.views.anatomy import centreline_from_ct

    with pytest.raises(AnatomyPlacementError, match="outside the CT"):
        centreline_from_ct([[0.0, 0.0, 5.0], [0.0, 0.0, 500.0]], (10, 10, 10), np.eye(4))


def test_centreline_from_ct_is_placed_as_the_skeleton():
    from carmkin.views.anatomy import centreline_from_ct

    affine = np.diag([0.8, 0.8, 1.25, 1.0])
    affine[:3, 3] = (-10.0, 20.0, 100.0)
    points = affine[:3, :3] @ np.array([[12.0, 17.0, 5.0], [12.0, 17.0, 30.0]]).T + affine[:3, 3][:, None]
    line = centreline_from_ct(points.T, (30, 30, 40), affine, "HFS", (0.01, 0.02, -0.03))
    centre = affine[:3, :3] @ ((np.array([30, 30, 40]) - 1) / 2) + affine[:3, 3]
    want = (np.array([-1.0, -1.0, 1.0]) * (points.T - centre)) / 1000 + (0.01, 0.02, -0.03)
    assert np.allclose(line.points, want, atol=1e-15)


@pytest.mark.parametrize("points, match", [
    ([[0, 0, 0], [0.01, 0, 0]], "at least 3"),
    ([[0, 0, 0], [0.01, 0, 0], [0.02, 0, 0]], "collinear"),
    ([[0, 0, 0]] * 3, "collinear"),
    ([[0, 0, 0], [0.01, 0, 0], [np.nan, 0, 0]], "finite"),
])
def test_bad_planes_are_refused(points, match):
    with pytest.raises(PlaneError, match=match):
        plane_from_points(points)
