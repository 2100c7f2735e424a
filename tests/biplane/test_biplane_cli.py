"""`carmkin biplane check|plan`: mm and degrees in, one line per usage error (exit 2), exit 1 when the pair cannot be
planned."""

import json
import re

import pytest

from carmkin.cli import main


def test_check_prints_the_rest_clearances(capsys):
    assert main(["biplane", "check"]) == 0
    out = capsys.readouterr().out
    assert "frontal angio-floor, lateral angio-lateral, 15 joints" in out and "lateral.orbital=+0.000°" in out
    assert "between the planes 146.2 mm" in out and "planes 0.000 mm apart" in out
    assert main(["biplane", "check", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["clearance_mm"]["planes"] == pytest.approx(146.2, abs=0.1) and data["rest"]["lateral.angular_deg"] == 0


def test_plan_prints_both_planes_and_writes_the_page(tmp_path, capsys):
    page = tmp_path / "biplane.html"
    assert main(["biplane", "plan", "--standard", "rao-35-caudal-35", "--html", str(page)]) == 0
    out = capsys.readouterr().out
    assert "frontal view: primary -35.0°, secondary -35.0°" in out and "lateral view: primary +55.0°" in out
    assert "frontal.angular=+35.000°" in out and "beams 90.00° apart" in out
    assert page.stat().st_size > 100_000


def test_plan_json_and_an_unplannable_pair(capsys):
    assert main(["biplane", "plan", "--primary-deg", "-35", "--secondary-deg", "-35", "--lateral-deg", "90",
                 "--patient", "none", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["success"] and data["angle_deg"] == pytest.approx(90.0) and data["clearance_mm"] > 10
    assert main(["biplane", "plan", "--standard", "pa", "--json"]) == 1  # the frontal tube meets the lateral's arm
    data = json.loads(capsys.readouterr().out)
    assert not data["success"] and data["failure"] == "LATERAL_UNREACHABLE" and "frontal.xray_source" in data["reason"]


@pytest.mark.parametrize("argv, message", [
    (["plan"], "--primary-deg and --secondary-deg \\(or --standard NAME\\) are required"),
    (["plan", "--standard", "ap", "--primary-deg", "3"], "give either a standard view or --primary-deg"),
    (["plan", "--standard", "ap", "--lateral-deg", "90", "--lateral-standard", "pa"], "--lateral-standard: give either"),
    (["check", "--preset", "angio-floor"], "--preset: .*angio-floor.toml: not a biplane preset"),
    (["check", "--preset", "nowhere.toml"], "--preset nowhere.toml: no such preset file"),
])
def test_usage_errors_are_one_line(argv, message, capsys):
    assert main(["biplane", *argv]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and re.search(message, err)


def test_an_angle_out_of_range_is_refused_while_parsing(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["biplane", "plan", "--standard", "ap", "--lateral-deg", "400"])
    assert exit_.value.code == 2 and "--lateral-deg" in capsys.readouterr().err
