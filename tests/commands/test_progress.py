"""Progress on long work and output paths checked first (docs/cli.md): a command shows a line on a terminal's
stderr within about 2 s (:mod:`carmkin.commands._progress`), writes nothing to a redirected stderr, and refuses
an output it cannot write before any work."""

from __future__ import annotations

import io
import os
import select
import subprocess
import sys
import time

import pytest

from carmkin.commands._progress import Heartbeat
from hang import HANG_GUARD_S


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_the_heartbeat_shows_after_its_delay_and_erases_itself():
    stream = Terminal()
    with Heartbeat("carmkin demo", stream=stream, delay=0.05, refresh=0.02):
        deadline = time.monotonic() + HANG_GUARD_S
        while "working" not in stream.getvalue() and time.monotonic() < deadline:
            time.sleep(0.01)
    text = stream.getvalue()
    assert "carmkin demo: working, 0 s" in text
    assert text.endswith("\r\x1b[K")  # the line is erased at the end


def test_a_printed_line_erases_the_heartbeat_first(capsys):
    stream = Terminal()
    with Heartbeat("carmkin demo", stream=stream, delay=0.0, refresh=0.01):
        deadline = time.monotonic() + HANG_GUARD_S
        while "working" not in stream.getvalue() and time.monotonic() < deadline:
            time.sleep(0.01)
        before = len(stream.getvalue())
        print("a result")
        assert stream.getvalue()[before:].startswith("\r\x1b[K")
    assert sys.stdout is not None and "a result" in capsys.readouterr().out


def test_no_heartbeat_without_a_terminal():
    stream = io.StringIO()
    with Heartbeat("carmkin demo", stream=stream, delay=0.0, refresh=0.01):
        time.sleep(0.05)
    assert stream.getvalue() == ""


def test_a_long_command_shows_progress_on_a_terminal():
    pty = pytest.importorskip("pty")
    master, slave = pty.openpty()
    import fcntl
    import struct
    import termios

    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # a terminal's size (a bare pty has 0 columns)
    command = [sys.executable, "-m", "carmkin.cli", "reposition", "experiment", "--tasks", "3"]
    # the heartbeat at once (its 1.5 s delay would make the test depend on the machine's speed)
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=slave,
                               env={**{k: v for k, v in os.environ.items() if k != "TQDM_DISABLE"},
                                    "CARMKIN_PROGRESS_DELAY_S": "0"})
    os.close(slave)
    seen = b""
    try:
        while process.poll() is None or select.select([master], [], [], 0)[0]:
            if select.select([master], [], [], 0.2)[0]:
                try:
                    seen += os.read(master, 4096)
                except OSError:
                    break
    finally:
        process.wait(timeout=HANG_GUARD_S)
        os.close(master)
    assert process.returncode == 0
    assert b"reposition experiment: " in seen and b"/3 [" in seen  # done/total, elapsed, time left


def test_redirected_stderr_gets_no_progress_frames():
    done = subprocess.run([sys.executable, "-m", "carmkin.cli", "verify", "--samples", "3000"], capture_output=True,
                          text=True, timeout=HANG_GUARD_S, env={k: v for k, v in os.environ.items() if k != "TQDM_DISABLE"})
    assert done.returncode == 0 and done.stderr == ""


def test_the_heartbeat_redraws_a_bar_that_waits_for_a_long_step(monkeypatch):
    """A bar redraws itself only when updated: during a long step the heartbeat redraws it, so that its elapsed
    time and time left keep moving (issue "The first hour, again": verify was silent for 27 s)."""
    from tqdm import tqdm

    monkeypatch.delenv("TQDM_DISABLE", raising=False)  # set by an earlier in-process command whose stderr was captured
    stream = Terminal()
    with Heartbeat("carmkin demo", stream=stream, delay=0.0, refresh=0.01):
        with tqdm(total=4, desc="demo", file=stream, mininterval=0, leave=False, disable=False) as bar:
            bar.update(1)
            drawn = stream.getvalue().count("1/4")
            deadline = time.monotonic() + HANG_GUARD_S
            while stream.getvalue().count("1/4") < drawn + 3 and time.monotonic() < deadline:
                time.sleep(0.01)  # no update: only the heartbeat can redraw it
            assert stream.getvalue().count("1/4") >= drawn + 3
    after = stream.getvalue().split("0/4", 1)[1]
    assert "working" not in after  # while the bar is on screen it is the progress: no second line beside it


def test_reproduce_and_reposition_experiment_count_their_steps(monkeypatch, capsys):
    """done/total: the bar of `reposition experiment` counts tasks and that of `reproduce` its tables."""
    import tqdm as tqdm_module

    totals = []

    class Recording(tqdm_module.tqdm):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **{**kwargs, "disable": True})
            totals.append(kwargs["total"])
            self.done = 0

        def update(self, n=1):
            self.done += n
            totals.append(("update", n))

    monkeypatch.setattr(tqdm_module, "tqdm", Recording)
    from carmkin.cli import main

    assert main(["reposition", "experiment", "--tasks", "2"]) == 0
    assert totals[0] == 2 and totals.count(("update", 1)) == 2
    totals.clear()
    assert main(["reproduce", "model"]) == 0
    assert totals == [1, ("update", 1)]
