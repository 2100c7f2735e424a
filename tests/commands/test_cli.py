"""The `carmkin` command line: every command on both presets (runs, or refuses in one line), the shared
joint/pose parser and printer, validated options, output paths, exit codes, never a traceback."""

from __future__ import annotations

import contextlib
import io
import json
import math
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import carmkin
import strategies
from carmkin.cli import main
from carmkin.commands import _common
from carmkin.commands._common import (
    UsageError,
    format_joints,
    joints_json,
    parse_joints,
    pose_from_mm_deg,
    read_pose,
)
from carmkin.errors import InvalidConfigurationError, InvalidPoseError
from hang import HANG_GUARD_S

PLAIN = carmkin.load_preset("siremobile-iso-c3d")
MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
PRESETS = {"plain": PLAIN, "motorized": MOTORIZED}
MOTORIZED_JOINTS = ("table_translation", "table_tilt", "table_trendelenburg", "table_lateral", "table_height",
                    "table_rotation", "vertical", "wigwag", "horizontal", "angular", "orbital")


def cli(argv, capsys) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of ``carmkin argv`` run in this process (argparse exits included)."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def cli_captured(argv) -> tuple[int, str, str]:
    """:func:`cli` without pytest's capsys (for hypothesis tests, whose examples share one test call)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:
            code = exc.code
    return code, out.getvalue(), err.getvalue()


def assert_one_line_error(err: str, *words: str) -> None:
    """stderr is exactly one line, no traceback, naming every word given."""
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    for word in words:
        assert word in lines[0], (word, lines[0])


def mid(system) -> np.ndarray:
    return (system.lower + system.upper) / 2


def cli_values(system, q) -> str:
    """q (m, rad) as the command line writes it: mm for prismatic, degrees for revolute joints."""
    return ",".join(repr(float(v * 1000.0 if p else math.degrees(v))) for v, p in zip(q, system.prismatic))


@st.composite
def in_range(draw, system) -> np.ndarray:
    """A configuration of ``system`` inside its ranges, limits included (any nq)."""
    return np.array([draw(st.floats(r.lower, r.upper, allow_nan=False)) for r in system.joint_ranges])


# --- every command on both presets ------------------------------------------------------------------------
@pytest.mark.parametrize("name", PRESETS)
def test_view_writes_a_page_on_both_presets(name, tmp_path, capsys):
    system = PRESETS[name]
    out = tmp_path / "v.html"
    code, text, err = cli(["view", "--preset", system.name, f"--q-mm-deg={cli_values(system, mid(system))}",
                           f"--to-q-mm-deg={cli_values(system, system.lower)}", "--frames", "3", "--html", out], capsys)
    assert code == 0, err
    assert out.stat().st_size > 100_000 and "closest to table: " in text


@pytest.mark.parametrize("name", PRESETS)
def test_urdf_verify_workspace_panorama_run_on_both_presets(name, tmp_path, capsys):
    system = PRESETS[name]
    code, _, err = cli(["urdf", "--preset", system.name, "-o", tmp_path / "c.urdf"], capsys)
    assert code == 0 and (tmp_path / "c.urdf").read_text().startswith("<?xml"), err
    code, out, err = cli(["verify", "--preset", system.name, "--samples", "20"], capsys)
    assert code == 0 and "PASS" in out, err
    code, out, err = cli(["workspace", "--preset", system.name, "--translations-mm", "0"], capsys)
    assert code == 0 and "reachable within all ranges" in out, err
    code, out, err = cli(["panorama", "shot", "--preset", system.name, "--principal-point", "400,300"], capsys)
    assert code in (0, 1) and "joints:" in out, err
    assert all(f"{n}=" in out for n in system.joint_names)  # the joints printed under their own names


def test_ik_and_singularity_run_on_the_plain_preset(capsys):
    code, out, err = cli(["ik", f"--pose={cli_pose(PLAIN, mid(PLAIN))}"], capsys)
    assert code == 0 and "§4.4.3" in out and "chosen: branch" in out, err
    code, out, err = cli(["singularity", f"--q-mm-deg={cli_values(PLAIN, mid(PLAIN))}"], capsys)
    assert code == 0 and "rank" in out, err


@pytest.mark.parametrize("argv, alternative", [
    (["ik", "--pose=0,0,500,0,0,0"], "carmkin.qp_ik.solve"),
    (["singularity"], "carmkin.singularity.measures"),
    (["singularity", "--check", "5"], "carmkin.singularity.measures"),
])
def test_closed_form_commands_refuse_the_motorized_preset_in_one_line(argv, alternative, capsys):
    code, out, err = cli([*argv, "--preset", MOTORIZED.name], capsys)
    assert code == 2 and out == ""
    assert_one_line_error(err, "6-joint", "11 joints", "table_tilt", alternative)


def test_refusal_has_no_traceback_as_a_process():
    """The installed entry point, as a user types it: one line on stderr, exit 2."""
    run = subprocess.run([sys.executable, "-m", "carmkin.cli", "singularity", "--preset", MOTORIZED.name],
                         capture_output=True, text=True, timeout=HANG_GUARD_S)
    assert run.returncode == 2 and run.stdout == ""
    assert_one_line_error(run.stderr, "carmkin singularity: error:")


# --- the joint-vector parser and printer ------------------------------------------------------------------
@settings(max_examples=50)
@given(data=st.data(), name=st.sampled_from(sorted(PRESETS)))
def test_joint_values_round_trip_through_the_command_line_units(data, name):
    system = PRESETS[name]
    q = data.draw(in_range(system))
    prismatic = np.asarray(system.prismatic, dtype=bool)
    lengths_mm = q[prismatic] * 1000.0
    ranges_mm = np.array([[r.lower, r.upper] for r in system.joint_ranges])[prismatic] * 1000.0
    if _common.metres_slip(lengths_mm, ranges_mm):  # read as metres by the unit-slip rule: refused, naming them
        with pytest.raises(InvalidConfigurationError, match="given in m"):
            parse_joints(cli_values(system, q), system, "--q")
        return
    np.testing.assert_allclose(parse_joints(cli_values(system, q), system, "--q"), q, rtol=1e-14, atol=1e-15)
    printed = joints_json(system, q)
    assert list(printed) == [f"{n}_{'mm' if p else 'deg'}" for n, p in zip(system.joint_names, system.prismatic)]


def test_parser_converts_mm_and_degrees_on_the_motorized_preset():
    q = parse_joints("10, 1, -2, 30, 40, 5, 200, 0, 100, 90, -45", MOTORIZED, "--q")
    np.testing.assert_allclose(q, [0.01, math.radians(1), math.radians(-2), 0.03, 0.04, math.radians(5), 0.2, 0.0,
                                   0.1, math.pi / 2, -math.pi / 4], rtol=0, atol=1e-15)
    assert MOTORIZED.joint_names == MOTORIZED_JOINTS
    text = format_joints(MOTORIZED, q)
    assert "table_height=+40.000 mm" in text and "table_tilt=+1.000°" in text and text.count("=") == 11


@pytest.mark.parametrize("text, words", [
    ("1,2,3", ["--q", "needs 11", "table_tilt (deg)", "table_height (mm)", "got 3"]),
    ("0,0,0,0,0,0,200,x,100,0,0", ["--q", "wigwag (deg) is not a number", "'x'"]),
    ("0,0,0,0,0,0,200,inf,100,0,0", ["--q", "wigwag must be finite"]),
    ("0,0,0,0,0,0,500,0,100,0,0", ["--q", "vertical = 500 mm", "[0, 400] mm", "+100 mm"]),
])
def test_parser_errors_name_the_option_the_count_and_the_joints(text, words):
    with pytest.raises(InvalidConfigurationError) as info:
        parse_joints(text, MOTORIZED, "--q")
    for word in words:
        assert word in str(info.value)


def test_a_value_on_a_limit_is_in_range():
    for system in PRESETS.values():
        np.testing.assert_allclose(parse_joints(cli_values(system, system.upper), system, "--q"), system.upper,
                                   rtol=1e-15, atol=0)
        parse_joints(cli_values(system, system.lower), system, "--q")


def test_out_of_range_configuration_is_refused_by_every_command_that_takes_one(tmp_path, capsys):
    bad = "0,500,0,100,0,0"  # vertical 500 mm > 400 mm
    for argv in (["view", "--q-mm-deg", bad, "--html", tmp_path / "unused.html"], ["singularity", "--q-mm-deg", bad],
                 ["panorama", "shot", "--principal-point", "400,300", "--q-mm-deg", bad],
                 ["ik", "--pose=0,0,500,0,0,0", "--q-mm-deg", bad], ["project", "--q-mm-deg", bad]):
        code, _, err = cli(argv, capsys)
        assert code == 2
        assert_one_line_error(err, "vertical = 500 mm", "[0, 400] mm")


# --- poses --------------------------------------------------------------------------------------------
def cli_pose(system, q) -> str:
    """--pose text (mm, rotation vector in degrees) of FK(q), through Pinocchio's log map."""
    import pinocchio as pin

    T = system.fk(q)
    return ",".join(repr(float(v)) for v in np.r_[T[:3, 3] * 1000, np.degrees(pin.log3(T[:3, :3]))])


def test_pose_files_json_and_text_give_the_same_pose(tmp_path):
    T = PLAIN.fk(mid(PLAIN) + 0.05)
    T_mm = T.copy()
    T_mm[:3, 3] *= 1000
    (tmp_path / "m.json").write_text(json.dumps({"matrix_mm": T_mm.tolist()}))
    np.savetxt(tmp_path / "m.txt", T_mm)
    np.testing.assert_allclose(read_pose(tmp_path / "m.json", "--p"), T, atol=1e-15)
    np.testing.assert_allclose(read_pose(tmp_path / "m.txt", "--p"), T, atol=1e-15)
    # a quarter turn about Z at (1, 2, 3) mm
    quarter = pose_from_mm_deg([1, 2, 3], [0, 0, 90])
    np.testing.assert_allclose(quarter[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    np.testing.assert_allclose(quarter[:3, 3], [0.001, 0.002, 0.003], atol=1e-18)


@pytest.mark.parametrize("name, content, words", [
    ("p.json", '{"position_mm": [0, 0, 0]}', ["--pose-file", "rotation_vector_deg"]),
    ("p.json", "not json", ["--pose-file"]),
    ("p.json", '{"matrix_mm": [[1, 0], [0, 1]]}', ["--pose-file", "4x4"]),
    ("p.txt", "1 0 0 0\n0 1 0 0\n0 0 1 0\n", ["--pose-file", "4x4"]),
])
def test_bad_pose_files_are_one_line_errors(name, content, words, tmp_path, capsys):
    path = tmp_path / name
    path.write_text(content)
    with pytest.raises(InvalidPoseError):
        read_pose(path, "--pose-file")
    code, _, err = cli(["ik", "--pose-file", path], capsys)
    assert code == 2
    assert_one_line_error(err, *words)


# A pose as a user hands it over: typed with 4 decimals (||R^T R - I|| ~ 1e-4) or stored in float32 (~1e-7).
ROUNDINGS = {"4 decimals": lambda M: np.round(M, 4), "float32": lambda M: M.astype(np.float32).astype(float)}


def write_pose(path, T_mm) -> None:
    """``T_mm`` (4x4, translation in mm) as a text matrix or a JSON ``matrix_mm`` file, digits as given."""
    if path.suffix == ".json":
        path.write_text(json.dumps({"matrix_mm": T_mm.tolist()}))
    else:
        np.savetxt(path, T_mm, fmt="%.17g")


def si_joints(system, joints: dict) -> np.ndarray:
    """q (m, rad) from the ``{"<name>_<unit>": value}`` of ``carmkin ik --json`` (mm, degrees)."""
    return np.array([joints[f"{n}_mm"] / 1000.0 if p else math.radians(joints[f"{n}_deg"])
                     for n, p in zip(system.joint_names, system.prismatic)])


@settings(max_examples=40)
@given(q=strategies.configurations(), rounding=st.sampled_from(sorted(ROUNDINGS)),
       suffix=st.sampled_from([".txt", ".json"]))
def test_a_rounded_pose_file_is_projected_noted_in_one_line_and_solved(tmp_path_factory, q, rounding, suffix):
    T_mm = PLAIN.fk(q)
    T_mm[:3, 3] *= 1000.0
    given_mm = ROUNDINGS[rounding](T_mm)
    R = given_mm[:3, :3]
    assume(np.linalg.norm(R.T @ R - np.eye(3)) > 1e-9)  # not already rigid (float32 of an axis-aligned pose)
    path = tmp_path_factory.mktemp("pose") / f"rounded{suffix}"
    write_pose(path, given_mm)
    code, out, err = cli_captured(["ik", "--pose-file", path, "--json"])
    assert code in (0, 1), err  # solved: within the ranges or not (a joint drawn on its limit may round out)
    assert_one_line_error(err, "--pose-file", "projected the pose onto the nearest rigid transform", "°", "mm")
    chosen = json.loads(out)["branches"][json.loads(out)["chosen"]]
    T = PLAIN.fk(si_joints(PLAIN, chosen["joints"]))
    np.testing.assert_allclose(T[:3, 3] * 1000.0, given_mm[:3, 3], atol=1e-6)  # the translation is kept
    np.testing.assert_allclose(T[:3, :3], R, atol=2e-4)  # the rotation moved by the rounding only


def test_the_note_gives_the_turn_of_the_axes_in_degrees_and_the_translation_change_in_mm(tmp_path, capsys):
    # R (I + S) with S symmetric has the polar factor R: the projection gives back R, turning the first two
    # axes by atan(eps) (e0 + eps e1 against e0), the third not at all; the translation stays.
    eps = 1e-4
    T_mm = PLAIN.fk(mid(PLAIN))
    T_mm[:3, 3] *= 1000.0
    S = np.zeros((3, 3))
    S[0, 1] = S[1, 0] = eps
    T_mm[:3, :3] = T_mm[:3, :3] @ (np.eye(3) + S)
    write_pose(tmp_path / "p.txt", T_mm)
    code, _, err = cli(["ik", "--pose-file", tmp_path / "p.txt"], capsys)
    assert code in (0, 1)
    assert_one_line_error(err, f"rotation moved by {math.degrees(math.atan(eps)):.2g}°", "translation by 0 mm")


def test_an_exactly_rigid_pose_file_is_used_as_given_without_a_note(tmp_path, capsys):
    T_mm = PLAIN.fk(mid(PLAIN))
    T_mm[:3, 3] *= 1000.0
    write_pose(tmp_path / "p.txt", T_mm)
    code, _, err = cli(["ik", "--pose-file", tmp_path / "p.txt"], capsys)
    assert code == 0 and err == ""


@pytest.mark.parametrize("option", ["--pose-file", "--to-pose"])
def test_a_clearly_non_rigid_pose_is_refused_in_one_line_naming_the_option_and_the_threshold(option, tmp_path, capsys):
    from carmkin.transforms import NEARLY_RIGID_TOLERANCE

    T_mm = PLAIN.fk(mid(PLAIN))
    T_mm[:3, 3] *= 1000.0
    T_mm[0, :3] *= 1.01  # a row stretched by 1 %: ||R^T R - I|| ~ 2e-2
    write_pose(tmp_path / "p.txt", T_mm)
    command = ["ik", "--pose-file"] if option == "--pose-file" else ["view", "--html", tmp_path / "v.html", option]
    code, out, err = cli([*command, tmp_path / "p.txt"], capsys)
    assert code == 2 and out == ""
    assert_one_line_error(err, option, f"{NEARLY_RIGID_TOLERANCE:g}")


def test_the_viewer_projects_a_rounded_target_pose(tmp_path, capsys):
    T_mm = PLAIN.fk(mid(PLAIN) + 0.1)  # not axis-aligned, so that rounding changes it
    T_mm[:3, 3] *= 1000.0
    write_pose(tmp_path / "p.txt", np.round(T_mm, 4))
    code, out, err = cli(["view", "--to-pose", tmp_path / "p.txt", "--html", tmp_path / "v.html"], capsys)
    assert code == 0 and "wrote" in out
    assert_one_line_error(err, "--to-pose", "projected the pose onto the nearest rigid transform")


def test_missing_pose_file_is_a_one_line_error(tmp_path, capsys):
    for argv in (["ik", "--pose-file", tmp_path / "none.json"],
                 ["view", "--to-pose", tmp_path / "none.txt", "--html", tmp_path / "v.html"]):
        code, _, err = cli(argv, capsys)
        assert code == 2
        assert_one_line_error(err, "none.")


# --- numeric options (issue 13) --------------------------------------------------------------------------
@pytest.mark.parametrize("argv, option", [
    (["verify", "--samples", "-5"], "--samples"),
    (["verify", "--samples", "0"], "--samples"),
    (["verify", "--seed", "-1"], "--seed"),
    (["verify", "--random-setups", "-3"], "--random-setups"),
    (["verify", "--tolerance", "nan"], "--tolerance"),
    (["singularity", "--check", "-5"], "--check"),
    (["singularity", "--grid", "1"], "--grid"),
    (["singularity", "--length-mm", "0"], "--length-mm"),
    (["panorama", "parallax", "--trials", "0"], "--trials"),
    (["panorama", "plan", "--overlap", "1"], "--overlap"),
    (["panorama", "plan", "--length-mm", "-400"], "--length-mm"),
    (["panorama", "map", "--grid", "0"], "--grid"),
    (["workspace", "--tolerance", "-1"], "--tolerance"),
    (["workspace", "--translations-mm", "inf"], "--translations-mm"),
    (["workspace", "--table-dofs", "all", "--poses", "0"], "--poses"),
    (["view", "--fps", "0"], "--fps"),
    (["view", "--frames", "1"], "--frames"),
    (["view", "--margin-mm", "-1"], "--margin-mm"),
    (["view", "--port", "70000"], "--port"),
])
def test_bad_numbers_are_usage_errors_naming_the_option(argv, option, capsys):
    code, out, err = cli(argv, capsys)
    assert code == 2 and out == ""
    assert_one_line_error(err, f"argument {option}", "expected")


def test_object_plane_beyond_the_detector_is_refused(capsys):
    code, _, err = cli(["panorama", "plan", "--object-distance-mm", "5000"], capsys)
    assert code == 2
    sid = PLAIN.carm.source_to_detector * 1000
    assert_one_line_error(err, "--object-distance-mm", f"{sid:g} mm")


@pytest.mark.parametrize("argv, option", [
    (["panorama", "parallax", "--noise=-1,0", "--trials", "1"], "--noise"),
    (["panorama", "shot", "--principal-point", "1,2,3"], "--principal-point"),
    (["panorama", "map", "--range-px", "5,1,0,10", "--grid", "3"], "--range-px"),
    (["singularity", "--measure", "volume"], "--measure"),
    (["singularity", "--pair", "wigwag,elbow"], "elbow"),
])
def test_bad_option_text_is_a_one_line_error(argv, option, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # panorama map would write its default file here
    code, _, err = cli(argv, capsys)
    assert code == 2
    assert_one_line_error(err, option)


# --- output files ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv", [
    ["workspace", "--png", "x.txt"],
    ["singularity", "--png", "x.txt"],
    ["panorama", "map", "--png", "x.txt"],
    ["workspace", "--json", "x.txt"],
    ["view", "--html", "x.png"],
])
def test_wrong_extension_is_refused_before_any_work(argv, tmp_path, capsys):
    argv = [*argv[:-1], tmp_path / argv[-1]]
    code, out, err = cli(argv, capsys)
    assert code == 2 and "wrote" not in out
    assert_one_line_error(err, str(argv[-2]), "extension")
    assert not argv[-1].exists()


def test_outputs_are_written_where_asked(tmp_path, capsys):
    new = tmp_path / "out" / "folder"
    new.mkdir(parents=True)  # a missing folder is refused (tests/commands/test_flags.py)
    for argv, path in (
        (["singularity", "--png", new / "s.png", "--grid", "5"], new / "s.png"),
        (["panorama", "map", "--grid", "3", "--png", new / "m.png"], new / "m.png"),
        (["workspace", "--translations-mm", "0", "--json", new / "w.json", "--png", new / "w.png"], new / "w.json"),
    ):
        code, out, err = cli(argv, capsys)
        assert code == 0, err
        assert path.stat().st_size > 0 and f"wrote {path}" in out
    assert json.loads((new / "w.json").read_text())


def test_unwritable_output_is_a_one_line_error(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("a file where a folder is expected")
    for argv, option in ((["urdf", "-o", blocker / "x.urdf"], "--output"),
                         (["view", "--html", blocker / "v.html"], "--html"),
                         (["urdf", "-o", tmp_path], "--output")):
        code, _, err = cli(argv, capsys)
        assert code == 2
        assert_one_line_error(err, option)


# --- the command line itself ------------------------------------------------------------------------------
def test_an_internal_error_is_one_line_with_exit_3(monkeypatch, capsys):
    from carmkin.commands import urdf

    def broken(args):
        raise TypeError("boom\nsecond line")

    monkeypatch.setattr(urdf, "run", broken)
    monkeypatch.delenv("CARMKIN_DEBUG", raising=False)
    code, _, err = cli(["urdf"], capsys)
    assert code == 3
    assert_one_line_error(err, "internal error: TypeError: boom second line", "CARMKIN_DEBUG=1")


def test_help_lists_every_command_and_loads_no_heavy_library():
    code = ("import sys, contextlib, io\nfrom carmkin.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
            "    try: main(['--help'])\n    except SystemExit: pass\n"
            "heavy = [m for m in ('pinocchio', 'coal', 'qpsolvers', 'matplotlib', 'meshcat', 'scipy') "
            "if m in sys.modules]\nprint(heavy, out.getvalue())")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=HANG_GUARD_S)
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("[] ")
    for command in ("verify", "ik", "urdf", "workspace", "singularity", "panorama", "view"):
        assert command in run.stdout


def test_help_texts_name_the_library_choices():
    from carmkin import singularity
    from carmkin.commands import singularity as singularity_command
    from carmkin.commands import workspace as workspace_command
    from carmkin.studies import table_workspace

    assert tuple(table_workspace.MODELS) == workspace_command.TABLE_MODELS
    assert all(m in singularity_command.MEASURES_HELP for m in singularity.MAP_MEASURES)


def test_usage_error_is_a_carmkin_error():
    assert issubclass(UsageError, carmkin.CarmkinError) and issubclass(_common.NotApplicableError, UsageError)


def test_a_panorama_plan_opens_in_the_browser(tmp_path, capsys):
    """`panorama plan --html`: a viewer page with one cone per shot, placed at the shot's target pose."""
    import base64
    import re

    import umsgpack

    page = tmp_path / "plan.html"
    code, out, err = cli(["panorama", "plan", "--length-mm", "200", "--html", page], capsys)
    assert code == 0 and f"wrote {page}" in out, err
    commands = [umsgpack.unpackb(base64.b64decode(b))
                for b in re.findall(r'data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"', page.read_text())]
    cones = {c["path"] for c in commands if c["type"] == "set_transform" and "/shots/planned/" in c["path"]}
    shots = int(re.search(r"(\d+) shots", out).group(1))
    assert len(cones) == shots >= 2


def test_nonsense_inputs_are_refused_in_one_line(tmp_path, capsys):
    broken = tmp_path / "broken.toml"
    broken.write_text("a = [")
    cases = ((["urdf", "--preset", broken], ["--preset", "malformed TOML"]),
             (["urdf", "--preset", tmp_path / "none.toml"], ["--preset", "no such preset file"]),
             (["workspace", "--translations-mm", "5000"], ["--translations-mm 5000", "table translation range", "mm"]))
    for argv, words in cases:
        code, out, err = cli(argv, capsys)
        assert code == 2 and out == ""
        assert_one_line_error(err, *words)
