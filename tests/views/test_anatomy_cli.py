"""`carmkin views optimal`: the table, the JSON answer, the figure, and usage errors (exit 2, no traceback)."""

from __future__ import annotations

import json

import numpy as np

from carmkin.cli import main
from carmkin.views.anatomy import synthetic_tree

HEART = np.array([0.02, 0.05, -0.02])


def _write_tree(folder, seed=1):
    paths = []
    for k, c in enumerate(synthetic_tree(HEART, seed)):
        path = folder / f"vessel{k}.csv"
        np.savetxt(path, c.points * 1000, delimiter=",", header="x_mm,y_mm,z_mm", comments="")
        paths.append(str(path))
    return paths


def test_optimal_prints_the_table_and_writes_the_figure(tmp_path, capsys):
    paths = _write_tree(tmp_path)
    png = tmp_path / "map.png"
    code = main(["views", "optimal", "--centreline", paths[0], "--others", *paths[1:], "--step-deg", "15",
                 "--png", str(png)])
    out = capsys.readouterr().out
    assert code == 0 and png.stat().st_size > 0
    assert "best reachable" in out and "optimal" in out and "foreshort." in out


def test_optimal_json_to_stdout_matches_the_library(tmp_path, capsys):
    from carmkin import load_preset
    from carmkin.patient import ParametricPatient
    from carmkin.views import optimal_view_map

    paths = _write_tree(tmp_path)
    assert main(["views", "optimal", "--centreline", paths[0], "--others", *paths[1:], "--step-deg", "15",
                 "--json", "-"]) == 0
    answer = json.loads(capsys.readouterr().out)
    system = load_preset("siremobile-iso-c3d")
    tree = synthetic_tree(HEART, 1)
    grid_p, grid_s = np.arange(-90, 90 + 1e-9, 15), np.arange(-45, 45 + 1e-9, 15)
    m = optimal_view_map(system, np.round(tree[0].points * 1000, 18) / 1000, grid_p, grid_s,
                         ParametricPatient.on_table(system), [c.points for c in tree[1:]])
    assert answer["best_reachable"]["primary_deg"] == m.best_reachable[0]
    assert answer["best_reachable"]["secondary_deg"] == m.best_reachable[1]
    assert abs(answer["best_reachable"]["score"] - m.score[m.cell(m.best_reachable)]) < 1e-9


def test_bad_files_are_usage_errors(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("1,2\n3,4\n")
    assert main(["views", "optimal", "--centreline", str(bad)]) == 2
    assert main(["views", "optimal", "--centreline", str(tmp_path / "missing.csv")]) == 2
    metres = tmp_path / "metres.csv"
    metres.write_text("0.01,0.05,0\n0.02,0.05,0.01\n")  # metres given where mm are expected
    assert main(["views", "optimal", "--centreline", str(metres)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "--centreline" in err and "long" in err
