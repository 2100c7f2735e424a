"""No test is bound to wall time: every wait of a test (a subprocess's ``timeout=``, a ``time.monotonic() + ...``
deadline) is the one hang guard of tests/hang.py, minutes long, never a number of its own that a loaded machine
could exceed (issue "The first hour, again": ``carmkin reproduce all`` given 120 s failed at load 4.6)."""

import re
from pathlib import Path

from hang import HANG_GUARD_S

TESTS = Path(__file__).resolve().parent
#: A wait bounded by a number written in place: ``timeout=120``, ``timeout=2.5``, ``time.monotonic() + 10``.
NUMERIC_WAIT = re.compile(r"\btimeout\s*=\s*\d|\b(?:monotonic|perf_counter|time)\(\)\s*\+\s*\d")


def test_no_test_waits_for_a_number_of_seconds_of_its_own():
    found = [f"{path.relative_to(TESTS)}:{number}: {line.strip()}"
             for path in sorted(TESTS.rglob("*.py")) if path.name != Path(__file__).name
             for number, line in enumerate(path.read_text().splitlines(), 1) if NUMERIC_WAIT.search(line)]
    assert not found, "a wall-time bound (use hang.HANG_GUARD_S):\n" + "\n".join(found)


def test_the_rule_recognises_a_numeric_wait():
    for line in ("subprocess.run(c, timeout=120)", "deadline = time.monotonic() + 10", "p.wait(timeout = 2.5)"):
        assert NUMERIC_WAIT.search(line), line
    for line in ("subprocess.run(c, timeout=HANG_GUARD_S)", "deadline = time.monotonic() + HANG_GUARD_S"):
        assert not NUMERIC_WAIT.search(line), line


def test_the_hang_guard_is_minutes_long():
    assert HANG_GUARD_S >= 15 * 60
