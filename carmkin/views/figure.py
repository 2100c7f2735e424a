"""The reachability map as a matplotlib figure (Figure API, no pyplot state): clearance (mm) over the
(primary, secondary) angles, unreachable cells grey, the standard views marked."""

from __future__ import annotations

import numpy as np


def reach_map_figure(reach, title: str = ""):
    """A :class:`matplotlib.figure.Figure` of a :class:`~carmkin.views.ReachMap`."""
    from matplotlib.figure import Figure

    from .standard import STANDARD_VIEWS

    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.add_subplot()
    clearance = np.where(reach.reachable, reach.clearance * 1000.0, np.nan)
    p, s = reach.primary_deg, reach.secondary_deg
    ax.set_facecolor("0.8")
    mesh = ax.pcolormesh(p, s, clearance.T, shading="nearest", cmap="RdYlGn", vmin=0.0)
    fig.colorbar(mesh, ax=ax, label="clearance (mm); grey: unreachable")
    for v in STANDARD_VIEWS.values():
        if p.min() <= v.primary_deg <= p.max() and s.min() <= v.secondary_deg <= s.max():
            ax.plot(v.primary_deg, v.secondary_deg, "k+")
            ax.annotate(v.name, (v.primary_deg, v.secondary_deg), fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax.set_xlabel("primary angle (deg): RAO − / LAO +")
    ax.set_ylabel("secondary angle (deg): CAU − / CRA +")
    ax.set_title(title or f"reachable views: {100 * reach.fraction:.0f} %")
    return fig
