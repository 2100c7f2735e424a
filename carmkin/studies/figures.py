"""Figures of the workspace studies (matplotlib Figure API through :mod:`carmkin.plots`; mm and degrees):
the §4.6.1 excess against Table 4.5 and the reach per table model."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from carmkin import plots


def workspace_excess(result, path=None, joints: Sequence[str] = ("wigwag", "horizontal")) -> Figure:
    """The excess (mean ± std, min–max band) and K against table translation for a
    :class:`~carmkin.studies.workspace.StudyResult`, with the dissertation's means and K as red crosses."""
    from carmkin.seed import DISSERTATION_TABLE_4_5
    from carmkin.studies.workspace import UNITS, translation_key

    fig = plots.figure((5.5 * len(joints), 6.5), layout="constrained")
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
    return plots.save(fig, path, dpi=120)


def table_reach(results, labels: dict[str, str], path=None) -> Figure:
    """Bar chart of the reachable fraction per table model (:class:`~carmkin.studies.table_workspace.ModelReach`
    results; ``labels``: model -> display name)."""
    fig = plots.figure((7, 3.6), layout="constrained")
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
    return plots.save(fig, path)
