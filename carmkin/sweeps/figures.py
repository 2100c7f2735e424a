"""Figures of a sweep (matplotlib Figure API through :mod:`carmkin.plots`, no pyplot state): clearance and
isocentre drift along the arc; slices and a line profile of the perturbation study. mm and degrees."""

from __future__ import annotations

import numpy as np


def _figure(figsize):
    from carmkin import plots

    return plots.figure(figsize, layout="constrained")


def clearance_and_drift(sweep, path=None):
    """Two panels over φ (deg): the smallest pair distance at each frame with the certified swept minimum
    and the margin; the plain joint rotation's isocentre drift beside the compensated trajectory's."""
    fig = _figure((8, 5.5))
    top, bottom = fig.subplots(2, 1, sharex=True)
    phi = np.degrees(sweep.angles)
    top.plot(phi, sweep.frame_clearance * 1e3, ".-", label="at the frames (exact)")
    top.axhline(sweep.min_clearance * 1e3, color="tab:green", ls="--", label="certified swept minimum")
    top.axhline(sweep.margin * 1e3, color="tab:red", label="margin")
    if sweep.failure is not None:
        top.axvline(np.degrees(sweep.failure.angle), color="k", ls=":", label=f"{sweep.failure.kind.value}")
    top.set_ylabel("clearance (mm)")
    top.legend(fontsize=8)
    bottom.plot(phi, sweep.drift * 1e3, label="plain joint rotation")
    T = sweep.system.fk(np.where(np.isfinite(sweep.q), sweep.q, 0.0), check_units=False)
    residual = np.linalg.norm(sweep.target - T[:, :3, 3] - sweep.distance * T[:, :3, 2], axis=1)
    bottom.plot(phi, residual * 1e3, label="compensated" if sweep.compensated else "planned")
    bottom.set_xlabel("sweep angle φ (deg)")
    bottom.set_ylabel("isocentre drift (mm)")
    bottom.legend(fontsize=8)
    if path is not None:
        fig.savefig(path, dpi=120)
    return fig


def study(results, path=None):
    """Central slices (axial: y, coronal) of each reconstruction and the phantom, and a line profile."""
    n = len(results)
    fig = _figure((2.6 * (n + 1), 6.5))
    axes = fig.subplots(2, n + 1)
    c = results[0].volume.shape[0] // 2
    images = [("phantom", results[0].phantom)] + [(f"{r.label.split('(')[0]}\nRMSE {r.rmse:.3f}", r.volume)
                                                  for r in results]
    for k, (label, volume) in enumerate(images):
        axes[0, k].imshow(volume[:, c, :], cmap="gray", vmin=0.9, vmax=1.1)  # soft-tissue window of the phantom
        axes[0, k].set_title(label, fontsize=8)
        axes[0, k].axis("off")
    for k in range(1, n + 1):
        axes[1, k].axis("off")
    profile = axes[1, 0]
    profile.plot(results[0].profile()[1], "k", lw=2, label="phantom")
    for r in results:
        profile.plot(r.profile()[0], lw=1, label=r.label.split("(")[0].split(",")[0])
    profile.set_title("central line profile (x)", fontsize=8)
    profile.legend(fontsize=6)
    axes[1, 0].set_position(axes[1, 0].get_position())
    if path is not None:
        fig.savefig(path, dpi=120)
    return fig
