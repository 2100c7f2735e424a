"""`carmkin move plan` (issue 37): mm and degrees in, the certified motion out (text, JSON, figure, a page that plays
it in a real headless browser); usage errors exit 2 in one line, a motion not found exits 1 with the reason."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from hang import HANG_GUARD_S

from carmkin.cli import main


def run(*args):
    return subprocess.run([sys.executable, "-m", "carmkin.cli", "move", *args], capture_output=True, text=True,
                          timeout=HANG_GUARD_S)


def test_plan_to_a_view_prints_and_writes_the_motion(capsys, tmp_path):
    out_json = tmp_path / "m.json"
    assert main(["move", "plan", "--to-view", "lao-30", "--json", str(out_json), "--png", str(tmp_path / "m.png")]) == 0
    text = capsys.readouterr().out
    assert "motion: straight, 1 segment(s)" in text and "certified clearance" in text
    data = json.loads(out_json.read_text())
    assert data["success"] and data["method"] == "straight" and data["margin_mm"] == 10.0
    assert data["min_clearance_mm"] >= 10.0 - 0.1
    assert data["duration_s"] == pytest.approx(data["times_s"][-1])
    assert set(data["goal"]) == {"table_translation_mm", "vertical_mm", "wigwag_deg", "horizontal_mm", "angular_deg",
                                 "orbital_deg"}
    assert (tmp_path / "m.png").stat().st_size > 10_000


def test_a_motion_not_found_exits_1_with_the_reason():
    result = run("plan", "--to-view", "pa", "--time-limit-s", "0.2")
    assert result.returncode == 1, result.stderr
    assert "not found within 0.2 s" in result.stdout and "Traceback" not in result.stderr


@pytest.mark.parametrize("args, expected", [
    (["--to-view", "foo"], "unknown standard view 'foo'"),
    (["--to-q-mm-deg", "0,0,0,0,0,500"], "orbital = 500 deg is outside its range"),
    (["--to-q-mm-deg", "0,0,0"], "needs 6 comma-separated values"),
    (["--to-view", "ap", "--time-limit-s", "0"], "--time-limit-s"),
    (["--to-view", "ap", "--margin-mm", "-3"], "--margin-mm"),
    (["--to-view", "ap", "--planner", "prm"], "--planner"),
    ([], "one of the arguments --to-view --to-q-mm-deg is required"),
    (["--to-view", "ap", "--q-mm-deg", "0,100,0,100,90,0"], "q_from is not clear of the 10 mm margin"),
])
def test_usage_errors_exit_2_in_one_line(args, expected):
    result = run("plan", *args)
    assert result.returncode == 2, (result.stdout, result.stderr)
    assert expected in result.stderr and "Traceback" not in result.stderr


def test_the_page_plays_the_motion_in_headless_chromium(tmp_path):
    """Early and late screenshots of the page differ: the C-arm moves (the animation plays by itself)."""
    from carmkin.errors import BrowserNotFoundError
    from carmkin.viz.screenshot import find_chromium, screenshot

    try:
        find_chromium()
    except BrowserNotFoundError as exc:
        pytest.skip(f"headless browser test skipped: {exc}")
    from PIL import Image

    page = tmp_path / "move.html"
    assert main(["move", "plan", "--to-view", "lao-30", "--html", str(page)]) == 0
    early = np.asarray(Image.open(screenshot(page, tmp_path / "early.png", (600, 450), budget_ms=1000)), float)
    late = np.asarray(Image.open(screenshot(page, tmp_path / "late.png", (600, 450), budget_ms=8000)), float)
    assert early.std() > 10, "blank screenshot"
    changed = (np.abs(early - late).max(axis=-1) > 30).mean()
    assert changed > 0.005, f"only {changed:.2%} of the pixels differ: the motion did not play"
