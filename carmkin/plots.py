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
