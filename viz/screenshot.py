"""Render an HTML page (e.g. a static viewer page) to PNG with headless Chromium, software WebGL.

Needs a Chromium or Chrome executable (Debian: ``apt-get install chromium``); set ``CARMKIN_CHROMIUM`` to
pick one explicitly. Chromium runs in its own process group, which is killed on timeout, so no browser
process outlives the call.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import tempfile
from pathlib import Path

from carmkin.errors import BrowserNotFoundError, VisualizationError

#: Shortest virtual-time budget accepted: with 200 ms, Chromium never finished on a static viewer page here
#: (the 0.9 MB page had not loaded when the budget ran out and an idle page draws no further frame).
MIN_BUDGET_MS = 1000
CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome")
#: Flags measured to render WebGL headless on this kind of machine (software rasterizer, no network).
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--enable-unsafe-swiftshader", "--hide-scrollbars")


def find_chromium() -> str:
    """Path of a Chromium/Chrome executable, or :class:`BrowserNotFoundError` saying what was tried."""
    explicit = os.environ.get("CARMKIN_CHROMIUM")
    if explicit:
        if shutil.which(explicit) is None:
            raise BrowserNotFoundError(f"CARMKIN_CHROMIUM={explicit!r} is not an executable")
        return shutil.which(explicit)
    for name in CANDIDATES:
        path = shutil.which(name)
        if path:
            return path
    raise BrowserNotFoundError(f"no Chromium found (tried {', '.join(CANDIDATES)} on PATH; "
                               "install it with `apt-get install chromium` or set CARMKIN_CHROMIUM)")


def screenshot(url_or_path, png_path, size: tuple[int, int] = (1024, 768), budget_ms: int = 5000,
               timeout: float = 90.0) -> Path:
    """Render ``url_or_path`` (a URL or an HTML file) to ``png_path`` at ``size`` (pixels); returns the PNG path.

    ``budget_ms`` is Chromium's virtual-time budget: how long the page may run (animations included)
    before the picture is taken; at least :data:`MIN_BUDGET_MS`.
    """
    if budget_ms < MIN_BUDGET_MS:
        raise VisualizationError(f"budget_ms must be >= {MIN_BUDGET_MS} ms, got {budget_ms}")
    url = str(url_or_path)
    if "://" not in url:
        path = Path(url).resolve()
        if not path.is_file():
            raise VisualizationError(f"no page to render at {path}")
        url = path.as_uri()
    png_path = Path(png_path).resolve()
    png_path.unlink(missing_ok=True)
    with tempfile.TemporaryDirectory(prefix="carmkin-chromium-") as profile:
        command = [find_chromium(), *FLAGS, f"--user-data-dir={profile}", f"--window-size={size[0]},{size[1]}",
                   f"--virtual-time-budget={budget_ms}", f"--screenshot={png_path}", url]
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                   start_new_session=True)
        try:
            _, stderr = process.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            raise VisualizationError(f"chromium did not finish within {timeout} s") from None
        finally:
            _kill_group(process)
    if process.returncode != 0 or not png_path.is_file():
        tail = stderr.decode(errors="replace").strip().splitlines()[-5:]
        raise VisualizationError(f"chromium exited with {process.returncode} and no screenshot: {' | '.join(tail)}")
    return png_path


def _kill_group(process: subprocess.Popen) -> None:
    """Kill what is left of the process group Chromium was started in (helpers it spawned)."""
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    process.communicate()
