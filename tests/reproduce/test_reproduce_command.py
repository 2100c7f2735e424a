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


def test_fit_reruns_a_small_grid_end_to_end(capsys, tmp_path):
    """Issue 31: the fit exited 2 at 1 px corner noise (the §3.3.3 calibration refused the grid's room)."""
    out_json = tmp_path / "fit.json"
    argv = ["reproduce", "fit", "--corner-noise-grid-px", "1,1.5", "--operator-scale-grid", "0.4", "--fit-tasks", "3",
            "--json", str(out_json)]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "chi2 of the seed's six numbers" in out and "REPRODUCED" in out
    grid = json.loads(out_json.read_text())["fit"]["grid"]
    assert {(c, s) for c, s, _ in grid} <= {(1.0, 0.4), (1.5, 0.4)} and grid


def test_3_2_prints_its_verdict_with_kind_and_criterion(capsys, tmp_path):
    out_json = tmp_path / "v.json"
    assert main(["reproduce", "3.2", "--repeats", "2", "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert "predicted" in out and "error < 1 % (seed's claim)" in out and "fitted 0 (in-sample" in out
    rows = json.loads(out_json.read_text())["verdict"]
    assert len(rows) == 12 and {r["kind"] for r in rows} == {"predicted"} and all(r["criterion"] for r in rows)


@pytest.mark.parametrize("argv, message", [
    (["reproduce", "4.6.2", "--corner-noise-px", "-1"], "--corner-noise-px"),
    (["reproduce", "4.6.2", "--tasks", "0"], "--tasks"),
    (["reproduce", "fit", "--png", "x.nope"], "--png"),
    (["reproduce", "5.1"], "table"),
    (["reproduce", "all", "--repeats", "1"], "--repeats"),
    (["reproduce", "fit", "--corner-noise-grid-px", "1,x"], "--corner-noise-grid-px"),
    (["reproduce", "fit", "--operator-scale-grid", "-1"], "--operator-scale-grid"),
])
def test_bad_input_exits_2_with_a_message(argv, message, capsys):
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    assert message in capsys.readouterr().err


def _region_dependent(calls):
    """A fake experiment: row "a" reproduced everywhere, row "b" not reproduced at 1 px corner noise only."""
    from carmkin.reproduce import verdict

    def experiment(system, model, repeats, **options):
        calls.append((model.corner_noise_px, round(model.operator_scale, 12)))
        b = "not reproduced" if model.corner_noise_px == 1.0 else "reproduced"
        return [verdict.Row("x", "a", 1.0, 1.0, 0.1, 0.0, 1.0, "reproduced", "predicted", "fake"),
                verdict.Row("x", "b", 1.0, 1.0, 0.1, 0.0, 1.0, b, "predicted", "fake")]
    return experiment


@pytest.mark.parametrize("extra, expected, rule", [
    ([], "predicted 2 (1 reproduced, 0 not reproduced, 1 undetermined)", "judged across the fit's 95 % region (3 points"),
    (["--best-fit-only"], "predicted 2 (2 reproduced, 0 not reproduced, 0 undetermined)",
     "judged at one point (0.5 px, 0.2: --best-fit-only), not across the fit's 95 % region"),
    (["--corner-noise-px", "1"], "predicted 2 (1 reproduced, 1 not reproduced, 0 undetermined)",
     "judged at one point (1 px, 0.2: a model given by --corner-noise-px / --operator-scale)"),
])
def test_the_printed_tally_is_judged_across_the_fits_region(extra, expected, rule, capsys, tmp_path, monkeypatch):
    """Issue 41: a verdict holds only where it holds at every point of the fit's 95 % region, in the CLI's
    rows, tally and JSON; a model the user gives is judged at that point and the tally says so."""
    from carmkin.reproduce import fit, verdict

    calls = []
    monkeypatch.setitem(verdict.EXPERIMENTS, "3.2", _region_dependent(calls))
    out_json = tmp_path / "v.json"
    assert main(["reproduce", "3.2", "--repeats", "2", "--json", str(out_json), *extra]) == 0
    out = capsys.readouterr().out
    tally = [line for line in out.splitlines() if line.startswith("predicted ")]
    assert len(tally) == 1 and tally[0].startswith(expected)
    assert rule in tally[0]
    data = json.loads(out_json.read_text())
    assert data["judged_at"]["rule"] in tally[0]
    if not extra:
        assert calls == [tuple(p) for p in fit.FIT_REGION]
        assert data["judged_at"]["points"] == [list(p) for p in fit.FIT_REGION]
        assert [r["verdict"] for r in data["verdict"]] == ["reproduced", "undetermined"]
        assert "across the fit's 95 % region: reproduced, reproduced, not reproduced" in data["verdict"][1]["criterion"]
    else:
        assert len(calls) == 1 and data["judged_at"]["points"] == [list(calls[0])]
