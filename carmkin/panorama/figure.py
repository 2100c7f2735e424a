"""The validity-map figure of the panorama planner (§4.4.3; matplotlib Figure API through
:mod:`carmkin.plots`): the category of every principal point, the reference image and the planned shots."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from carmkin import plots
from carmkin.panorama.planner import CATEGORIES


#: Colours of the validity-map categories, in the order of :data:`~carmkin.panorama.planner.CATEGORIES`.
VALIDITY_COLORS = ("#4caf50", "#ff9800", "#e53935", "#9e9e9e", "#212121")


def plot_validity_map(planner, us, vs, categories: np.ndarray, path=None, shots=()) -> Figure:
    """A validity map (category indices into :data:`~carmkin.panorama.planner.CATEGORIES` from
    :meth:`~carmkin.panorama.PanoramaPlanner.validity_map` on the pixel grid ``us`` × ``vs``), the reference
    image border and the outlines of ``shots``; saved to ``path`` when given."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    from carmkin.imaging.camera import image_border

    colors, labels = list(VALIDITY_COLORS), CATEGORIES
    fig = plots.figure((8, 5), layout="constrained")
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
    return plots.save(fig, path, dpi=110)
