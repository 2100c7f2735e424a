"""`carmkin views plan|map`: degrees and mm in, one line per usage error (exit 2), exit 1 when unreachable."""

import json
import subprocess
import sys

import pytest

from carmkin.cli import main
from hang import HANG_GUARD_S


def run(*args):
    return subprocess.run([sys.executable, "-m", "carmkin.cli", "views", *args], capture_output=True, text=True,
                          timeout=HANG_GUARD_S)


def test_plan_prints_joints_and_clearance(capsys):
    assert main(["views", "plan", "--primary-deg", "30", "--secondary-deg", "20"]) == 0
    out = capsys.readouterr().out
    assert "30.0° LAO, 20.0° CRA" in out and "clearance" in out and "wigwag=" in out


def test_plan_from_a_configuration_prints_how_long_the_moves_take(capsys):
    assert main(["views", "plan", "--primary-deg", "20", "--secondary-deg", "10", "--q-mm-deg",
                 "0,200,0,100,0,20", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["duration_s"] > 0
    assert main(["views", "plan", "--primary-deg", "20", "--secondary-deg", "10", "--q-mm-deg", "0,200,0,100,0,20"]) == 0
    assert f"moves take {data['duration_s']:.1f} s (joint by joint" in capsys.readouterr().out


def test_plan_json_and_standard_view(capsys):
    assert main(["views", "plan", "--standard", "pelvis-inlet", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["success"] and data["angles_deg"][1] == pytest.approx(40.0)


def test_plan_with_a_rotation_reads_it_back(capsys):
    assert main(["views", "plan", "--primary-deg", "30", "--secondary-deg", "20", "--rotation-deg", "105",
                 "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["success"] and data["rotation_deg"] == pytest.approx(105.0, abs=1e-9)
    # The C-arm's roll is its wigwag's ±10°: 30° is out of reach, and the same beam with its own roll is offered.
    assert main(["views", "plan", "--primary-deg", "30", "--secondary-deg", "20", "--rotation-deg", "30"]) == 1
    out = capsys.readouterr().out
    assert "no wigwag within its range gives this rotation" in out and "0.00° away" in out


def test_plan_a_segment(capsys):
    assert main(["views", "plan", "--segment-mm", "0,50,-20,30,0,50", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["success"] and data["clearance_mm"] > 20.0


def test_unreachable_exits_1_with_the_nearest_view(capsys):
    assert main(["views", "plan", "--primary-deg", "-70", "--secondary-deg", "35"]) == 1
    out = capsys.readouterr().out
    assert "unreachable" in out and "nearest reachable view" in out


@pytest.mark.parametrize("args", [["plan", "--primary-deg", "abc", "--secondary-deg", "0"],
                                  ["plan", "--primary-deg", "10"],
                                  ["plan", "--standard", "nope"],
                                  ["plan", "--standard", "ap", "--primary-deg", "3"],
                                  ["plan", "--primary-deg", "0", "--secondary-deg", "0", "--patient-position", "XX"],
                                  ["plan", "--primary-deg", "0", "--secondary-deg", "0", "--rotation-deg", "300"],
                                  ["map", "--workers", "0"],
                                  ["plan", "--segment-mm", "1,2"],
                                  ["plan", "--segment-mm", "0,0,0,0,0,1", "--rotation-deg", "90"],
                                  ["plan", "--segment-mm", "0,0,0,0,0,0"],
                                  ["plan", "--segment-mm", "0,0,0,0,0,1", "--primary-deg", "3"],
                                  ["map", "--primary-range-deg", "10,-10"]])
def test_usage_errors_are_one_line(args):
    result = run(*args)
    assert result.returncode == 2, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr


def test_map_writes_json_plot_and_page(tmp_path, capsys):
    paths = [tmp_path / "m.json", tmp_path / "m.png", tmp_path / "m.html"]
    assert main(["views", "map", "--step-deg", "30", "--json", str(paths[0]), "--png", str(paths[1]),
                 "--html", str(paths[2])]) == 0
    out = capsys.readouterr().out
    assert "views reachable" in out
    cells = json.loads(paths[0].read_text())["cells"]
    assert len(cells) == 7 * 4 and all(p.exists() and p.stat().st_size for p in paths)


def test_map_compare_prints_three_maps_and_plots(tmp_path, capsys):
    plot = tmp_path / "compare.png"
    assert main(["views", "map", "--compare", "--step-deg", "30", "--png", str(plot)]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if "views reachable" in line]
    assert [line.split(":")[0] for line in lines] == ["C-arm alone (5 DOF)", "+ table translation (6 DOF)",
                                                       "+ motorized table (11 DOF, 11 table poses)"]
    assert plot.stat().st_size
    assert run("map", "--compare", "--html", str(tmp_path / "x.html")).returncode == 2


# --- the one default margin (issue "The first hour, again": views defaulted to 20 mm, everything else to 10) -----
@pytest.mark.parametrize("action", [["plan"], ["map"], ["optimal", "--centreline", "c.csv"]])
def test_views_default_to_the_one_default_margin(action):
    import carmkin
    from carmkin.cli import build_parser

    args = build_parser().parse_args(["views", *action])
    assert args.margin_mm == pytest.approx(carmkin.DEFAULT_MARGIN * 1000.0)


@pytest.mark.parametrize("command", [["sweep", "plan"], ["biplane", "plan"]])
def test_the_other_planners_default_to_the_same_margin(command):
    import carmkin
    from carmkin.cli import build_parser

    args = build_parser().parse_args(command)
    assert args.margin_mm == pytest.approx(carmkin.DEFAULT_MARGIN * 1000.0)


def test_the_map_says_which_margin_its_text_and_json_used(tmp_path, capsys):
    out_json = tmp_path / "m.json"
    assert main(["views", "map", "--step-deg", "45", "--patient", "none", "--json", str(out_json)]) == 0
    assert "margin 10 mm" in capsys.readouterr().out.splitlines()[0]
    data = json.loads(out_json.read_text())
    assert data["margin_mm"] == 10.0 and data["patient"] == {"model": "none", "position": "HFS"}
    assert main(["views", "map", "--step-deg", "45", "--patient", "none", "--margin-mm", "25", "--json", "-"]) == 0
    assert json.loads(capsys.readouterr().out)["margin_mm"] == 25.0


def test_plan_json_names_target_patient_and_margin(capsys):
    assert main(["views", "plan", "--primary-deg", "30", "--secondary-deg", "20", "--target-mm", "0,-100,0",
                 "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["target_mm"] == pytest.approx([0.0, -100.0, 0.0])
    assert data["margin_mm"] == 10.0
    assert data["patient"] == {"model": "parametric", "position": "HFS", "height_mm": pytest.approx(1750.0),
                               "mass_kg": 75.0}


def test_optimal_help_names_the_centreline_midpoint_as_the_target_default(capsys):
    with pytest.raises(SystemExit):
        main(["views", "optimal", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "default the centreline's midpoint" in help_text and "default 0,0,0" not in help_text
