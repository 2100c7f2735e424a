"""A planned motion in the browser (issue 37): the C-arm moving along a :class:`carmkin.motion.Trajectory`, as one
static meshcat page (no server), played by the page itself."""

from __future__ import annotations

import numpy as np

from .static import offline_visualizer
from .viewer import CArmViewer
from .views import draw_patient

#: Frames per second of the browser animation of a trajectory (:func:`animation_viewer`).
ANIMATION_FPS = 10.0
#: At most this many frames in the page (a long motion plays faster than real time beyond it; the page stays small).
MAX_FRAMES = 600


def animation_viewer(planner, trajectory, patient=None) -> CArmViewer:
    """A viewer without a server (meshcat's scene recorded in memory): the C-arm moving along ``trajectory``
    around ``patient``, in real time up to :data:`MAX_FRAMES` frames at :data:`ANIMATION_FPS` (faster beyond),
    with play / pause / scrub in the page's "Animations" panel. Shown inline in a notebook;
    ``.static_html()`` is the page."""
    frames = int(min(MAX_FRAMES, max(2, round(trajectory.duration * ANIMATION_FPS) + 1)))
    q, _, _ = trajectory.sample(np.linspace(0.0, trajectory.duration, frames))
    viewer = CArmViewer(planner.system, offline_visualizer(f"carmkin motion: {planner.system.name}"), q=q[0])
    if patient is not None:
        draw_patient(viewer, patient)
    viewer.animate_path(q, fps=ANIMATION_FPS * max(1.0, trajectory.duration * ANIMATION_FPS / (frames - 1)))
    return viewer
