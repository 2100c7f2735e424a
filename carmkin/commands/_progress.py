"""Progress for every command: a line on stderr that says the command is working and for how long.

Commands with a measured amount of work show a tqdm bar (``verify``, ``workspace``...); every other command
that runs longer than :data:`DELAY_S` gets this heartbeat instead, so that no command is silent for more than
about 2 s. Both only draw on a terminal: with stderr redirected to a file or a pipe nothing is written (no bar
frames in a log). While a tqdm bar is on screen the heartbeat redraws it every :data:`REFRESH_S` (done/total,
elapsed, rate and time left keep moving during a long step) instead of its own line, which it erases at the end.
"""

from __future__ import annotations

import os
import sys
import threading
import time

#: Seconds of silence before the heartbeat shows (the environment variable ``CARMKIN_PROGRESS_DELAY_S`` may
#: change it: 0 shows it at once, as the tests do).
DELAY_S = 1.5
#: Seconds between two refreshes of the heartbeat line.
REFRESH_S = 0.5


def _bars_on_screen() -> list:
    """The tqdm bars drawing now (tqdm is imported only if a command already did)."""
    tqdm_module = sys.modules.get("tqdm.std")
    return [] if tqdm_module is None else [b for b in list(getattr(tqdm_module.tqdm, "_instances", ()))
                                           if not getattr(b, "disable", True)]


def _refresh(bars) -> None:
    """Redraw ``bars``: their elapsed time, rate and time left move on while one step of the work takes long
    (a bar redraws itself only when it is updated: ``verify`` showed nothing for 27 s)."""
    for bar in bars:
        try:
            bar.refresh()
        except (OSError, ValueError, AttributeError):  # the terminal went away, or the bar just closed
            pass


class Heartbeat:
    """``with Heartbeat("carmkin views plan"):`` -> after :data:`DELAY_S`, ``carmkin views plan: working, 3 s``
    on ``stream`` (default stderr), refreshed every :data:`REFRESH_S` until the block ends; nothing unless
    ``stream`` is a terminal."""

    def __init__(self, name: str, stream=None, delay: float | None = None, refresh: float = REFRESH_S):
        if delay is None:
            try:
                delay = float(os.environ.get("CARMKIN_PROGRESS_DELAY_S", DELAY_S))
            except ValueError:
                delay = DELAY_S
        self.name, self.stream, self.delay, self.refresh = name, stream or sys.stderr, delay, refresh
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._drawn = False

    def _enabled(self) -> bool:
        try:
            return bool(self.stream.isatty())
        except (AttributeError, ValueError):
            return False

    def __enter__(self) -> "Heartbeat":
        if self._enabled():
            self._start = time.monotonic()
            self._lock = threading.Lock()
            self._stdout = sys.stdout
            sys.stdout = _Erasing(self._stdout, self)  # a printed line first erases the heartbeat
            self._thread = threading.Thread(target=self._run, name="carmkin-heartbeat", daemon=True)
            self._thread.start()
        return self

    def erase(self) -> None:
        """Erase the heartbeat line (before other output); the next refresh draws it again."""
        with self._lock:
            if self._drawn:
                try:
                    self.stream.write("\r\x1b[K")
                    self.stream.flush()
                except (OSError, ValueError):
                    pass
                self._drawn = False

    def _run(self) -> None:
        if self._stop.wait(self.delay):
            return
        while not self._stop.is_set():
            bars = _bars_on_screen()
            if bars:
                _refresh(bars)
            else:
                self._draw(f"{self.name}: working, {time.monotonic() - self._start:.0f} s")
            if self._stop.wait(self.refresh):
                break

    def _draw(self, text: str) -> None:
        with self._lock:
            try:
                self.stream.write("\r\x1b[K" + text)
                self.stream.flush()
                self._drawn = True
            except (OSError, ValueError):  # the terminal went away: stop quietly
                self._stop.set()

    def __exit__(self, *exc) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            if sys.stdout.__class__ is _Erasing:
                sys.stdout = self._stdout
            self.erase()


class _Erasing:
    """stdout while a heartbeat runs: each write first erases the heartbeat's line (same terminal)."""

    def __init__(self, stream, heartbeat: Heartbeat):
        self._stream, self._heartbeat = stream, heartbeat

    def write(self, text: str) -> int:
        self._heartbeat.erase()
        return self._stream.write(text)

    def __getattr__(self, name):
        return getattr(self._stream, name)
