"""A meshcat server that listens on the loopback interface only, run in a thread of this process.

meshcat 0.3.2 binds its ZMQ socket to ``127.0.0.1`` but its web server (``ZMQWebSocketBridge`` calls
``app.listen(port)`` with no address) to every interface, and ``meshcat.Visualizer()`` runs it in a separate
process that outlives a killed parent. :class:`LoopbackServer` runs the same bridge in a daemon thread with
the HTTP/WebSocket listener bound to ``host`` as well: nothing is reachable from other machines, and the
server cannot outlive the process that started it.

    with LoopbackServer() as server:
        vis = server.visualizer()        # a meshcat.Visualizer connected over ZMQ
        print(server.web_url)            # http://127.0.0.1:7000/static/
"""

from __future__ import annotations

import asyncio
import contextlib
import io
import threading

import meshcat
from meshcat.servers.zmqserver import ZMQWebSocketBridge

from carmkin.errors import ServerError

LOOPBACK = "127.0.0.1"


class _LoopbackBridge(ZMQWebSocketBridge):
    """meshcat's bridge with the web server bound to ``host`` (meshcat binds it to all interfaces)."""

    http_server = None

    def make_app(self):
        app = super().make_app()
        listen = app.listen

        def listen_on_host(port, **kwargs):
            self.http_server = listen(port, address=self.host, **kwargs)
            return self.http_server

        app.listen = listen_on_host
        return app


class LoopbackServer:
    """meshcat ZMQ + HTTP/WebSocket server on ``host`` (default ``127.0.0.1``), served by a daemon thread.

    Args:
        host: address both sockets bind to. Only loopback addresses are accepted.
        port: HTTP port; ``None`` takes the first free port from 7000 (meshcat's rule).
        zmq_port: ZMQ port; ``None`` takes the first free port from 6000.
        timeout: seconds to wait for the server to start or stop.
    """

    def __init__(self, host: str = LOOPBACK, port: int | None = None, zmq_port: int | None = None,
                 timeout: float = 10.0) -> None:
        if not (host.startswith("127.") or host == "localhost"):
            raise ServerError(f"host must be a loopback address (127.x.x.x), got {host!r}")
        self.host, self.port, self.zmq_port, self.timeout = host, port, zmq_port, timeout
        self._bridge: _LoopbackBridge | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._clients: list[meshcat.Visualizer] = []

    # --- life cycle ----------------------------------------------------------------------------------
    def start(self) -> "LoopbackServer":
        """Start serving; returns once both sockets listen (raises :class:`ServerError` otherwise)."""
        if self._thread is not None:
            raise ServerError("server already started")
        self._thread = threading.Thread(target=self._serve, name="carmkin-meshcat", daemon=True)
        self._thread.start()
        if not self._ready.wait(self.timeout):
            raise ServerError(f"meshcat server did not start within {self.timeout} s")
        if self._error is not None:
            self._thread.join(self.timeout)
            raise ServerError(f"meshcat server failed to start: {self._error}") from self._error
        return self

    def stop(self) -> None:
        """Close the clients made by :meth:`visualizer`, stop the server and join its thread."""
        for client in self._clients:
            client.window.zmq_socket.close(linger=0)
        self._clients.clear()
        if self._thread is None:
            return
        if self._bridge is not None:
            self._bridge.ioloop.add_callback(self._bridge.ioloop.stop)
        self._thread.join(self.timeout)
        if self._thread.is_alive():
            raise ServerError(f"meshcat server thread did not stop within {self.timeout} s")
        self._thread = None

    def __enter__(self) -> "LoopbackServer":
        return self.start()

    def __exit__(self, *exc_info) -> None:
        self.stop()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    # --- addresses -----------------------------------------------------------------------------------
    @property
    def web_url(self) -> str:
        """URL of the viewer page, e.g. ``http://127.0.0.1:7000/static/``."""
        return self._started().web_url

    @property
    def zmq_url(self) -> str:
        """ZMQ endpoint the Python clients send scene commands to, e.g. ``tcp://127.0.0.1:6000``."""
        return self._started().zmq_url

    def bound_addresses(self) -> list[tuple[str, int]]:
        """``(address, port)`` of every listening HTTP socket of the server (from the sockets themselves)."""
        server = self._started().http_server
        return [sock.getsockname()[:2] for sock in server._sockets.values()]

    def visualizer(self) -> meshcat.Visualizer:
        """A ``meshcat.Visualizer`` connected to this server (closed by :meth:`stop`)."""
        with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints the URL itself
            client = meshcat.Visualizer(zmq_url=self.zmq_url)
        self._clients.append(client)
        return client

    # --- internals -----------------------------------------------------------------------------------
    def _started(self) -> _LoopbackBridge:
        if self._bridge is None or not self.running:
            raise ServerError("server not running: call start() or use it as a context manager")
        return self._bridge

    def _serve(self) -> None:
        loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)
        try:
            zmq_url = None if self.zmq_port is None else f"tcp://{self.host}:{self.zmq_port}"
            self._bridge = _LoopbackBridge(zmq_url=zmq_url, host=self.host, port=self.port)
        except BaseException as exc:  # reported to the starting thread
            self._error = exc
            self._ready.set()
            loop.close()
            return
        self._ready.set()
        try:
            self._bridge.ioloop.start()
        finally:
            self._bridge.http_server.stop()
            self._bridge.zmq_stream.close(linger=0)
            for websocket in list(self._bridge.websocket_pool):
                websocket.close()
            loop.run_until_complete(asyncio.sleep(0))
            loop.close()
