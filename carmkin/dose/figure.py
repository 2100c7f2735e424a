"""The dose map as a figure (matplotlib through :mod:`carmkin.plots`): the skin seen from above (cells facing
up, −Y0) and from below (facing down), X0 across and Z0 along the table in mm, coloured by dose (mGy), the PSD
marked."""

from __future__ import annotations

import numpy as np


def dose_figure(m, path=None, title: str = ""):
    """A figure of the :class:`carmkin.dose.DoseMap` ``m``, saved to ``path`` when given."""
    from carmkin.plots import figure, save

    up = m.normals[:, 1] <= 0.0  # Y0 points down: these cells face up
    panels = [(mask, label) for mask, label in ((up, "seen from above (cells facing up)"),
                                                (~up, "seen from below (cells facing down)")) if mask.any()]
    fig = figure((5.5 * len(panels) + 1.5, 6.5))
    peak = max(m.psd_gy * 1e3, 1e-12)
    for i, (mask, label) in enumerate(panels):
        ax = fig.add_subplot(1, len(panels), i + 1)
        cells = m.cells[mask] * 1e3
        order = np.argsort(m.dose_gy[mask])
        points = ax.scatter(cells[order, 0], cells[order, 2], c=m.dose_gy[mask][order] * 1e3, s=4, cmap="inferno",
                            vmin=0.0, vmax=peak)
        ax.plot(m.psd_point[0] * 1e3, m.psd_point[2] * 1e3, "c+", markersize=14, label="PSD")
        ax.set_xlabel("X0 across the table (mm)")
        ax.set_ylabel("Z0 along the table, head + (mm)")
        ax.set_title(label, fontsize=10)
        ax.set_aspect("equal")
        ax.legend(loc="lower right", fontsize=8)
    fig.colorbar(points, ax=fig.axes, label="entrance skin dose (mGy)")
    fig.suptitle(title or f"PSD {m.psd_gy * 1e3:.3g} mGy, {len(m.events)} events")
    return save(fig, path, dpi=120)
