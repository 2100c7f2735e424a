"""meshcat objects drawn next to the robot: the X-ray cone and coordinate triads.

Each function returns meshcat objects expressed in the frame they are attached to (metres).
"""

from __future__ import annotations

import meshcat.geometry as mg
import numpy as np

from carmkin.model.params import CArmGeometry

#: Colour of the X-ray cone (translucent yellow) and of the ghost copies (translucent cyan).
CONE_RGB = (1.0, 0.85, 0.2)
GHOST_RGB = (0.3, 0.85, 0.95)


def hex_color(rgb) -> int:
    """``0xRRGGBB`` from three floats in [0, 1]."""
    r, g, b = (int(round(255 * float(np.clip(c, 0.0, 1.0)))) for c in rgb[:3])
    return (r << 16) | (g << 8) | b


def cone_vertices(carm: CArmGeometry) -> np.ndarray:
    """(5, 3) apex (the focal spot) then the detector corners, in the ``xray_source`` frame (m).

    The detector rectangle is ``detector_width`` along X and ``detector_height`` along Y, centred on the
    principal axis Z at ``source_to_detector``.
    """
    w, h, f = carm.detector_width / 2, carm.detector_height / 2, carm.source_to_detector
    return np.array([[0, 0, 0], [-w, -h, f], [w, -h, f], [w, h, f], [-w, h, f]], dtype=float)


def xray_cone(carm: CArmGeometry, rgb=CONE_RGB, opacity: float = 0.3) -> tuple[mg.Mesh, mg.LineSegments]:
    """The X-ray pyramid (translucent faces, opaque edges) in the ``xray_source`` frame."""
    vertices = cone_vertices(carm)
    faces = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1], [1, 3, 2], [1, 4, 3]])
    surface = mg.Mesh(mg.TriangularMeshGeometry(vertices, faces),
                      mg.MeshLambertMaterial(color=hex_color(rgb), opacity=opacity, transparent=True,
                                             depthWrite=False))
    edges = [(0, 1), (0, 2), (0, 3), (0, 4), (1, 2), (2, 3), (3, 4), (4, 1)]
    points = np.array([vertices[i] for edge in edges for i in edge], dtype=np.float32).T
    outline = mg.LineSegments(mg.PointsGeometry(points), mg.LineBasicMaterial(color=hex_color(rgb)))
    return surface, outline


def triad(length: float = 0.2, thickness: float | None = None) -> list[tuple[mg.Geometry, mg.Material, np.ndarray]]:
    """A frame drawn as three boxes X red, Y green, Z blue (WebGL lines are 1 px wide whatever is asked).

    Returns ``(geometry, material, placement)`` per axis, placements in the frame itself.
    """
    t = thickness or length / 15
    out = []
    for axis, rgb in enumerate(((0.9, 0.1, 0.1), (0.1, 0.75, 0.1), (0.1, 0.2, 0.95))):
        size = [t, t, t]
        size[axis] = length
        placement = np.eye(4)
        placement[axis, 3] = length / 2
        out.append((mg.Box(size), mg.MeshLambertMaterial(color=hex_color(rgb)), placement))
    return out
