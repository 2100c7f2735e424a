"""The skin dose map in the browser (issue 38): the skin cells of a :class:`carmkin.dose.DoseMap` as a coloured mesh.

Each skin cell is drawn as a square of side ``cell`` (m; default the cells' median nearest-neighbour spacing)
centred on it, in the plane normal to its outward normal: two triangles, four vertices, all four of the cell's
colour (meshcat vertex colours). A skin that is a surface (a CT's, whose cells are its vertices: the map's
``faces``) is drawn as that surface instead, each vertex its cell's colour (the colours blend across a triangle). The colour scale is :func:`dose_colours`: "hot", black at 0 Gy through red and
yellow to white at the scale's maximum (default the map's peak skin dose); cells no event's field enters are drawn
in :data:`NO_DOSE_RGB`. The PSD is marked by a cyan sphere. The page states the scale and its maximum (mGy) in a
legend above the scene. Table frame, metres; node ``dose`` under the viewer's root (``dose/skin``, ``dose/psd``).
"""

from __future__ import annotations

import html as _html

import meshcat.geometry as mg
import numpy as np

from carmkin.errors import VisualizationError

from .shapes import hex_color
from .static import offline_visualizer
from .viewer import CArmViewer

#: Colour (RGB in [0, 1]) of the skin cells that no entrance field reaches (a pale skin tone).
NO_DOSE_RGB = (0.93, 0.84, 0.76)
#: Colour of the sphere that marks the peak skin dose, and its radius (m).
PSD_RGB = (0.0, 0.85, 0.95)
PSD_MARK_M = 0.012
#: The colour scale's stops (fraction of the maximum, RGB): black, red, yellow, white; linear between them.
HOT_STOPS = ((0.0, (0.0, 0.0, 0.0)), (1 / 3, (1.0, 0.0, 0.0)), (2 / 3, (1.0, 1.0, 0.0)), (1.0, (1.0, 1.0, 1.0)))
#: Node of the dose overlay under the viewer's root.
NODE = "dose"


def hot(t) -> np.ndarray:
    """RGB (N, 3) in [0, 1] of fractions ``t`` (N,) in [0, 1] on :data:`HOT_STOPS` (each channel non-decreasing)."""
    t = np.asarray(t, dtype=float)
    xs = [s for s, _ in HOT_STOPS]
    return np.column_stack([np.interp(t, xs, [rgb[k] for _, rgb in HOT_STOPS]) for k in range(3)])


def dose_colours(dose_gy, max_gy: float) -> np.ndarray:
    """RGB (N, 3): ``dose_gy`` (N,) on the hot scale from 0 to ``max_gy`` (Gy, ≥ every dose: nothing is clipped);
    a zero dose in :data:`NO_DOSE_RGB`."""
    dose = np.asarray(dose_gy, dtype=float)
    if not (np.isfinite(max_gy) and max_gy > 0):
        raise VisualizationError(f"max_gy must be a positive finite dose (Gy), got {max_gy!r}")
    if dose.size and (not np.all(np.isfinite(dose)) or dose.min() < 0 or dose.max() > max_gy):
        raise VisualizationError(f"dose_gy must lie in [0, max_gy = {max_gy * 1e3:.4g} mGy], got "
                                 f"[{dose.min() * 1e3:.4g}, {dose.max() * 1e3:.4g}] mGy")
    rgb = hot(dose / max_gy)
    rgb[dose == 0.0] = NO_DOSE_RGB
    return rgb


def cell_spacing(cells: np.ndarray) -> float:
    """The median distance (m) from each cell to its nearest neighbour."""
    from scipy.spatial import cKDTree

    if len(cells) < 2:
        raise VisualizationError(f"a dose map needs at least 2 skin cells to size them, got {len(cells)}")
    distance, _ = cKDTree(cells).query(cells, k=2)
    return float(np.median(distance[:, 1]))


def cell_mesh(cells: np.ndarray, normals: np.ndarray, side: float) -> tuple[np.ndarray, np.ndarray]:
    """(4N, 3) vertices and (2N, 3) faces: a square of ``side`` (m) per cell, normal to its normal, counter-clockwise
    seen from outside."""
    n = np.asarray(normals, dtype=float)
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(n, helper)
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(n, e1)
    h = side / 2
    corners = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    vertices = np.stack([cells + h * (a * e1 + b * e2) for a, b in corners], axis=1).reshape(-1, 3)
    base = 4 * np.arange(len(cells))[:, None]
    faces = np.vstack([base + [0, 1, 2], base + [0, 2, 3]]).reshape(2, -1, 3).transpose(1, 0, 2).reshape(-1, 3)
    return vertices, faces


def draw_dose(viewer: CArmViewer, m, max_gy: float | None = None, cell: float | None = None) -> float:
    """The map ``m`` (:class:`carmkin.dose.DoseMap`) as a coloured mesh under ``viewer``'s root, and the PSD marked.
    ``max_gy``: the top of the colour scale (Gy, default the map's PSD); ``cell``: the side of a cell's square
    (m, default :func:`cell_spacing`; given, a surface's cells are drawn as squares too). Returns the scale's
    maximum (Gy)."""
    top = float(m.psd_gy) if max_gy is None else float(max_gy)
    if top <= 0.0 and max_gy is None:
        top = 1.0  # no dose anywhere: every cell is NO_DOSE_RGB whatever the scale
    colours = dose_colours(m.dose_gy, top)
    if getattr(m, "faces", None) is not None and cell is None:  # a surface: its own triangles
        vertices, faces = m.cells, m.faces
    else:
        side = cell_spacing(m.cells) if cell is None else float(cell)
        if not (np.isfinite(side) and side > 0):
            raise VisualizationError(f"cell must be a positive side (m), got {cell!r}")
        vertices, faces = cell_mesh(m.cells, m.normals, side)
        colours = np.repeat(colours, 4, axis=0)
    node = viewer.root[NODE]
    node.delete()
    geometry = mg.TriangularMeshGeometry(vertices.astype(np.float32), np.asarray(faces).astype(np.uint32),
                                         color=colours.astype(np.float32))
    node["skin"].set_object(geometry, mg.MeshBasicMaterial(vertexColors=True, side=2))
    mark = np.eye(4)
    mark[:3, 3] = m.psd_point
    node["psd"].set_object(mg.Sphere(PSD_MARK_M), mg.MeshLambertMaterial(color=hex_color(PSD_RGB)))
    node["psd"].set_transform(mark)
    return top


def legend_html(max_gy: float, title: str = "") -> str:
    """The page's legend: the hot scale as a gradient from 0 to ``max_gy`` (mGy), the no-dose colour, the PSD mark."""
    stops = ", ".join(f"rgb({', '.join(str(round(255 * c)) for c in rgb)}) {s * 100:.1f}%" for s, rgb in HOT_STOPS)

    def css(rgb):
        return f"rgb({', '.join(str(round(255 * c)) for c in rgb)})"

    return (f'<div id="carmkin-dose-legend" style="position: absolute; top: 8px; left: 8px; z-index: 10; '
            f'background: rgba(255, 255, 255, 0.85); padding: 6px 10px; font: 13px sans-serif;">'
            f"<div>{_html.escape(title)}</div>"
            f'<div>entrance skin dose (mGy), scale "hot": 0 '
            f'<span style="display: inline-block; width: 160px; height: 12px; vertical-align: middle; '
            f'background: linear-gradient(to right, {stops});"></span> '
            f'<span id="carmkin-dose-max">{max_gy * 1e3:.4g}</span> mGy (max)</div>'
            f'<div><span style="color: {css(NO_DOSE_RGB)};">&#9632;</span> no entrance field &nbsp; '
            f'<span style="color: {css(PSD_RGB)};">&#9679;</span> peak skin dose</div></div>')


def dose_page(system, m, q=None, max_gy: float | None = None, title: str = "") -> str:
    """A static HTML page: the C-arm at ``q`` (default the middle of its ranges), the table and the map ``m`` as a
    coloured skin (:func:`draw_dose`), with the legend (:func:`legend_html`)."""
    viewer = CArmViewer(system, offline_visualizer(f"carmkin dose: {system.name}"), q=q)
    top = draw_dose(viewer, m, max_gy)
    page = viewer.static_html()
    pane = '<div id="meshcat-pane"></div>'
    if page.count(pane) != 1:
        raise VisualizationError("the viewer page has no single meshcat pane to put the dose legend beside")
    title = title or f"PSD {m.psd_gy * 1e3:.4g} mGy, {len(m.events)} events"
    return page.replace(pane, legend_html(top, title) + pane, 1)
