"""Findings of a newcomer's trial of the command line (issue 32, docs/cli.md): what a first session runs into
(a distance in m where mm is asked, a missing file, output piped into ``head``, numbers printed as numpy
arrays or as -0.000) gives one plain line or plain numbers. Each test states the finding it guards."""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest

import carmkin
from carmkin.cli import BROKEN_PIPE, main
from carmkin.commands._common import format_joints
from test_cli import assert_one_line_error, cli  # noqa: E402 (tests/commands is on sys.path)
from hang import HANG_GUARD_S

PLAIN = carmkin.load_preset("siremobile-iso-c3d")


@pytest.mark.parametrize("argv, option", [
    (["views", "plan", "--standard", "AP", "--distance-mm", "0.6"], "--distance-mm"),
    (["sweep", "plan", "--distance-mm", "0.6"], "--distance-mm"),
    (["panorama", "plan", "--length-mm", "400", "--object-distance-mm", "0.3"], "--object-distance-mm"),
])
def test_a_distance_in_m_is_refused_naming_the_slip(argv, option, capsys):
    """Finding: `views plan --distance-mm 0.6` searched 9 s and said "unreachable"; `panorama plan
    --object-distance-mm 0.3` failed on an internal principal point of -2e6 px. Both took 0.6 m for 0.6 mm."""
    code, out, err = cli(argv, capsys)
    assert code == 2 and not out
    assert_one_line_error(err, option, "given in m?", " m = ")


@pytest.mark.parametrize("argv, words", [
    (["ik", "--pose-file", "missing.json"], ("--pose-file", "missing.json: no such file")),
    (["ik", "--pose-file", "missing.txt"], ("--pose-file", "missing.txt: no such file")),
    (["view", "--to-pose", "missing.txt", "--html", "v.html"], ("--to-pose", "missing.txt: no such file")),
    (["dicom", "--read", "missing.dcm"], ("cannot read missing.dcm: no such file",)),
])
def test_a_missing_input_file_is_said_plainly(argv, words, tmp_path, capsys, monkeypatch):
    """Finding: "[Errno 2] No such file or directory: 'missing.json'" and "FileNotFoundError: [Errno 2] ..."."""
    monkeypatch.chdir(tmp_path)
    code, _, err = cli(argv, capsys)
    assert code == 2 and "Errno" not in err and "Error:" not in err
    assert_one_line_error(err, *words)


def test_dataset_info_of_a_missing_folder_says_it_is_missing(tmp_path, capsys):
    """Finding: `dataset info /nonexistent` said the folder "holds no dataset", as if it were there."""
    pytest.importorskip("pyarrow", reason="dataset info needs the datasets extra (pyarrow)")
    code, _, err = cli(["dataset", "info", tmp_path / "missing"], capsys)
    assert code == 2
    assert_one_line_error(err, "missing", "no such folder")


class _ClosedPipe:
    """A stdout whose reader has gone (`carmkin ... | head` after head exits)."""

    def write(self, text):
        raise BrokenPipeError(32, "Broken pipe")

    def flush(self):
        raise BrokenPipeError(32, "Broken pipe")


def test_output_into_a_closed_pipe_stops_quietly(capsys, monkeypatch):
    """Finding: `carmkin workspace --png t.png | head -3` printed "error: cannot access: Broken pipe", exit 2."""
    monkeypatch.setattr(sys, "stdout", _ClosedPipe())
    code = main(["ik", "--pose=193,406,342,67.5,-84.2,59.8"])
    monkeypatch.undo()
    assert code == BROKEN_PIPE == 141
    assert capsys.readouterr().err == ""


def test_view_refuses_bad_input_before_loading_the_viewer(tmp_path):
    """Finding: `carmkin view --preset nosuch.toml` took 2.5 s (meshcat and the viewer loaded) to say so."""
    code = ("import sys; from carmkin.cli import main; "
            "rc = main(['view', '--preset', 'nosuch.toml', '--html', 'v.html']); "
            "print(rc, 'meshcat' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=HANG_GUARD_S)
    assert done.stdout.split() == ["2", "False"], done.stdout + done.stderr


def test_ik_names_the_unit_of_each_excess(capsys):
    """Finding: `carmkin ik` printed "excess vertical_mm +205.6131, horizontal_mm -94.2646" (JSON keys as text)."""
    code, out, _ = cli(["ik", "--pose=193,406,342,67.5,-84.2,59.8"], capsys)
    line = next(line for line in out.splitlines() if "excess" in line)
    items = line.split("excess ", 1)[1].split(", ")
    assert all(re.fullmatch(r"[a-z_]+ [+-]\d+\.\d{4}( mm|°)", item) for item in items), line
    assert "_mm" not in line and "_deg" not in line


def test_joint_lists_never_print_minus_zero():
    """Finding: "table_translation=-0.000 mm" for a value of -1.7e-13 m."""
    q = np.array([-1.7e-13, 0.2, -3e-17, 0.1, -0.0, -4e-9])
    text = format_joints(PLAIN, q)
    assert "-0.000" not in text and "table_translation=+0.000 mm" in text and "orbital=+0.000°" in text
    assert "vertical=+200.000 mm" in text  # values that are not zero keep their digits
    assert format_joints(PLAIN, -q).count("-") == 2  # -200 mm and -100 mm, nothing else


def test_panorama_prints_plain_numbers_with_units(capsys):
    """Finding: "direction [ 1.0000e+00 -2.8328e-16  0.0000e+00]", "overlap 0" and "Δd0 ...: [-306.19  134.46 ...]"
    (numpy's array printing, a unitless overlap)."""
    code, out, _ = cli(["panorama", "plan", "--length-mm", "400", "--overlap", "0.1"], capsys)
    assert code == 0
    head = next(line for line in out.splitlines() if line.startswith("object plane"))
    assert re.search(r"direction \([+-]\d\.\d{4}, [+-]\d\.\d{4}, [+-]\d\.\d{4}\) \(unit vector", head), head
    assert "e-" not in head and "overlap 10%" in head
    moves = next(line for line in out.splitlines() if line.startswith("table translations"))
    values = moves.split(": ", 1)[1]
    assert re.fullmatch(r"\(([+-]\d+\.\d\d)(, [+-]\d+\.\d\d)*\)", values), moves


def test_dicom_prints_no_minus_zero_and_a_space_before_mm(capsys):
    """Finding: "TableTopVerticalPosition: -0.000 mm", "table X/Y/Z to isocentre -100.000, 200.000, -0.000 mm"."""
    code, out, _ = cli(["dicom"], capsys)
    assert code == 0 and "-0.000" not in out and "TableTopVerticalPosition: 0.000 mm" in out


def test_the_table_study_names_its_time_column():
    """Finding: `workspace --table-dofs compare` headed its time column "s"."""
    from carmkin.studies.table_workspace import ModelReach, table_rows

    rows = table_rows([ModelReach("none", np.array([True, False]), 0.25)])
    assert rows[0].split()[-2:] == ["time", "(s)"] and rows[1].split()[-2:] == ["50.0%", "0.2"]


@pytest.mark.parametrize("argv", [["views", "plan", "--standard", "AP", "--patient-position", "XYZ"],
                                  ["dicom", "--patient-position", "xyz"], ["project", "--patient-position", "up"]])
def test_a_bad_patient_position_names_the_option_and_the_codes(argv, capsys):
    """Finding: `views plan --patient-position XYZ` said "position must be one of ..." without the option."""
    code, out, err = cli(argv, capsys)
    assert code == 2 and not out
    assert_one_line_error(err, "--patient-position", "HFS, HFP, HFDR, HFDL, FFS, FFP, FFDR, FFDL")


def test_a_zero_angle_is_neither_rao_nor_cau(capsys):
    """Finding: `dicom --patient-position ffs` printed "Primary Angle -0.0000° (RAO), Secondary Angle -0.0000° (CAU)"
    for a frontal view (rounding noise of -1e-15° chose the side)."""
    for position in ("hfs", "ffs"):
        code, out, _ = cli(["dicom", "--patient-position", position], capsys)
        assert code == 0 and "Primary Angle 0.0000° (LAO), Secondary Angle 0.0000° (CRA)" in out, out


@pytest.mark.parametrize("argv", [["views", "plan", "--standard", "AP"], ["views", "map"], ["dicom"], ["project"],
                                  ["ik", "--pose=193,406,342,67.5,-84.2,59.8"], ["singularity"]])
def test_the_json_of_a_plan_names_its_preset(argv, capsys):
    """Finding: `views plan --json -` and `views map --json` left out the preset that `ik`, `dicom`, `project`...
    name, so a saved plan could not say which C-arm it is for."""
    import json

    code, out, _ = cli([*argv, "--json", "-"], capsys)
    assert code in (0, 1)
    assert json.loads(out)["preset"] == "siremobile-iso-c3d"
