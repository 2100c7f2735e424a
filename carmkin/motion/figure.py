"""The figure of a trajectory: clearance and joint speeds against time (matplotlib, no pyplot state)."""

from __future__ import annotations

import numpy as np

from carmkin import plots

#: Time samples of the figure's curves.
FIGURE_SAMPLES = 400


def trajectory_figure(planner, trajectory, path=None):
    """Two panels against time (s): the exact clearance (mm, coal on every pair; the margin and the certified
    bound drawn) and each moving joint's speed as a share of its limit (%). Saved to ``path`` when given."""
    scene = planner.scene
    t = np.linspace(0.0, trajectory.duration, FIGURE_SAMPLES)
    q, qd, _ = trajectory.sample(t)
    clearance = np.array([planner.certifier.distances(v).min() for v in q])
    speed = np.array([j.speed for j in scene.motion.joints])
    fig = plots.figure((8.0, 5.5), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    top.plot(t, clearance * 1e3, color="tab:blue", label="clearance (exact, every pair)")
    top.axhline(planner.margin * 1e3, color="tab:red", linestyle="--", label=f"margin {planner.margin * 1e3:g} mm")
    top.axhline(trajectory.min_clearance * 1e3, color="tab:green", linestyle=":",
                label=f"certified bound {trajectory.min_clearance * 1e3:.1f} mm")
    for time_point in trajectory.times[1:-1]:
        top.axvline(time_point, color="0.8", linewidth=0.8)
    top.set_ylabel("clearance (mm)")
    top.legend(loc="upper right", fontsize="small")
    top.set_title(f"{planner.system.name}: {trajectory.method}, {trajectory.duration:.1f} s")
    for j, name in enumerate(scene.joint_names):
        if np.any(qd[:, j] != 0.0):
            bottom.plot(t, 100.0 * np.abs(qd[:, j]) / speed[j], label=name)
    bottom.set_ylabel("joint speed (% of its limit)")
    bottom.set_xlabel("time (s)")
    bottom.set_ylim(0.0, 105.0)
    bottom.legend(loc="upper right", fontsize="small", ncol=2)
    return plots.save(fig, path)

