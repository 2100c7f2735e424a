"""The README's tour does what its text says: its Python blocks run, and the values its comments print are
the values the code produces. Every ```python block of the README and docs/ runs as written, and every
``tests/...`` path the docs name exists. The ```console blocks of the README and docs/*.md print what they show.

The convention for Python blocks: the blocks of one page run in order in one namespace (a later block may use
what an earlier one defined, as in a notebook), in a fresh folder, with matplotlib's non-interactive backend.
A block that cannot run as written (it needs a browser, a GPU, minutes) starts with the line
``# not run by the tests: <why>``: the page shows the reason and the test skips that block with it.

The convention for numbers quoted in the docs: a fenced block ```console whose first line is ``$ carmkin ...``
(a fast, deterministic command, a few seconds at most), followed by what the command prints, stdout and
stderr together, as a terminal shows them. A line ``...`` stands for any number of lines; a line ending with
``# varies`` (rounding noise, timings; keep them rare) may print other numbers with the same words; a
printed zero's sign and the width of runs of spaces do not count. Slower commands go in a plain ``` block."""

import contextlib
import io
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hang import HANG_GUARD_S

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: Every page of the documentation: the README and docs/ (new pages are picked up by this glob).
PAGES = sorted([README, *(ROOT / "docs").rglob("*.md")])
#: First line of a ```python block the tests do not run, followed by the reason (shown in the page).
NOT_RUN = "# not run by the tests:"


def python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_the_tour_runs_and_prints_what_its_comments_say():
    blocks = python_blocks(README.read_text())
    assert blocks, "the README has a Python tour"
    for block in blocks:
        namespace: dict = {}
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            exec(compile(block, "README.md", "exec"), namespace)  # noqa: S102 - our own README
        printed = out.getvalue().splitlines()
        promised = [re.split(r"\s{2,}", m.group(1))[0].strip() for line in block.splitlines()
                    if line.startswith("print(") and (m := re.search(r"#\s*(.+)$", line))]
        assert len(printed) == len(promised)
        for got, want in zip(printed, promised):
            assert got.strip() == want, f"README promises {want!r}, the code prints {got.strip()!r}"


def test_the_tour_solve_succeeds_and_reaches_the_target():
    namespace: dict = {}
    with contextlib.redirect_stdout(io.StringIO()):
        exec(compile(python_blocks(README.read_text())[0], "README.md", "exec"), namespace)  # noqa: S102
    res, system, T = namespace["res"], namespace["system"], namespace["T"]
    assert res.success and res.validity.valid
    assert np.allclose(system.fk(res.q), T, atol=1e-9)


# --- every python block of every page runs -----------------------------------------------------------------
def page_blocks(path: Path) -> list[tuple[int, str]]:
    """``(line, source)`` of each ```python block of ``path``."""
    text = path.read_text()
    return [(text.count("\n", 0, m.start()) + 2, m.group(1))
            for m in re.finditer(r"^```python\n(.*?)^```", text, flags=re.S | re.M)]


PAGES_WITH_CODE = [p for p in PAGES if page_blocks(p)]


def not_run_reason(source: str) -> str | None:
    first = source.lstrip().splitlines()[0] if source.strip() else ""
    return first[len(NOT_RUN):].strip() if first.startswith(NOT_RUN) else None


@pytest.mark.parametrize("path", PAGES_WITH_CODE, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_python_block_runs_as_written(path, tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__docs__"}
    skipped = []
    for line, source in page_blocks(path):
        reason = not_run_reason(source)
        if reason is not None:
            assert reason, f"{path.name}:{line}: say why the block is not run"
            skipped.append(f"{path.name}:{line}: {reason}")
            continue
        with contextlib.redirect_stdout(io.StringIO()):
            exec(compile(source, f"{path.relative_to(ROOT)}:{line}", "exec"), namespace)  # noqa: S102 - our docs
        plt.close("all")
    if skipped:
        pytest.skip("; ".join(skipped))


def test_blocks_that_are_not_run_say_why():
    marked = [(p.name, line, not_run_reason(s))
              for p in PAGES for line, s in page_blocks(p) if not_run_reason(s) is not None]
    assert all(reason for _, _, reason in marked), marked


def test_the_docs_pages_have_python_blocks():
    assert sum(len(page_blocks(p)) for p in PAGES) >= 12


# --- every tests/ path the docs name exists -----------------------------------------------------------------
TEST_REFERENCE = re.compile(r"\btests/[\w/.-]*\w(?:/|::\w+)?")


def test_every_test_path_in_the_docs_exists():
    stale = []
    for path in PAGES:
        for number, line in enumerate(path.read_text().splitlines(), 1):
            for ref in TEST_REFERENCE.findall(line):
                file, _, name = ref.partition("::")
                target = ROOT / file
                if not target.exists():
                    stale.append(f"{path.relative_to(ROOT)}:{number}: {file} does not exist")
                elif name and not re.search(rf"^\s*(?:async\s+)?(?:def|class)\s+{name}\b", target.read_text(), re.M):
                    stale.append(f"{path.relative_to(ROOT)}:{number}: {file} has no {name}")
    assert not stale, "\n".join(stale)


# --- console blocks: the numbers the docs quote are the numbers the commands print ---------------------------
DOCS = PAGES
#: A line of a console block ending with this marker may print other numbers (timings, rounding noise): each
#: number in it stands for any number; its words must still match.
VARIES = "# varies"
#: A line of a console block that is exactly this stands for any number of output lines (none included).
ELISION = "..."
NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def console_blocks() -> list[tuple[str, str, list[str]]]:
    """``(where, command line, expected output lines)`` of every ```console block whose first line is
    ``$ carmkin ...`` in the README and docs/*.md."""
    found = []
    for path in DOCS:
        text = path.read_text()
        for match in re.finditer(r"```console\n(.*?)```", text, flags=re.S):
            lines = match.group(1).splitlines()
            if lines and lines[0].startswith("$ carmkin "):
                where = f"{path.name}:{text.count(chr(10), 0, match.start()) + 1}"
                found.append((where, lines[0][2:], lines[1:]))
    return found


def normalized(line: str) -> str:
    """A printed zero's sign is rounding noise (``-0.000`` and ``+0.`` read as `` 0.000`` and `` 0.``), and so is
    the width it takes in a padded column (runs of spaces read as one)."""
    return " ".join(re.sub(r"(?<![\w.])[-+](?=0(?:\.0*)?(?![\d.]))", " ", line).split())


def line_matches(printed: str, promised: str) -> bool:
    printed, promised = normalized(printed), normalized(promised)
    if not promised.endswith(VARIES):
        return printed == promised
    words = re.split(NUMBER, promised[:-len(VARIES)].strip())
    return re.fullmatch(NUMBER.join(re.escape(w) for w in words), printed) is not None


def output_matches(printed: list[str], promised: list[str]) -> bool:
    """Line by line; an :data:`ELISION` line in ``promised`` skips any number of printed lines."""
    if not promised:
        return not printed
    if promised[0] == ELISION:
        return any(output_matches(printed[k:], promised[1:]) for k in range(len(printed) + 1))
    return bool(printed) and line_matches(printed[0], promised[0]) and output_matches(printed[1:], promised[1:])


def test_the_console_convention_reads_as_documented():
    assert line_matches("rank 5; det J +1.6e-16", f"rank 5; det J -3e-17  {VARIES}")
    assert not line_matches("rank 5; det K +1.6e-16", f"rank 5; det J -3e-17  {VARIES}")
    assert line_matches("orbital=-0.000°, d=[ 0. -0.]", "orbital=+0.000°, d=[ 0.  0.]")
    assert not line_matches("orbital=-0.001°", "orbital=+0.001°")
    assert not line_matches("x -0.4937", "x 0.4937") and not line_matches("e-06", "e06")
    assert output_matches(["a", "b", "c", "d"], ["a", ELISION, "d"]) and output_matches(["a"], ["a", ELISION])
    assert not output_matches(["a", "b"], ["a"]) and not output_matches(["a"], ["a", "b"])


@pytest.mark.parametrize("where, command, promised", console_blocks(), ids=[b[0] for b in console_blocks()])
def test_console_blocks_print_what_the_docs_show(where, command, promised, tmp_path):
    """Runs ``$ carmkin ...`` of a ```console block in a fresh folder, with this interpreter's carmkin;
    stdout and stderr together, as a terminal shows them (progress bars off)."""
    env = {**os.environ, "TQDM_DISABLE": "1", "COLUMNS": "120"}
    done = subprocess.run([sys.executable, "-m", "carmkin.cli", *shlex.split(command)[1:]], cwd=tmp_path, env=env,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=HANG_GUARD_S)
    printed = done.stdout.splitlines()
    assert output_matches(printed, promised), (
        f"{where}: `{command}` printed\n" + "\n".join(printed) + "\n\nbut the docs show\n" + "\n".join(promised))


def test_there_are_console_blocks_in_the_docs():
    assert len(console_blocks()) >= 6


# --- CI runs each README command with what that command installs -----------------------------------------------
#: A README command that installs an extra and runs something with it: ``python -m pip install -e ".[x]" && ...``.
README_INSTALL = re.compile(r'^python -m pip install -e "\.\[(\w+)\]" && .+$', re.M)


def test_ci_runs_each_readme_command_of_an_extra_in_a_fresh_venv_with_only_that_extra():
    """The README's test and docs commands pass on a fresh machine with what each installs: .ci/run runs each
    exactly as written in its own fresh virtual environment, before anything else is installed into it."""
    ci = (ROOT / ".ci" / "run").read_text()
    commands = README_INSTALL.findall(README.read_text())
    assert {"test", "docs"} <= set(commands)
    for match in README_INSTALL.finditer(README.read_text()):
        command, extra = match.group(0), match.group(1)
        run = re.search(rf"\n    {re.escape(command)}(?: 2>&1 \| tee \S+)?\n", ci)  # its output may be logged too
        assert run, f".ci/run does not run the README's `{command}` as written"
        before = ci[:run.start()]
        fresh = before.rindex("python3 -m venv")
        installs = re.findall(r"pip install (?!-q --upgrade pip)[^\n]*", before[fresh:])
        assert not installs, f"`{command}` runs in a virtual environment that already has {installs}"


# --- the README's "What is where" names resolve as written -------------------------------------------------
WHAT_IS_WHERE = README.read_text().split("### What is where", 1)[1].split("\n## ", 1)[0]
#: Each name resolved after a fresh ``import carmkin`` alone (every carmkin module dropped before each name, so
#: that no earlier name's imports make a later one resolve by accident).
RESOLVE = """
import sys
bad = []
for name in sys.argv[1:]:
    for module in [m for m in sys.modules if m == "carmkin" or m.startswith("carmkin.")]:
        del sys.modules[module]
    import carmkin
    value = carmkin
    try:
        for part in name.split(".")[1:]:
            value = getattr(value, part)
    except AttributeError as exc:
        bad.append(f"{name}: {exc}")
print("\\n".join(bad))
"""


def test_every_name_of_what_is_where_resolves_after_import_carmkin():
    names = sorted(set(re.findall(r"`(carmkin(?:\.\w+)+)`", WHAT_IS_WHERE)))
    assert len(names) >= 20 and "carmkin.robot.verify" in names
    done = subprocess.run([sys.executable, "-c", RESOLVE, *names], capture_output=True, text=True,
                          timeout=HANG_GUARD_S)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "", f"names of the README's What is where that fail after import carmkin:\n{done.stdout}"
