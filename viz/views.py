"""Drawing the patient and a reachability map in the viewer (issue 20), on top of :class:`CArmViewer`.

:func:`draw_patient` adds the patient's obstacles (boxes, capsules, spheres, cylinders) to the scene, fixed
to the table frame; :func:`draw_view_sphere` draws the map as points on a sphere of view directions around
the target, each at ``target − radius · direction`` (the source side), coloured by clearance (red: closest,
green: clear by ``scale`` or more; unreachable views grey); :func:`reach_map_page` puts both with the C-arm
posed at the clearest view into one static HTML page. Table frame, metres.
"""

from __future__ import annotations

import meshcat.geometry as mg
import numpy as np

from .shapes import hex_color
from .viewer import CArmViewer

PATIENT_RGB = (0.93, 0.76, 0.62)
UNREACHABLE_RGB = (0.55, 0.55, 0.55)


def _geometry(obstacle):
    if obstacle.shape == "box":
        return mg.Box(obstacle.size)
    if obstacle.shape == "sphere":
        return mg.Sphere(obstacle.size[0])
    radius, length = obstacle.size
    if obstacle.shape == "cylinder":
        return mg.Cylinder(length, radius)
    return mg.Cylinder(length + 2 * radius, radius)  # a capsule drawn as its bounding cylinder


def draw_patient(viewer: CArmViewer, patient, name: str = "patient") -> None:
    """The patient (a model with ``obstacles()`` or a list of Obstacle) in the viewer, table frame."""
    from carmkin.views.plan import patient_obstacles

    node = viewer.root[name]
    node.delete()
    turn = np.eye(4)
    turn[:3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]  # meshcat cylinders run along Y; ours along Z
    for o in patient_obstacles(patient):
        pose = o.pose @ turn if o.shape in ("capsule", "cylinder") else o.pose
        node[o.name].set_object(_geometry(o), mg.MeshLambertMaterial(color=hex_color(PATIENT_RGB), opacity=0.8,
                                                                      transparent=True))
        node[o.name].set_transform(pose)


def clearance_colours(clearance: np.ndarray, scale: float = 0.2) -> np.ndarray:
    """RGB (N, 3) in [0, 1]: red at 0 m, yellow at scale/2, green at ``scale`` (m) and beyond; grey for NaN."""
    c = np.clip(np.nan_to_num(clearance, nan=0.0) / scale, 0.0, 1.0)
    rgb = np.column_stack((np.clip(2 - 2 * c, 0, 1), np.clip(2 * c, 0, 1), np.zeros_like(c)))
    rgb[~np.isfinite(clearance)] = UNREACHABLE_RGB
    return rgb


def draw_view_sphere(viewer: CArmViewer, reach, radius: float = 0.5, name: str = "views") -> None:
    """The map's view directions as points at ``radius`` (m) from its target, coloured by clearance."""
    d = reach.directions.reshape(-1, 3)
    points = np.asarray(reach.target) - radius * d
    clearance = np.where(reach.reachable.ravel(), reach.clearance.ravel(), np.nan)
    colours = clearance_colours(clearance)
    viewer.root[name].set_object(mg.PointsGeometry(points.T, color=colours.T),
                                 mg.PointsMaterial(size=0.02))


def reach_map_page(system, reach, patient=None) -> str:
    """A static HTML page: the C-arm at the clearest reachable view, the patient, the sphere of views."""
    q = None
    if reach.reachable.any():
        i, j = np.unravel_index(np.nanargmax(np.where(reach.reachable, reach.clearance, -np.inf)), reach.reachable.shape)
        q = reach.q[i, j]
    viewer = CArmViewer(system, q=q)
    if patient is not None:
        draw_patient(viewer, patient)
    draw_view_sphere(viewer, reach)
    return viewer.static_html()
