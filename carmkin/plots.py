"""The matplotlib figure toolkit of carmkin (imported on first use; matplotlib is heavy) and the singularity
maps.

Every figure of the toolkit is built with :func:`figure` and saved with :func:`save`: the object API (no
pyplot: no global backend or figure state is touched, so it works the same in scripts, the CLI and
notebooks), returned as a :class:`matplotlib.figure.Figure` and saved to ``path`` when one is given. Axes
are in the user's units: mm for prismatic joints and lengths, degrees for angles. Figures live beside the
data they draw and import this module (downward only; nothing below :mod:`carmkin.singularity` imports it):

- :func:`singularity_maps` (here): |det J| over (θ2, θ4) and a measure over a joint pair
  (:mod:`carmkin.singularity`);
- :mod:`carmkin.studies.figures`: the §4.6.1 workspace study and the reach per table model;
- :mod:`carmkin.panorama.figure`: §4.4.3 validity of principal points;
- :mod:`carmkin.sweeps.figures`: clearance and drift along a sweep.
"""

from __future__ import annotations

import math

import numpy as np

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def figure(figsize, **kwargs) -> Figure:
    """A :class:`~matplotlib.figure.Figure` of ``figsize`` (inches) with a canvas of its own, so ``savefig``
    works without pyplot."""
    fig = Figure(figsize=figsize, **kwargs)
    FigureCanvasAgg(fig)
    return fig


def save(fig: Figure, path, **kwargs) -> Figure:
    """``fig`` saved to ``path`` (any ``savefig`` target) when one is given; returns ``fig``."""
    if path is not None:
        fig.savefig(path, **kwargs)
    return fig


# --- singularity -------------------------------------------------------------------------------------------
def singularity_maps(system, q, path=None, pair: tuple[int, int] = (4, 5), n: int = 61,
                     measure: str = "inverse-condition", length: float | None = None) -> Figure:
    """Two maps: |det J| over (wigwag, angular) and ``measure`` over ``pair`` (two joints by name or index, any
    system), the other joints at ``q``; singular curves overlaid, joint limits dashed. Axes in degrees
    (revolute) or mm (prismatic). Saved as PNG to ``path`` when given."""
    from matplotlib.patches import Rectangle

    from carmkin.model.singular_cases import SingularCase
    from carmkin.singularity import _pair, measure_map, singular_curves

    names, prismatic = system.joint_names, system.prismatic

    def label(joint: int) -> str:
        return f"{names[joint]} ({'mm' if prismatic[joint] else 'deg'})"

    fig = figure((12, 5), layout="constrained")
    panels = ((_pair(system, ("wigwag", "angular")), "det"), (_pair(system, pair), measure))
    for ax, (pr, meas) in zip(fig.subplots(1, 2), panels):
        x, y, values = measure_map(system, q, pr, n, meas, length)
        scale = [1e3 if prismatic[k] else 180.0 / math.pi for k in pr]
        mesh = ax.pcolormesh(x * scale[0], y * scale[1], values, shading="auto", cmap="viridis")
        fig.colorbar(mesh, ax=ax, label="|det J| (eq. 4.7)" if meas == "det" else meas)
        for case, joint, value in singular_curves(system, pr, q):
            color = "red" if case == SingularCase.ORBITAL_PARALLEL_TO_WIGWAG else "orange"
            style = dict(color=color, lw=1.5, label=f"case ({case})")
            k = pr.index(joint)
            (ax.axvline if k == 0 else ax.axhline)(value * scale[k], **style)
        r0, r1 = (system.joint_ranges[k] for k in pr)
        ax.add_patch(Rectangle((r0.lower * scale[0], r1.lower * scale[1]), (r0.upper - r0.lower) * scale[0],
                               (r1.upper - r1.lower) * scale[1], fill=False, ls="--", color="white", lw=1.2,
                               label="joint limits"))
        ax.set_xlim(x[0] * scale[0], x[-1] * scale[0])
        ax.set_ylim(y[0] * scale[1], y[-1] * scale[1])
        ax.set_xlabel(label(pr[0]))
        ax.set_ylabel(label(pr[1]))
        handles, labels = ax.get_legend_handles_labels()
        if handles:
            unique = dict(zip(labels, handles))
            ax.legend(unique.values(), unique.keys(), loc="upper right", fontsize=8)
        title = "|det J|" if meas == "det" else meas
        ax.set_title(f"{title} over ({names[pr[0]]}, {names[pr[1]]}); sin γ1 = "
                     f"{math.sin(system.setup.gamma1):+.3f}", fontsize=10)
    fig.suptitle(f"{system.name}: singularity maps (other joints at q)")
    return save(fig, path, dpi=100)


# --- a planned configuration with the patient (carmkin views plan --png) -------------------------------------
#: Colours of the scene figure's parts.
SCENE_COLOURS = {"table": "#8c8c8c", "patient": "#e8b98f", "carm": "#1f4e9c", "beam": "#d62728", "target": "#d62728",
                 "closest": "#2ca02c", "collision": "#ff0000"}


def _obstacle_corners(obstacle) -> np.ndarray:
    """(8, 3) corners (table frame, m) of the box that bounds ``obstacle`` (box, capsule, cylinder, sphere)."""
    if obstacle.shape == "box":
        half = np.asarray(obstacle.size) / 2
    elif obstacle.shape == "sphere":
        half = np.full(3, obstacle.size[0])
    else:  # capsule or cylinder along its Z: (radius, length)
        radius, length = obstacle.size
        half = np.array([radius, radius, length / 2 + (radius if obstacle.shape == "capsule" else 0.0)])
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    local = signs * half
    return local @ obstacle.pose[:3, :3].T + obstacle.pose[:3, 3]


def _carm_parts(world) -> list[tuple[str, np.ndarray]]:
    """``(name, (8, 3) corners, table frame m)`` of each C-arm collision body of ``world`` as last placed (its
    boxes: every body of the chain's collision model is a box), so that a picture shows the parts the clearance
    is measured on, not only the chain's frame origins."""
    names = {a for a, _ in world.pairs}
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    parts = []
    for k, body in enumerate(world.geometry_model.geometryObjects):
        half = getattr(body.geometry, "halfSide", None)
        if body.name not in names or half is None:
            continue
        placement = world.geometry_data.oMg[k]
        parts.append((body.name, (signs * np.asarray(half)) @ np.asarray(placement.rotation).T
                      + np.asarray(placement.translation)))
    return parts


def _turn(o, a, b) -> float:
    """z of the cross product (a − o) × (b − o) of 2D points: > 0 for a left (counter-clockwise) turn."""
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull of 2D points (monotone chain), closed polygon vertices (k, 2)."""
    pts = sorted(map(tuple, np.round(points, 12)))
    if len(pts) < 3:
        return np.array(pts)

    def half(sequence):
        out = []
        for p in sequence:
            while len(out) >= 2 and _turn(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(reversed(pts))
    return np.array(lower[:-1] + upper[:-1])


def scene_figure(system, q, patient=None, target=None, path=None, title: str = "") -> Figure:
    """Two orthographic views of the table frame (m shown as mm): the side view (Z0 across, Y0 up the page: Y0
    points down) and the end view (X0 across): the table top, the patient's bodies (their bounding boxes' outlines),
    the C-arm's collision bodies (its boxes: cart, arm, C, source housing, detector; a body in collision filled red;
    not the DH frames' skeleton, which passes through the patient where the bodies clear it), a mount's base and
    joint points, the X-ray beam from
    the source to the detector centre and the ``target`` (3,) m. ``patient``: None, a list of Obstacle or a model with ``obstacles()``.

    The closest pair of :class:`carmkin.world.World` (C-arm part against table top, patient or floor) is drawn
    as a line between its nearest points, labelled with its distance; when the C-arm collides (a pair at or
    below 0 m), the line is red and so is the outline of every body it collides with (table top or patient
    body), so that the picture shows the collision a report of the same configuration states."""
    from matplotlib.patches import Polygon

    from carmkin.world import World
    from carmkin.world.obstacles import as_obstacles, link_of

    q = np.asarray(q, dtype=float)
    robot = np.zeros((0, 3))  # a mount's base and joint points, floor up (carmkin.model.mount_joints)
    if system.mount.joints:
        rest = q.copy()
        rest[1 + len(system.table.joints):system.nq - 5] = 0.0
        base = system.base_motion(rest) @ np.append(system.mount.base_origin, 1.0)
        moved = [F @ np.append(j.point, 1.0) for F, j in zip(system.mount_frames(q), system.mount.twists)]
        robot = np.array([base] + moved)[:, :3]
    T = np.asarray(system.fk(q))
    source = T[:3, 3]
    detector = source + system.carm.source_to_detector * T[:3, 2]
    top = np.eye(4)
    top[:3, 3] = system.table.top_center
    bodies = [("table", "table", _obstacle_corners(type("Top", (), {"shape": "box", "size": system.table.top_size,
                                                                    "pose": top})()))]
    bodies += [("patient", o.name, _obstacle_corners(o)) for o in as_obstacles(patient)]
    world = World(system, patient)
    distances = world.distances(q=q)  # also places the world's bodies at q
    parts = _carm_parts(world)
    nearest = int(np.argmin(distances))
    near = world.proximity(distances, np.inf)  # every pair's witness points, in pair order
    witness = np.vstack((near.point1[nearest], near.point2[nearest])) * 1e3
    collided = {link_of(b) for (_, b), d in zip(world.pairs, distances.tolist()) if d <= 0.0}
    collided_parts = {a for (a, _), d in zip(world.pairs, distances.tolist()) if d <= 0.0}
    part, body = (link_of(n) for n in world.pairs[nearest])
    gap = f"{part} to {body}: {distances[nearest] * 1e3:.1f} mm"
    closest_label = f"COLLISION {gap}" if distances[nearest] <= 0.0 else f"closest: {gap}"
    fig = figure((11, 4.8))
    views = (("side view: Z0 (mm) along the table", 2), ("end view: X0 (mm) across the table", 0))
    for k, (label, axis) in enumerate(views):
        ax = fig.add_subplot(1, 2, k + 1)
        for kind, name, corners in bodies:
            outline = _hull(corners[:, [axis, 1]] * 1e3)
            hit = name in collided
            ax.add_patch(Polygon(outline, closed=True, facecolor=SCENE_COLOURS[kind], alpha=0.5, label=kind, gid=name,
                                 edgecolor=SCENE_COLOURS["collision"] if hit else "k", lw=2.0 if hit else 0.5))
        for name, corners in parts:  # the C-arm's collision bodies (cart, arm, C, housings, detector)
            hit = name in collided_parts
            ax.add_patch(Polygon(_hull(corners[:, [axis, 1]] * 1e3), closed=True, gid=f"carm:{name}",
                                 facecolor=SCENE_COLOURS["collision" if hit else "carm"], alpha=0.35,
                                 edgecolor=SCENE_COLOURS["carm"], lw=0.8, label="C-arm bodies"))
        if len(robot):
            ax.plot(robot[:, axis] * 1e3, robot[:, 1] * 1e3, "-o", color="k", ms=3, lw=3, label="mount (robot axes)")
        beam = np.vstack((source, detector)) * 1e3
        ax.plot(beam[:, axis], beam[:, 1], "--", color=SCENE_COLOURS["beam"], lw=1.5, label="beam")
        ax.plot(*beam[1, [axis, 1]], "s", color=SCENE_COLOURS["beam"], ms=7, label="detector")
        ax.plot(*beam[0, [axis, 1]], "^", color=SCENE_COLOURS["beam"], ms=7, label="source")
        ax.plot(witness[:, axis], witness[:, 1], "-", marker=".", lw=2.5, label=closest_label,
                color=SCENE_COLOURS["collision" if collided else "closest"])
        if target is not None:
            t = np.asarray(target, dtype=float) * 1e3
            ax.plot(t[axis], t[1], "x", color=SCENE_COLOURS["target"], ms=12, mew=2.5, label="target")
        ax.set_xlabel(label)
        ax.set_ylabel("Y0 (mm; Y0 points down: up the page is up)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.autoscale_view()
        ax.invert_yaxis()
        ax.grid(alpha=0.3)
        if k == 0:
            handles, labels = ax.get_legend_handles_labels()
            unique = dict(zip(labels, handles))
            ax.legend(unique.values(), unique.keys(), fontsize=7, loc="best")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return save(fig, path, dpi=100)
