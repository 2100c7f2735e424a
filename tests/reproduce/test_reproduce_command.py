"""`carmkin reproduce ...`: prints the tables beside the seed's, writes JSON and plots, exits 2 on bad input."""

from __future__ import annotations

import json

import pytest

from carmkin.cli import main


def test_model_and_table_3_2(capsys, tmp_path):
    out_json = tmp_path / "r.json"
    assert main(["reproduce", "model"]) == 0
    assert "assumption" in capsys.readouterr().out
    assert main(["reproduce", "3.2", "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert "240 mm" in out and "239.80" in out
    assert set(json.loads(out_json.read_text())["3.2"]) == {"A", "B", "C"}


def test_4_6_2_with_its_decomposition_plot(capsys, tmp_path):
    plot = tmp_path / "joints.png"
    assert main(["reproduce", "4.6.2", "--tasks", "2", "--png", str(plot), "--corner-noise-px", "0.3"]) == 0
    out = capsys.readouterr().out
    assert "5.20 ± 2.60" in out and "px/deg" in out and plot.stat().st_size > 0


@pytest.mark.parametrize("argv, message", [
    (["reproduce", "4.6.2", "--corner-noise-px", "-1"], "--corner-noise-px"),
    (["reproduce", "4.6.2", "--tasks", "0"], "--tasks"),
    (["reproduce", "fit", "--png", "x.nope"], "--png"),
    (["reproduce", "5.1"], "table"),
])
def test_bad_input_exits_2_with_a_message(argv, message, capsys):
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    assert message in capsys.readouterr().err
