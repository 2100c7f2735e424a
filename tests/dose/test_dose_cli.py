"""`carmkin dose map`: the report's PSD printed and written, refused events named, one-line errors."""

import json

import numpy as np
import pytest

pytest.importorskip("pydicom", reason="carmkin dose map reads reports with pydicom (extra dose)")
import carmkin  # noqa: E402
from carmkin import dose  # noqa: E402
from carmkin.cli import main  # noqa: E402
from test_rdsr import event_items, write  # noqa: E402


def test_dose_map_prints_and_writes_the_psd_of_the_report(tmp_path, capsys):
    path = write(tmp_path / "r.dcm", [event_items(**{"Positioner Primary Angle": (0.0, "deg"),
                                                     "Positioner Secondary Angle": (0.0, "deg")})] * 2)
    out_json, out_png = tmp_path / "d.json", tmp_path / "d.png"
    assert main(["dose", "map", "--rdsr", str(path), "--json", str(out_json), "--png", str(out_png)]) == 0
    text = capsys.readouterr().out
    data = json.loads(out_json.read_text())
    system = carmkin.load_preset("angio-floor")
    expected = dose.skin_dose(system, dose.read_rdsr(path, system), dose.plane(system))
    assert data["psd_mgy"] == pytest.approx(expected.psd_gy * 1e3, rel=1e-12) and data["max_overlap"] == 2
    assert f"PSD {expected.psd_gy * 1e3:.4g} mGy" in text and out_png.stat().st_size > 1000
    assert np.allclose(data["psd_point_mm"], expected.psd_point * 1e3, atol=1e-3)


def test_dose_map_names_a_refused_event_and_exits_2(tmp_path, capsys):
    path = write(tmp_path / "r.dcm", [event_items(), event_items(**{"Dose (RP)": None})])
    assert main(["dose", "map", "--rdsr", str(path)]) == 2
    err = capsys.readouterr().err
    assert "carmkin dose map: error: RDSR event #2 Fluoroscopy: no usable Dose (RP)" in err and "Traceback" not in err
    assert main(["dose", "map", "--rdsr", str(path), "--skip-incomplete", "--phantom", "cylinder"]) == 0
    assert "refused #2: RDSR event #2" in capsys.readouterr().out


@pytest.mark.parametrize("argv, words", [
    (["--rdsr", "/nonexistent/r.dcm"], "--rdsr /nonexistent/r.dcm: no such file"),
    (["--rdsr", "R", "--preset", "siremobile-iso-c3d"], "no joint 'table_lateral'"),
    (["--rdsr", "R", "--spacing-mm", "0"], "--spacing-mm"),
])
def test_dose_map_bad_input_is_one_line(argv, words, tmp_path, capsys):
    path = write(tmp_path / "r.dcm", [event_items()])
    try:
        code = main(["dose", "map", *[str(path) if a == "R" else a for a in argv]])
    except SystemExit as exc:  # argparse's usage errors
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1


def test_dose_map_on_the_parametric_patient_takes_the_patient_flags_in_mm(tmp_path, capsys):
    from carmkin.patient import ParametricPatient

    path = write(tmp_path / "r.dcm", [event_items(**{"Positioner Primary Angle": (0.0, "deg"),
                                                     "Positioner Secondary Angle": (0.0, "deg")})])
    out_json = tmp_path / "d.json"
    argv = ["dose", "map", "--rdsr", str(path), "--phantom", "patient", "--patient-height-mm", "1800",
            "--patient-mass-kg", "80", "--patient-chest-z-mm", "-100", "--spacing-mm", "20", "--json", str(out_json)]
    assert main(argv) == 0
    system = carmkin.load_preset("angio-floor")
    body = ParametricPatient.on_table(system, height=1.8, mass=80.0, chest_z=-0.1)
    expected = dose.skin_dose(system, dose.read_rdsr(path, system), body, spacing=0.02)
    assert json.loads(out_json.read_text())["psd_mgy"] == pytest.approx(expected.psd_gy * 1e3, rel=1e-12)
    capsys.readouterr()
    for extra, words in ((["--patient", "none"], "--phantom patient needs --patient parametric"),
                         (["--patient-position", "FFS"], "--patient-position FFS: a report's angles are read for")):
        assert main(argv[:-2] + extra) == 2
        err = capsys.readouterr().err
        assert words in err and len(err.strip().splitlines()) == 1
    with pytest.raises(SystemExit) as info:  # the old flag in metres is gone: one grammar, mm
        main(["dose", "map", "--rdsr", str(path), "--height-m", "1.8"])
    assert info.value.code == 2
