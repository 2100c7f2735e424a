"""Both planes of a biplane in one meshcat scene (issue 30): the frontal plane under ``carmkin/frontal``, the lateral
under ``carmkin/lateral``, each a :class:`~carmkin.viz.viewer.CArmViewer` of its own system, both in the one
table frame (the lateral's scene rotation is the frontal's, so the table and the isocentre coincide; the lateral
plane's copy of the table and floor is hidden: the table is one). Table frame, metres.

It reads the biplane value by its attributes (``frontal``, ``lateral``, ``rest``, ``planes_q``), so the viewer
does not import :mod:`carmkin.biplane` (a room of its own layer).
"""

from __future__ import annotations

import numpy as np

from .static import offline_visualizer
from .viewer import ROOT, CArmViewer
from .views import draw_patient

#: The plane nodes under the viewer's root.
PLANE_ROOTS = {"frontal": f"{ROOT}/frontal", "lateral": f"{ROOT}/lateral"}
#: Links the lateral plane does not draw: the frontal plane draws the one table and floor.
SHARED_LINKS = ("table", "floor")


def biplane_viewers(biplane, q=None, vis=None) -> tuple[CArmViewer, CArmViewer]:
    """The frontal and lateral :class:`CArmViewer` of ``biplane`` at its configuration ``q`` (nq,) (m, rad;
    default ``biplane.rest``), in one visualizer ``vis`` (default: an offline one)."""
    q = np.array(biplane.rest) if q is None else q
    q_f, q_l = biplane.planes_q(q)
    vis = offline_visualizer(f"carmkin: {biplane.name}") if vis is None else vis
    frontal = CArmViewer(biplane.frontal, vis, q_f, root=PLANE_ROOTS["frontal"])
    lateral = CArmViewer(biplane.lateral, vis, q_l, root=PLANE_ROOTS["lateral"],
                         scene_in_world=frontal.scene_in_world)
    _, _, visual_model = biplane.lateral.pinocchio()
    for geometry in visual_model.geometryObjects:
        if lateral.model.frames[geometry.parentFrame].name in SHARED_LINKS:
            vis[f"{PLANE_ROOTS['lateral']}/robot/visuals/{geometry.name}"].set_property("visible", False)
    return frontal, lateral


def biplane_page(biplane, q=None, patient=None) -> str:
    """A static HTML page: both planes at ``q`` (default rest) and the ``patient`` (a model or obstacles)."""
    frontal, _ = biplane_viewers(biplane, q)
    if patient is not None:
        draw_patient(frontal, patient)
    return frontal.static_html()
