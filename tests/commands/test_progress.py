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
    command = [sys.executable, "-m", "carmkin.cli", "reposition", "experiment", "--tasks", "3"]
    # the heartbeat at once (its 1.5 s delay would make the test depend on the machine's speed)
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=slave,
                               env={**os.environ, "CARMKIN_PROGRESS_DELAY_S": "0"})
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
    assert b"carmkin reposition experiment: working" in seen


def test_redirected_stderr_gets_no_progress_frames():
    done = subprocess.run([sys.executable, "-m", "carmkin.cli", "verify", "--samples", "3000"], capture_output=True,
                          text=True, timeout=HANG_GUARD_S, env={k: v for k, v in os.environ.items() if k != "TQDM_DISABLE"})
    assert done.returncode == 0 and done.stderr == ""
