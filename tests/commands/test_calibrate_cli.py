"""`carmkin calibrate` (issue 42): the calibration from files, as a user has them — a phantom's beads (table
frame, mm) and per view the joint readings (mm, deg) and the detected beads' pixels. The estimates agree with
the simulated device within their σ, a view off by 20 px is named, JSON and CSV inputs give the same fit, and
every file the command cannot use is refused in one line naming it (exit 2), before any fit."""

import json

import numpy as np
import pytest

import carmkin
from carmkin import calibration as cal
from carmkin.calibration import files
from carmkin.calibration.reprojection import model_projections, pixels
from carmkin.cli import main

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")
TRUTH = cal.adjust(SYSTEM, cal.EXAMPLE_PERTURBATION)
VIEWS, NOISE_PX, OUTLIER_PX, OUTLIER = 30, 0.1, 20.0, 5
#: The estimates' bound: every fitted parameter within this many of its reported σ of the truth.
SIGMAS = 4.0


def helix(system) -> np.ndarray:
    """A 60-bead helix phantom (radius 50 mm, 150 mm long, 3 turns) fixed on the table around the isocentre of
    the joints' mid-range configuration (table frame, m)."""
    mid = (system.lower + system.upper) / 2
    T = system.fk(mid)
    centre = T[:3, 3] + system.carm.source_to_orbital_axis * T[:3, 2]
    t = np.linspace(0.0, 1.0, 60)
    a = 2 * np.pi * 3 * t
    return centre + np.column_stack((0.05 * np.cos(a), 0.05 * np.sin(a), 0.15 * (t - 0.5)))


def simulate(tmp_path, outlier=None, drop=3):
    """The phantom and views files of the simulated device TRUTH: beads projected at the readings, 0.1 px noise;
    view ``outlier``'s pixels moved by 20 px along u; view 0 missing ``drop`` beads."""
    X = helix(SYSTEM)
    Q = cal.spread_readings(SYSTEM, VIEWS, seed=1)
    x = pixels(model_projections(TRUTH, Q), np.broadcast_to(X, (VIEWS, *X.shape)))
    x = x + np.random.default_rng(1).normal(0.0, NOISE_PX, x.shape)
    if outlier is not None:
        x[outlier, :, 0] += OUTLIER_PX
    beads = [f"b{i:02d}" for i in range(len(X))]
    names = [f"view-{i:02d}" for i in range(VIEWS)]
    detected = [{b: tuple(p) for b, p in zip(beads, xi)} for xi in x]
    for b in beads[:drop]:
        del detected[0][b]
    phantom = files.write_phantom(tmp_path / "phantom.csv", beads, X)
    views = files.write_views(tmp_path / "views.csv", SYSTEM, names, Q, detected)
    return phantom, views, Q, X, detected, names


def cli(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_estimates_agree_with_the_device_and_a_20_px_view_is_named(tmp_path, capsys):
    phantom, views, *_ = simulate(tmp_path, outlier=OUTLIER)
    code, out, err = cli(["calibrate", views, "--phantom", phantom, "--json", tmp_path / "r.json"], capsys)
    assert code == 0, err
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["outlier_views"] == [f"view-{OUTLIER:02d}"]
    assert f"outlier views: view-{OUTLIER:02d} (left out of the fit)" in out
    assert f"views view-{OUTLIER:02d} (" in out  # the caution names the view, not its index
    truth = dict(zip(cal.parameters(SYSTEM) and [p.name for p in cal.parameters(SYSTEM)],
                     cal.values(TRUTH, cal.parameters(SYSTEM))))
    assert set(report["fitted"]) == set(truth) - {"length_offset", "gamma3", "D2", "D3"}
    for name, fit in report["fitted"].items():
        assert abs(fit["value"] - truth[name]) <= SIGMAS * fit["sigma"], (name, fit, truth[name])
        assert f"{name} " in out and "1σ" in out
    assert set(report["held"]) == {"length_offset", "gamma3", "D2", "D3"}
    assert report["residual_px"][f"view-{OUTLIER:02d}"] > 10 > max(
        r for v, r in report["residual_px"].items() if v != f"view-{OUTLIER:02d}")


def test_without_the_outlier_test_nothing_is_flagged_and_json_on_stdout(tmp_path, capsys):
    phantom, views, *_ = simulate(tmp_path)
    code, out, err = cli(["calibrate", views, "--phantom", phantom, "--json"], capsys)
    assert code == 0, err
    report = json.loads(out)
    assert report["outlier_views"] == [] and report["converged"]
    assert report["views"] == [f"view-{i:02d}" for i in range(VIEWS)]


def test_json_files_give_the_csv_fit_and_the_preset_is_written(tmp_path, capsys):
    phantom, views, Q, X, detected, names = simulate(tmp_path)
    columns = files.reading_columns(SYSTEM)
    scale = np.array([1e3 if p else 180 / np.pi for p in SYSTEM.prismatic])
    (tmp_path / "views.json").write_text(json.dumps({"views": [
        {"view": n, "q": dict(zip(columns, (q * scale).tolist())), "beads_px": {b: list(uv) for b, uv in d.items()}}
        for n, q, d in zip(names, Q, detected)]}))
    (tmp_path / "phantom.json").write_text(json.dumps({"beads_mm": {f"b{i:02d}": (p * 1e3).tolist()
                                                                    for i, p in enumerate(X)}}))
    code, out, err = cli(["calibrate", tmp_path / "views.json", "--phantom", tmp_path / "phantom.json", "--json",
                          tmp_path / "a.json", "--save-preset", tmp_path / "cal.toml"], capsys)
    assert code == 0, err
    code, _, err = cli(["calibrate", views, "--phantom", phantom, "--json", tmp_path / "b.json"], capsys)
    assert code == 0, err
    a, b = (json.loads((tmp_path / f).read_text())["fitted"] for f in ("a.json", "b.json"))
    for name in a:
        assert a[name]["value"] == pytest.approx(b[name]["value"], abs=1e-6 * max(1.0, abs(b[name]["value"])))
    calibrated = carmkin.load_preset(tmp_path / "cal.toml")
    assert calibrated.carm.source_to_detector * 1e3 == pytest.approx(a["source_to_detector"]["value"], abs=1e-6)


BAD_PHANTOM = {
    "no-header.csv": ("b0,1,2,3\n", "the header must name bead, x_mm, y_mm, z_mm"),
    "nan.csv": ("bead,x_mm,y_mm,z_mm\n" + "".join(f"b{i},{i},0,0\n" for i in range(5)) + "b5,nan,0,0\n",
                "line 7: x_mm must be a finite number (mm), got 'nan'"),
    "twice.csv": ("bead,x_mm,y_mm,z_mm\n" + "".join(f"b{i % 5},{i},0,0\n" for i in range(7)), "named twice"),
    "few.csv": ("bead,x_mm,y_mm,z_mm\n" + "".join(f"b{i},{i},0,0\n" for i in range(4)), "4 beads, need at least 6"),
    "bad.json": ("{not json", "not valid JSON"),
    "other.json": ('{"beads": {}}', "expected an object with 'beads_mm'"),
    "phantom.txt": ("", "must end in .csv or .json"),
}


@pytest.mark.parametrize("name", sorted(BAD_PHANTOM))
def test_a_phantom_file_it_cannot_use_is_one_line_exit_2(name, tmp_path, capsys):
    _, views, *_ = simulate(tmp_path)
    text, expected = BAD_PHANTOM[name]
    (tmp_path / name).write_text(text)
    code, out, err = cli(["calibrate", views, "--phantom", tmp_path / name], capsys)
    assert code == 2 and not out and len(err.strip().splitlines()) == 1, err
    assert err.startswith("carmkin calibrate: error: phantom") and str(tmp_path / name) in err and expected in err


def _edit_views(path, line, column, value):
    rows = path.read_text().splitlines()
    header = rows[0].split(",")
    cells = rows[line - 1].split(",")
    cells[header.index(column)] = value
    rows[line - 1] = ",".join(cells)
    path.write_text("\n".join(rows) + "\n")


@pytest.mark.parametrize("line, column, value, expected", [
    (5, "u_px", "abc", "line 5: u_px must be a number (px), got 'abc'"),
    (5, "bead", "nope", "line 5: bead 'nope' is not in the phantom"),
    (5, "bead", "b04", "line 6: bead 'b04' given twice for view 'view-00'"),  # the second b04
    (5, "vertical_mm", "7", "line 5: view 'view-00' has other joint readings than on its first row"),
    (2, "wigwag_deg", "95", "view 'view-00': wigwag_deg = 95 is outside wigwag's range"),
])
def test_a_views_file_it_cannot_use_names_the_line_or_view(line, column, value, expected, tmp_path, capsys):
    phantom, views, *_ = simulate(tmp_path, drop=0)
    if column == "wigwag_deg":  # every row of the view, so that only the range is wrong
        for k in range(2, 2 + 60):
            _edit_views(views, k, column, value)
    else:
        _edit_views(views, line, column, value)
    code, out, err = cli(["calibrate", views, "--phantom", phantom], capsys)
    assert code == 2 and not out and len(err.strip().splitlines()) == 1, err
    assert f"views '{views}'" in err and expected in err


def test_a_view_with_too_few_beads_and_a_missing_column_are_refused(tmp_path, capsys):
    phantom, views, *_ = simulate(tmp_path, drop=56)
    code, _, err = cli(["calibrate", views, "--phantom", phantom], capsys)
    assert code == 2 and "view 'view-00': 4 beads detected, need at least 6" in err
    views.write_text(views.read_text().replace("orbital_deg", "orbital"))
    code, _, err = cli(["calibrate", views, "--phantom", phantom], capsys)
    assert code == 2 and "missing orbital_deg" in err
    code, _, err = cli(["calibrate", tmp_path / "none.csv", "--phantom", phantom], capsys)
    assert code == 2 and "none.csv" in err and "no such file" in err


def test_the_preset_path_is_checked_before_any_work(tmp_path, capsys, monkeypatch):
    phantom, views, *_ = simulate(tmp_path)
    monkeypatch.setattr(files, "calibrate", lambda *a, **k: pytest.fail("work began"))
    code, _, err = cli(["calibrate", views, "--phantom", phantom, "--save-preset", tmp_path / "c.txt"], capsys)
    assert code == 2 and "--save-preset" in err and ".toml" in err


def test_readings_and_a_phantom_in_metres_are_refused_naming_the_slip(tmp_path, capsys):
    phantom, views, Q, X, detected, names = simulate(tmp_path)
    metres = files.write_phantom(tmp_path / "phantom-m.csv", [f"b{i:02d}" for i in range(len(X))], X / 1e3)
    code, _, err = cli(["calibrate", views, "--phantom", metres], capsys)
    assert code == 2 and "--phantom" in err and "given in m?" in err
    radians = Q.copy()
    radians[:, ~np.asarray(SYSTEM.prismatic)] *= np.pi / 180  # written as if m and rad were mm and deg
    radians[:, np.asarray(SYSTEM.prismatic)] /= 1e3
    files.write_views(tmp_path / "views-m.csv", SYSTEM, names, radians, detected)
    code, _, err = cli(["calibrate", tmp_path / "views-m.csv", "--phantom", phantom], capsys)
    assert code == 2 and "given in m?" in err and "radians" in err and "views-m.csv" in err
