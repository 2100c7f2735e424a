"""Browser visualization of a C-arm + table with meshcat (installed as ``carmkin.viz``).

- :class:`CArmViewer`: robot from the URDF, X-ray cone, frames, ghosts, distances, animated moves.
- :func:`offline_visualizer`: record a scene with no server and write it as one static HTML page.
- :class:`LoopbackServer`: a live meshcat server listening on 127.0.0.1 only.
- :func:`screenshot`: render a page to PNG with headless Chromium.
- :func:`dose_page`: a skin dose map (:mod:`carmkin.dose`) as a coloured skin in a static page (:mod:`.dose`).
"""

import warnings

from carmkin.errors import BrowserNotFoundError, ServerError, VisualizationError

with warnings.catch_warnings():  # meshcat 0.3.2 imports pyzmq's deprecated zmq.eventloop.ioloop: not the user's concern
    warnings.filterwarnings("ignore", message="zmq.eventloop.ioloop is deprecated", category=DeprecationWarning)
    import meshcat  # noqa: F401 (imported once here, quietly; the modules below find it loaded)

from .distances import DistanceChecker, PairDistance
from .dose import dose_page
from .screenshot import find_chromium, screenshot
from .server import LoopbackServer
from .static import RecordingWindow, offline_visualizer
from .viewer import CArmViewer, check_configuration, interpolate

__all__ = [
    "BrowserNotFoundError",
    "CArmViewer",
    "DistanceChecker",
    "LoopbackServer",
    "PairDistance",
    "RecordingWindow",
    "ServerError",
    "VisualizationError",
    "check_configuration",
    "dose_page",
    "find_chromium",
    "interpolate",
    "offline_visualizer",
    "screenshot",
]
