"""`carmkin reposition ...`: runs, speaks mm / deg, exits 2 on bad input without a traceback, stays lazy."""

from __future__ import annotations

import subprocess
import sys

import pytest

from carmkin.cli import main


def test_simulate_prints_the_guidance_steps(capsys):
    assert main(["reposition", "simulate", "--seed", "3"]) == 0
    out = capsys.readouterr().out
    assert "move " in out and " mm" in out and "°" in out
    # issue 23: "repositioned" only with the stop rule, beside the true residual and what it means
    assert "repositioned (the stop rule holds)" in out and "stop rule met" in out
    assert "Residual against the reference" in out and "What the residual means" in out


def test_experiment_and_calibration_tables(capsys):
    assert main(["reposition", "experiment", "--tasks", "2", "--seed", "1"]) == 0
    out = capsys.readouterr().out
    assert "seed (§4.6.2)" in out and "5.20 ± 2.60" in out
    assert main(["reposition", "calibration", "--noise-mm", "0.2", "--positions", "3,6", "--trials", "5"]) == 0
    assert "N = 6" in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [
    (["reposition", "simulate", "--corner-noise-px", "-1"], "--corner-noise-px"),
    (["reposition", "simulate", "--threshold-mm", "0"], "--threshold-mm"),
    (["reposition", "simulate", "--seed", "-3"], "--seed"),
    (["reposition", "experiment", "--tasks", "0"], "--tasks"),
    (["reposition", "calibration", "--positions", "a,b"], "--positions"),
    (["reposition", "calibration", "--positions", "2"], "positions must be >= 3"),
])
def test_bad_input_exits_2_with_a_message(argv, message, capsys):
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse refuses an option's value before the command runs
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_help_explains_units_and_cli_stays_light():
    out = subprocess.run([sys.executable, "-m", "carmkin.cli", "reposition", "simulate", "--help"],
                         capture_output=True, text=True, check=True).stdout
    assert "mm" in out and "deg" in out and "px" in out
    probe = "import sys; from carmkin import cli; cli.build_parser(); print('cv2' in sys.modules, 'scipy' in sys.modules)"
    loaded = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert loaded.split()[0] == "False"
