"""The optimal-view map as a matplotlib figure (Figure API, no pyplot state): foreshortening and overlap
contours (%) over the (primary, secondary) angles, unreachable cells hatched, the optimum (star) and the best
reachable view (circle) marked."""

from __future__ import annotations

import numpy as np


def optimal_map_figure(omap, title: str = ""):
    """A :class:`matplotlib.figure.Figure` of a :class:`~carmkin.views.OptimalViewMap`."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 4.8), layout="constrained")
    p, s = omap.primary_deg, omap.secondary_deg
    panels = (("foreshortening (%)", 100 * omap.foreshortening, "viridis"), ("overlap (%)", 100 * omap.overlap, "magma"))
    for k, (label, values, cmap) in enumerate(panels):
        ax = fig.add_subplot(1, 2, k + 1)
        if len(p) > 1 and len(s) > 1:
            filled = ax.contourf(p, s, values.T, levels=12, cmap=cmap)
            ax.contour(p, s, values.T, levels=filled.levels, colors="k", linewidths=0.3)
            fig.colorbar(filled, ax=ax, label=label)
            if not omap.reachable.all():
                ax.contourf(p, s, (~omap.reachable).T.astype(float), levels=[0.5, 1.5], colors="none", hatches=["//"])
        ax.plot(*omap.optimal, "w*", markersize=14, markeredgecolor="k", label="optimal")
        if omap.best_reachable is not None:
            ax.plot(*omap.best_reachable, "o", color="cyan", markersize=9, markeredgecolor="k", label="best reachable")
        ax.set_xlabel("primary angle (deg): RAO − / LAO +")
        ax.set_ylabel("secondary angle (deg): CAU − / CRA +")
        ax.set_title(label + "; hatched: unreachable")
        ax.legend(loc="lower right", fontsize=8)
    fig.suptitle(title or "optimal-view map")
    return fig
