"""The viewer page of a biplane: both planes in one scene, in the one table frame, the table drawn once."""

import numpy as np
import umsgpack

from carmkin.biplane import load_biplane, plan_biplane
from carmkin.patient import ParametricPatient
from carmkin.viz.biplane import PLANE_ROOTS, biplane_page, biplane_viewers

BIPLANE = load_biplane("angio-biplane")


def _node(vis, path):
    node = vis.window.tree
    for part in ["meshcat", *path.split("/")]:
        node = node[part]
    return node


def _transform(vis, path):
    return np.array(umsgpack.unpackb(_node(vis, path).transform)["matrix"]).reshape(4, 4).T


def test_both_planes_stand_in_one_table_frame_at_their_configurations():
    plan = plan_biplane(BIPLANE, "rao-35-caudal-35", 90.0)
    frontal, lateral = biplane_viewers(BIPLANE, plan.q)
    vis = frontal.vis
    assert lateral.vis is vis
    np.testing.assert_array_equal(_transform(vis, PLANE_ROOTS["frontal"]), _transform(vis, PLANE_ROOTS["lateral"]))
    poses = BIPLANE.fk(plan.q)
    for plane, pose in zip(("frontal", "lateral"), poses):  # each cone sits at that plane's source
        np.testing.assert_allclose(_transform(vis, f"{PLANE_ROOTS[plane]}/cone"), pose, atol=1e-12)


def test_the_lateral_plane_does_not_draw_a_second_table():
    frontal, lateral = biplane_viewers(BIPLANE)
    visuals = _node(frontal.vis, f"{PLANE_ROOTS['lateral']}/robot/visuals")
    hidden = {name for name in visuals if any(umsgpack.unpackb(p).get("property") == "visible"
                                              and umsgpack.unpackb(p).get("value") is False
                                              for p in visuals[name].properties)}
    assert hidden == {"table_0", "floor_0"}


def test_the_page_holds_both_planes_and_the_patient():
    html = biplane_page(BIPLANE, patient=ParametricPatient.on_table(BIPLANE.frontal))
    assert html.startswith("<!DOCTYPE html>") and len(html) > 500_000
