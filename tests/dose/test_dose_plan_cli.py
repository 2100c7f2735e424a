"""`carmkin dose plan`: the predicted map of planned views printed and written, the dose-aware runs, one-line
errors."""

import json

import pytest

import carmkin
from carmkin import dose
from carmkin.cli import main


def test_dose_plan_predicts_the_map_and_the_dose_aware_runs(tmp_path, capsys):
    from carmkin.patient import ParametricPatient
    from carmkin.views import View, plan_view

    out_json, out_png = tmp_path / "p.json", tmp_path / "p.png"
    argv = ["dose", "plan", "--view-deg", "30,20", "--view-deg", "0,0", "--target-mm", "0,30,0", "--runs", "3",
            "--frames", "5", "--field-mm", "150,150", "--spacing-mm", "20", "--patient-height-mm", "1700",
            "--json", str(out_json)]
    assert main(argv + ["--dose-aware-deg", "10", "--png", str(out_png)]) == 0
    text = capsys.readouterr().out
    data = json.loads(out_json.read_text())
    system = carmkin.load_preset("angio-floor")
    patient = ParametricPatient.on_table(system, height=1.7)
    tech = dose.Technique(frames=5, field_mm=(150.0, 150.0))
    views = [View.from_angles(p, s, [0.0, 0.03, 0.0], position=patient) for p, s in ((30, 20), (0, 0))]
    plans = [plan_view(system, v, patient) for v in views for _ in range(3)]
    expected = dose.plan_dose(system, plans, patient, tech, spacing=0.02)
    assert data["psd_mgy"] == pytest.approx(expected.map.psd_gy * 1e3, rel=1e-12)
    assert f"PSD {expected.map.psd_gy * 1e3:.4g} mGy" in text and len(data["runs"]) == 6
    aware = data["dose_aware"]
    assert aware["psd_requested_mgy"] == pytest.approx(data["psd_mgy"], rel=1e-12)
    assert aware["psd_mgy"] <= aware["psd_requested_mgy"] and all(r["angle_deg"] <= 10 + 1e-9 for r in aware["runs"])
    assert all(r["motion_success"] for r in aware["runs"]) and out_png.stat().st_size > 1000
    assert "dose-aware within 10 deg: PSD" in text


@pytest.mark.parametrize("extra, words", [
    (["--view-deg", "30"], "--view-deg needs 2 comma-separated numbers"),
    (["--view-deg", "0,0", "--patient", "none"], "--patient none: a plan's kerma and skin need the parametric patient"),
    (["--view-deg", "0,0", "--field-mm", "0,100"], "field_mm must be two positive sides"),
    (["--view-deg", "0,0", "--cu-mm", "0.25"], "not in the HVL table"),
])
def test_dose_plan_bad_input_is_one_line(extra, words, capsys):
    assert main(["dose", "plan", *extra]) == 2
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
