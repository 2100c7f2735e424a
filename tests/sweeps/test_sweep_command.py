"""`carmkin sweep plan`: the summary, exports written and read back, exit 1 for an arc that does not fit, usage
errors in one line (exit 2). `carmkin sweep reconstruct` is tested in test_reconstruct.py (needs RTK)."""

from __future__ import annotations

import numpy as np
import pytest
from strategies import PRESET

from carmkin.cli import main
from carmkin.sweeps import astra_vectors, plan_sweep, tigre_geometry


def test_plan_prints_the_summary_and_writes_exports(tmp_path, capsys):
    astra, tigre, plot, html = tmp_path / "a.npy", tmp_path / "t.npz", tmp_path / "p.png", tmp_path / "s.html"
    assert main(["sweep", "plan", "--views", "20", "--astra", str(astra), "--tigre", str(tigre), "--png", str(plot),
                 "--html", str(html)]) == 0
    out = capsys.readouterr().out
    assert "feasible" in out and "NOT a complete short scan" in out and "limited by orbital" in out
    sweep = plan_sweep(PRESET, [0.0, 0.0, 0.0], n_views=20)
    np.testing.assert_allclose(np.load(astra), astra_vectors(sweep), atol=1e-9)
    saved = np.load(tigre)
    for key, value in tigre_geometry(sweep).items():
        np.testing.assert_allclose(saved[key], value, atol=1e-9)
    assert plot.stat().st_size > 0 and "<html" in html.read_text()[:2000].lower()


def test_plan_exits_1_when_the_arc_does_not_fit(capsys):
    assert main(["sweep", "plan", "--arc-deg", "200", "--views", "41"]) == 1
    out = capsys.readouterr().out
    assert "NOT feasible: joint orbital leaves its range" in out and "largest feasible arc 190.0°" in out


def test_plan_with_patient_and_combined_joints(capsys):
    assert main(["sweep", "plan", "--patient-box-mm", "500,300,1600", "--joint", "orbital:1,angular:0.1",
                 "--arc-deg", "120", "--views", "13", "--margin-mm", "5"]) in (0, 1)
    assert "swept clearance" in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [
    (["--joint", "elbow"], "joint 'elbow' is not a joint"),
    (["--joint", "orbital:x"], "--joint: weight"),
    (["--views", "1"], "--views"),
    (["--arc-deg", "0"], "--arc-deg"),
    (["--target-mm", "1,2"], "--target-mm needs 3"),
    (["--patient-box-mm", "1,2"], "--patient-box-mm needs"),
    (["--astra", "out.txt"], "--astra"),
    (["--q-mm-deg", "1,2"], "--q-mm-deg needs 6"),
    (["--acquisition-time-s", "0"], "--acquisition-time-s"),
    (["--acquisition-time-s", "1e9"], "--acquisition-time-s"),
])
def test_usage_errors_exit_2_in_one_line(argv, message, capsys):
    try:
        code = main(["sweep", "plan", *argv])
    except SystemExit as exc:  # argparse's own checks exit from the parser
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and err.count("\n") == 1


@pytest.mark.parametrize(("seconds", "code", "line"), [
    ("150", 0, "the joints follow a 150.0 s acquisition (orbital at 80% of its speed limit, 1.27 °/s of 1.58 °/s)"),
    ("60", 1, "the joints cannot follow a 60.0 s acquisition: orbital needs speed 3.17 °/s, its limit is 1.58 °/s "
              "(2.00x)"),
])
def test_plan_at_an_acquisition_time_checks_the_joints_follow(seconds, code, line, capsys):
    """190° at the preset's orbital 190°/120 s: 150 s is 80 % of its speed, 60 s twice it (exit 1)."""
    assert main(["sweep", "plan", "--views", "20", "--acquisition-time-s", seconds]) == code
    out = capsys.readouterr().out
    assert line in out and "sweep duration" in out
