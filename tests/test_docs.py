"""The README's tour does what its text says: its Python blocks run, and the values its comments print are
the values the code produces."""

import contextlib
import io
import re
from pathlib import Path

import numpy as np

README = Path(__file__).resolve().parents[1] / "README.md"


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
