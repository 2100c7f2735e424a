"""The workspace of views, side by side: the C-arm alone, with the table translation, with a motorized table.

The seed compares the 5-DOF C-arm of §4.6.1 with the 6-DOF system that adds the table translation (§4.6);
:func:`compare_maps` asks the same of views with the patient in the world: one :func:`reach_map` each for

* the C-arm alone (:func:`~carmkin.views.carm_alone`: the table translation held at 0),
* the C-arm with the table translation (``system``),
* the C-arm with a motorized table (``motorized``), its other table joints at the sampled values of
  :func:`table_samples` — the closed form per sample (the map holds a table's joints: sampling them is how
  a map sees them move).

:func:`compare_figure` draws them side by side. Angles in degrees, lengths in m.
"""

from __future__ import annotations

import numpy as np

from .maps import carm_alone, reach_map


def table_samples(system, reference=None) -> list[np.ndarray]:
    """Configurations (nq,) whose table joints a map of a motorized ``system`` takes: the reference (default
    mid-range) and each extra table joint alone at its lower and at its upper limit."""
    q_ref = 0.5 * (system.lower + system.upper) if reference is None else np.asarray(reference, dtype=float)
    out = [q_ref]
    for k, name in enumerate(system.joint_names):
        if name in {j.name for j in system.table.joints}:
            for value in (system.lower[k], system.upper[k]):
                q = q_ref.copy()
                q[k] = value
                out.append(q)
    return out


def compare_maps(system, target, primary_deg, secondary_deg, patient=None, motorized=None, **options) -> dict:
    """``{label: ReachMap}`` of ``target`` (3,) m over ``primary_deg`` × ``secondary_deg`` (deg) for the C-arm
    alone, ``system`` and, when given, the ``motorized`` system with :func:`table_samples`; ``options`` go to
    :func:`reach_map` (margin, position, workers)."""
    maps = {
        "C-arm alone (5 DOF)": reach_map(carm_alone(system), target, primary_deg, secondary_deg, patient, **options),
        f"+ table translation ({system.nq} DOF)": reach_map(system, target, primary_deg, secondary_deg, patient,
                                                            **options),
    }
    if motorized is not None:
        samples = table_samples(motorized)
        maps[f"+ motorized table ({motorized.nq} DOF, {len(samples)} table poses)"] = reach_map(
            motorized, target, primary_deg, secondary_deg, patient, table_samples=samples, **options)
    return maps


def compare_figure(maps: dict):
    """A :class:`matplotlib.figure.Figure` with the maps of :func:`compare_maps` side by side (one clearance
    colour scale; grey: unreachable), each titled with its share of reachable views."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4.2 * len(maps), 4.0), layout="constrained")
    axes = fig.subplots(1, len(maps), sharey=True, squeeze=False)[0]
    top = max(float(np.nanmax(np.where(m.reachable, m.clearance, np.nan), initial=0.0)) for m in maps.values()) * 1e3
    for ax, (label, m) in zip(axes, maps.items()):
        ax.set_facecolor("0.8")
        clearance = np.where(m.reachable, m.clearance * 1e3, np.nan)
        mesh = ax.pcolormesh(m.primary_deg, m.secondary_deg, clearance.T, shading="nearest", cmap="RdYlGn",
                             vmin=0.0, vmax=max(top, 1.0))
        ax.set_title(f"{label}\n{100 * m.fraction:.1f} % reachable", fontsize=9)
        ax.set_xlabel("primary (deg): RAO − / LAO +")
    axes[0].set_ylabel("secondary (deg): CAU − / CRA +")
    fig.colorbar(mesh, ax=list(axes), label="clearance (mm); grey: unreachable")
    return fig
