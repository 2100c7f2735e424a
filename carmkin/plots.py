"""All of carmkin's matplotlib figures, in one presentation module (imported on first use; matplotlib is heavy).

Each function takes results computed elsewhere, returns a :class:`matplotlib.figure.Figure` built with the
object API (no pyplot: no global backend or figure state is touched, so it works the same in scripts, the
CLI and notebooks) and saves it to ``path`` when one is given. Axes are in the user's units: mm for
prismatic joints and lengths, degrees for angles.

- :func:`singularity_maps`: |det J| over (θ2, θ4) and a measure over a joint pair (:mod:`carmkin.singularity`);
- :func:`workspace_excess`: the §4.6.1 study against Table 4.5 (:mod:`carmkin.studies.workspace`);
- :func:`table_reach`: reachable fraction per table model (:mod:`carmkin.studies.table_workspace`);
- :func:`panorama_validity_map`: §4.4.3 validity of principal points (:mod:`carmkin.imaging.panorama`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def _figure(figsize, **kwargs) -> Figure:
    fig = Figure(figsize=figsize, **kwargs)
    FigureCanvasAgg(fig)  # a canvas of its own, so savefig works without pyplot
    return fig


def _save(fig: Figure, path, **kwargs) -> Figure:
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

    fig = _figure((12, 5), layout="constrained")
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
    return _save(fig, path, dpi=100)


# --- studies -------------------------------------------------------------------------------------------------
def workspace_excess(result, path=None, joints: Sequence[str] = ("wigwag", "horizontal")) -> Figure:
    """The excess (mean ± std, min–max band) and K against table translation for a
    :class:`~carmkin.studies.workspace.StudyResult`, with the dissertation's means and K as red crosses."""
    from carmkin.studies.workspace import DISSERTATION_TABLE_4_5, UNITS, translation_key

    fig = _figure((5.5 * len(joints), 6.5), layout="constrained")
    axes = fig.subplots(2, len(joints), sharex=True, squeeze=False)
    d0 = np.array([r.translation * 1e3 for r in result.results])
    for col, joint in enumerate(joints):
        stats = [r.joints[joint] for r in result.results]
        mean, std = np.array([s.mean for s in stats]), np.array([s.std for s in stats])
        ax = axes[0, col]
        ax.fill_between(d0, [s.min for s in stats], [s.max for s in stats], alpha=0.25, label="min–max (ours)")
        ax.errorbar(d0, mean, yerr=std, fmt="o-", capsize=3, label="mean ± std (ours)")
        paper = DISSERTATION_TABLE_4_5.get(joint)
        if paper is not None:
            keys = [translation_key(r.translation) for r in result.results]
            ref = [(x, paper[k]["mean"], paper[k]["K"]) for x, k in zip(d0, keys) if k in paper]
            if ref:
                x, mean_ref, k_ref = zip(*ref)
                ax.plot(x, mean_ref, "rx", zorder=5, label="mean (dissertation)")
                axes[1, col].plot(x, k_ref, "rx", zorder=5, label="K (dissertation)")
        ax.set_title(f"{joint}: excess ({UNITS[joint][0]})")
        ax.legend(fontsize=8)
        axes[1, col].bar(d0, [s.K for s in stats], width=30.0, label="K (ours)")
        axes[1, col].legend(fontsize=8)
        axes[1, col].set_ylabel("K (poses out of range)")
        axes[1, col].set_xlabel("table translation d0 (mm)")
    fig.suptitle(f"5-DOF IK of 6-DOF poses, {result.system} (§4.6.1, Table 4.5)")
    return _save(fig, path, dpi=120)


def table_reach(results, labels: dict[str, str], path=None) -> Figure:
    """Bar chart of the reachable fraction per table model (:class:`~carmkin.studies.table_workspace.ModelReach`
    results; ``labels``: model -> display name)."""
    fig = _figure((7, 3.6), layout="constrained")
    ax = fig.subplots()
    fractions = [100 * r.fraction for r in results]
    ax.bar([labels[r.model].replace(" (", "\n(").replace(", ", ",\n", 1) for r in results], fractions,
           color="tab:blue")
    for x, f in enumerate(fractions):
        ax.text(x, f + 1, f"{f:.1f}%", ha="center")
    ax.set_ylim(0, 110)
    ax.set_ylabel("desired poses reachable (%)")
    ax.tick_params(axis="x", labelsize=7)
    ax.set_title(f"Reach by table DOFs ({len(results[0].reached)} poses)")
    return _save(fig, path)


# --- imaging ---------------------------------------------------------------------------------------------------
#: Colours of the validity-map categories, in the order of :data:`carmkin.imaging.panorama.CATEGORIES`.
VALIDITY_COLORS = ("#4caf50", "#ff9800", "#e53935", "#9e9e9e", "#212121")


def panorama_validity_map(planner, us, vs, categories: np.ndarray, labels: Sequence[str], path=None,
                          shots=()) -> Figure:
    """A validity map (category indices from :meth:`~carmkin.imaging.panorama.PanoramaPlanner.validity_map`
    on the pixel grid ``us`` × ``vs``; ``labels``: the category names, :data:`carmkin.imaging.panorama.CATEGORIES`),
    the reference image border and the outlines of ``shots``."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    from carmkin.imaging.camera import image_border

    colors = list(VALIDITY_COLORS)
    fig = _figure((8, 5), layout="constrained")
    ax = fig.subplots()
    du, dv = (us[1] - us[0]) if len(us) > 1 else 1.0, (vs[1] - vs[0]) if len(vs) > 1 else 1.0
    ax.imshow(categories, cmap=ListedColormap(colors), vmin=-0.5, vmax=len(labels) - 0.5, origin="upper",
              extent=(us[0] - du / 2, us[-1] + du / 2, vs[-1] + dv / 2, vs[0] - dv / 2), interpolation="nearest")
    border = image_border(*planner.size)
    ax.plot(border[:, 0], border[:, 1], "b-", lw=1.5, label="reference image")
    for k, shot in enumerate(shots):
        ax.plot(shot.outline[:, 0], shot.outline[:, 1], "w--", lw=1, label="planned shot: border" if k == 0 else None)
        ax.plot(*shot.principal_point, "w+", label="planned shot: principal point" if k == 0 else None)
    ax.set_xlabel("u (px, panorama frame)")
    ax.set_ylabel("v (px)")
    ax.set_title("validity of principal points (§4.4.3)")
    lines, _ = ax.get_legend_handles_labels()
    fig.legend(handles=[Patch(color=c, label=n) for c, n in zip(colors, labels)] + lines, loc="outside right upper",
               fontsize=7, facecolor="0.75", title="colour: validity (§4.4.3)", title_fontsize=7)
    ax.set_aspect("equal")
    return _save(fig, path, dpi=110)


# --- a planned configuration with the patient (carmkin views plan --png) -------------------------------------
#: Colours of the scene figure's parts.
SCENE_COLOURS = {"table": "#8c8c8c", "patient": "#e8b98f", "carm": "#1f4e9c", "beam": "#d62728", "target": "#d62728"}


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
    the C-arm's DH frame origins joined in chain order, the X-ray beam from the source to the detector centre and
    the ``target`` (3,) m. ``patient``: None, a list of Obstacle or a model with ``obstacles()``."""
    from matplotlib.patches import Polygon

    from carmkin.patient.obstacles import as_obstacles

    q = np.asarray(q, dtype=float)
    frames = np.asarray(system.dh_frames(q))[:, :3, 3]
    T = np.asarray(system.fk(q))
    source = T[:3, 3]
    detector = source + system.carm.source_to_detector * T[:3, 2]
    top = np.eye(4)
    top[:3, 3] = system.table.top_center
    bodies = [("table", _obstacle_corners(type("Top", (), {"shape": "box", "size": system.table.top_size,
                                                          "pose": top})()))]
    bodies += [("patient", _obstacle_corners(o)) for o in as_obstacles(patient)]
    fig = _figure((11, 4.8))
    views = (("side view: Z0 (mm) along the table", 2), ("end view: X0 (mm) across the table", 0))
    for k, (label, axis) in enumerate(views):
        ax = fig.add_subplot(1, 2, k + 1)
        for kind, corners in bodies:
            outline = _hull(corners[:, [axis, 1]] * 1e3)
            ax.add_patch(Polygon(outline, closed=True, facecolor=SCENE_COLOURS[kind], edgecolor="k", alpha=0.5,
                                 lw=0.5, label=kind))
        chain = np.vstack((np.zeros(3), frames, source)) * 1e3
        ax.plot(chain[:, axis], chain[:, 1], "-o", color=SCENE_COLOURS["carm"], ms=3, lw=2, label="C-arm (DH frames)")
        beam = np.vstack((source, detector)) * 1e3
        ax.plot(beam[:, axis], beam[:, 1], "--", color=SCENE_COLOURS["beam"], lw=1.5, label="beam")
        ax.plot(*beam[1, [axis, 1]], "s", color=SCENE_COLOURS["beam"], ms=7, label="detector")
        ax.plot(*beam[0, [axis, 1]], "^", color=SCENE_COLOURS["beam"], ms=7, label="source")
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
    return _save(fig, path, dpi=100)
