"""A meshcat window without a server: records the scene in memory and writes it as one static HTML page.

``meshcat.Visualizer()`` starts a server process that listens on every interface, and its
``static_html()`` asks that server for the scene. :class:`RecordingWindow` keeps the same scene tree as the
server (``meshcat.servers.tree``) in this process instead, so a page can be built with no socket and no
process at all: that is what notebooks, tests and ``carmkin view --html`` use. The page is the one
meshcat's server builds (same viewer script, same commands), with the animation replayed last.
"""

from __future__ import annotations

import os

import meshcat
import umsgpack
from meshcat.servers.tree import SceneTree, find_node, walk
from meshcat.servers.zmqserver import VIEWER_ROOT, create_command

from carmkin.errors import VisualizationError

_PAGE = """<!DOCTYPE html>
<html>
  <head><meta charset="utf-8"><title>{title}</title>
    <style>body {{ margin: 0; }} #meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}</style>
  </head>
  <body>
    <div id="meshcat-pane"></div>
    <script>{viewer_js}</script>
    <script>
      var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
      {commands}
    </script>
  </body>
</html>
"""


def _viewer_js() -> str:
    with open(os.path.join(VIEWER_ROOT, "main.min.js"), encoding="utf-8") as stream:
        return stream.read()


class RecordingWindow:
    """Stands in for ``meshcat.visualizer.ViewerWindow``: same ``send`` interface, no server.

    Supports the scene commands (``set_object``, ``set_transform``, ``set_property``, ``delete``,
    ``set_animation``); ``get_image``/``wait`` need a browser and raise :class:`VisualizationError`.
    """

    web_url = None

    def __init__(self, title: str = "carmkin") -> None:
        self.title = title
        self.tree = SceneTree()
        self.animation: bytes | None = None

    def send(self, command) -> None:
        """Record one meshcat command (the server's bookkeeping, ``ZMQWebSocketBridge.handle_zmq``)."""
        data = command.lower()
        kind, packed = data["type"], umsgpack.packb(data)
        path = [p for p in data["path"].split("/") if p]
        if kind == "set_animation":
            self.animation = packed
        elif kind == "set_object":
            node = find_node(self.tree, path)
            node.object, node.properties = packed, []
        elif kind == "set_transform":
            find_node(self.tree, path).transform = packed
        elif kind == "set_property":
            find_node(self.tree, path).properties.append(packed)
        elif kind == "delete":
            if path:
                find_node(self.tree, path[:-1]).pop(path[-1], None)
            else:
                self.tree, self.animation = SceneTree(), None
        else:
            raise VisualizationError(f"meshcat command {kind!r} needs a live viewer (use carmkin.viz.LoopbackServer)")

    def get_scene(self) -> str:
        """The recorded scene as a self-contained HTML page (objects, properties, transforms, then animation)."""
        commands = []
        for node in walk(self.tree):
            if node.object is not None:
                commands.append(node.object)
            commands.extend(node.properties)
            if node.transform is not None:
                commands.append(node.transform)
        if self.animation is not None:
            commands.append(self.animation)
        return _PAGE.format(title=self.title, viewer_js=_viewer_js(),
                            commands="".join(create_command(c) for c in commands))

    def get_image(self):
        raise VisualizationError("an offline meshcat window has no browser to capture images from")

    def wait(self):
        raise VisualizationError("an offline meshcat window has no browser to wait for")

    def open(self):
        raise VisualizationError("an offline meshcat window has no URL; write static_html() to a file instead")


def offline_visualizer(title: str = "carmkin") -> meshcat.Visualizer:
    """A ``meshcat.Visualizer`` recording into a :class:`RecordingWindow` (no server, no socket)."""
    return meshcat.Visualizer(window=RecordingWindow(title))
