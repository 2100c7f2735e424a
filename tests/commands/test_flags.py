"""One vocabulary on the command line (docs/cli.md): one option name for a joint vector on every command (the
former names hidden, working, and saying so), ``--target-mm`` for a point, ``--patient-position`` for a DICOM
code, ``--png``/``--html`` for figures, ``--json [FILE]`` on every command that computes something, usage errors
that name the subcommand; ``carmkin --version`` and ``carmkin.__version__`` from the package metadata, and an
output folder that does not exist refused before any work, never created."""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import re

import pytest

import carmkin
from carmkin.cli import build_parser
from carmkin.commands._common import JOINTS_FLAG, JOINTS_METAVAR
from test_cli import cli as run  # noqa: E402 (tests/commands is on sys.path)

#: The names each command used before the one name (kept hidden for one release).
FORMER = {"view": "--q", "ik": "--current", "panorama shot": "--reference-q-mm-deg"}
#: Options that take a second joint vector with another role (a target), not the configuration worked at.
OTHER_ROLES = {"--to-q-mm-deg"}


def parsers(parser: argparse.ArgumentParser | None = None, prefix: str = "") -> dict[str, argparse.ArgumentParser]:
    """Every (sub)command's parser by its command line (``"panorama shot"``), the leaves of the tree."""
    parser = parser or build_parser()
    found = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, child in action.choices.items():
                found |= parsers(child, f"{prefix} {name}".strip())
    return found or {prefix: parser}


def test_every_command_that_takes_a_configuration_names_it_the_same():
    visible = {}
    for command, parser in parsers().items():
        for action in parser._actions:
            if action.help != argparse.SUPPRESS and action.metavar == JOINTS_METAVAR:
                visible.setdefault(command, set()).update(o for o in action.option_strings if o not in OTHER_ROLES)
    assert {"view", "ik", "singularity", "panorama shot", "panorama plan", "project", "dicom", "drr"} <= set(visible)
    assert all(options == {JOINTS_FLAG} for options in visible.values()), visible


@pytest.mark.parametrize("command, former", FORMER.items())
def test_former_names_are_hidden_and_still_work_with_a_note(command, former, capsys):
    parser = parsers()[command]
    assert not re.search(rf"{re.escape(former)}(?![\w-])", parser.format_help())
    head = command.split()
    extra = {"view": ["--html", "unused.html"], "ik": ["--pose=0,0,500,0,0,0"],
             "panorama shot": ["--principal-point", "400,300"]}[command]
    bad = "0,500,0,100,0,0"  # vertical 500 mm > 400 mm: refused before any work, under either name
    code_new, _, err_new = run([*head, JOINTS_FLAG, bad, *extra], capsys)
    code_old, _, err_old = run([*head, former, bad, *extra], capsys)
    assert code_new == code_old == 2
    note, error = err_old.strip().splitlines()
    assert note.startswith(f"note: {former} is now called {JOINTS_FLAG}")
    assert error == err_new.strip() and "vertical = 500 mm" in error


def test_a_configuration_given_under_the_former_name_is_the_same_configuration(capsys):
    q = "50,200,2,100,30,-20"
    code_new, out_new, _ = run(["singularity", JOINTS_FLAG, q], capsys)
    code_old, out_old, err_old = run(["panorama", "shot", "--principal-point", "400,300", "--reference-q-mm-deg", q],
                                     capsys)
    code_ref, out_ref, _ = run(["panorama", "shot", "--principal-point", "400,300", JOINTS_FLAG, q], capsys)
    assert code_new == 0 and code_old == code_ref and out_old == out_ref and "note:" in err_old


def test_version_comes_from_the_package_metadata(capsys):
    expected = importlib.metadata.version("carmkin")
    assert carmkin.__version__ == expected
    code, out, _ = run(["--version"], capsys)
    assert code == 0 and out.strip() == f"carmkin {expected}"


@pytest.mark.parametrize("argv", [
    ["views", "plan", "--standard", "AP", "--png"],
    ["workspace", "--png"],
    ["ik", "--pose=213,385,359,72.7,-87.5,52.7", "--json"],
    ["urdf", "-o"],
])
@pytest.mark.parametrize("where", ["tmp", "/nonexistent"])
def test_a_missing_output_folder_is_refused_before_any_work_and_never_created(argv, where, tmp_path, capsys,
                                                                               monkeypatch):
    import pathlib

    folder = tmp_path / "missing" if where == "tmp" else pathlib.Path(where)
    if folder.exists():
        pytest.skip(f"{folder} exists on this machine")
    module = __import__(f"carmkin.commands.{argv[0]}", fromlist=["run"])
    monkeypatch.setattr(module, "run", lambda args: pytest.fail("the command ran before its output was checked"))
    suffix = {"--png": "x.png", "--json": "x.json", "-o": "x.urdf"}[argv[-1]]
    code, out, err = run([*argv, str(folder / suffix)], capsys)
    assert code == 2 and not out and len(err.strip().splitlines()) == 1, err
    assert f"the folder '{folder}' does not exist" in err and argv[-1] in err and argv[0] in err
    assert not folder.exists()


def test_a_dataset_folder_is_made_only_when_its_parent_is_there(tmp_path, capsys, monkeypatch):
    import carmkin.commands.dataset as dataset

    base = ["dataset", "generate", "--prior", "standard-views", "--n", "1", "--size", "10x10", "--out"]
    monkeypatch.setattr(dataset.common, "system_from_args", lambda args: pytest.fail("work began"))
    code, _, err = run([*base, str(tmp_path / "a" / "b")], capsys)
    assert code == 2 and f"the folder '{tmp_path / 'a'}' does not exist" in err and not (tmp_path / "a").exists()
    (tmp_path / "f").write_text("")
    code, _, err = run([*base, str(tmp_path / "f")], capsys)
    assert code == 2 and "is a file, expected a folder" in err
    with pytest.raises(pytest.fail.Exception, match="work began"):  # a new folder in an existing one: work starts
        run([*base, str(tmp_path / "new")], capsys)


def test_an_output_folder_that_cannot_be_made_is_refused_in_one_line(tmp_path, capsys):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    code, _, err = run(["urdf", "-o", blocker / "carm.urdf"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--output" in err and "is a file" in err


# --- the grammar of docs/cli.md, over every subcommand's parser ------------------------------------------------
#: Commands that compute nothing to report (they write a file or show a scene): no --json.
NO_JSON = {"urdf", "view"}
#: Names that the grammar replaced; none may be visible in any --help.
REPLACED = {"--plot", "--out", "--q", "--current", "--q-start", "--reference-q-mm-deg", "--target", "--target-pose"}
#: Former name -> (command line that uses it, the dest it must fill, its value).
ALIASES = {
    "--q-start": ("sweep plan", "q_mm_deg", "0,200,0,100,0,0"),
    "--plot": ("workspace", "png", "w.png"),
    "--out": ("panorama map", "png", "m.png"),
    "--target": ("view", "to_q_mm_deg", "0,200,0,100,0,0"),
    "--target-pose": ("view", "to_pose", "pose.txt"),
    "--patient": ("dicom", "patient_position", "FFS"),
}
LEAVES = parsers()
#: What the commands with required arguments need besides (parsed only: the tests stop before any work).
REQUIRED = {"dataset generate": ["--prior", "sweep", "--n", "1", "--size", "40x30", "--out", "never-made"],
            "dataset info": ["never-made"], "views optimal": ["--centreline", "never-read.csv"],
            "dose map": ["--rdsr", "never-read.dcm"], "dose plan": ["--view-deg", "0,0"], "move plan": ["--to-view", "ap"],
            "calibrate": ["never-read.csv", "--phantom", "never-read.csv"]}


def visible_options(parser) -> dict[str, argparse.Action]:
    return {o: a for a in parser._actions if a.help != argparse.SUPPRESS for o in a.option_strings}


@pytest.mark.parametrize("command", sorted(LEAVES))
def test_every_option_follows_the_grammar(command):
    options = visible_options(LEAVES[command])
    # --out names a folder (metavar DIR, e.g. a dataset's shards); as a figure it was replaced by --png
    replaced = {o for o in REPLACED & set(options) if not (o == "--out" and options[o].metavar == "DIR")}
    assert not replaced, f"carmkin {command}: {replaced} replaced (docs/cli.md)"
    for name, action in options.items():
        if action.metavar == JOINTS_METAVAR:
            assert name.endswith("q-mm-deg"), f"carmkin {command} {name}: a configuration is --...q-mm-deg"
        if action.metavar == "X,Y,Z" and name.startswith("--target"):
            assert name == "--target-mm", f"carmkin {command} {name}: a point is --target-mm"
        if action.metavar == "CODE":
            assert name == "--patient-position", f"carmkin {command} {name}: a DICOM code is --patient-position"
        if name == "--patient":
            assert action.metavar != "CODE", f"carmkin {command}: --patient is a body model, not a DICOM code"
    for action in LEAVES[command]._actions:  # every hidden name is a former name of a visible option
        if action.help == argparse.SUPPRESS and action.option_strings:
            assert any(a.dest == action.dest for a in options.values()), (command, action.option_strings)


@pytest.mark.parametrize("command", sorted(set(LEAVES) - NO_JSON))
def test_every_command_that_computes_writes_json(command):
    action = visible_options(LEAVES[command]).get("--json")
    assert action is not None, f"carmkin {command} has no --json"
    assert action.metavar == "FILE" and action.nargs == "?" and action.const == "-"


@pytest.mark.parametrize("command", sorted(LEAVES))
def test_an_unknown_option_names_the_subcommand(command, capsys):
    head = command.split()
    required = {"ik": ["--pose=0,0,500,0,0,0"], "reproduce": ["model"],
                "panorama shot": ["--principal-point", "400,300"], **REQUIRED}.get(command, [])
    code, out, err = run([*head, *required, "--bogus"], capsys)
    assert code == 2 and not out and "Traceback" not in err
    assert err.strip().splitlines() == [f"carmkin {command}: error: unrecognized arguments: --bogus "
                                        f"(see carmkin {command} --help)"]


@pytest.mark.parametrize("command", sorted(set(LEAVES) - NO_JSON))
def test_an_output_that_cannot_be_written_is_refused_before_any_work(command, tmp_path, capsys):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    required = {"ik": ["--pose=0,0,500,0,0,0"], "reproduce": ["all"],
                "panorama shot": ["--principal-point", "400,300"], **REQUIRED}.get(command, [])
    code, out, err = run([*command.split(), *required, "--json", blocker / "x.json"], capsys)
    assert code == 2 and not out
    assert err.strip().splitlines() == [f"carmkin {command}: error: --json {blocker / 'x.json'}: '{blocker}' is a "
                                        "file, not a folder"]


@pytest.mark.parametrize("former", sorted(ALIASES))
def test_former_names_fill_the_new_option_with_a_note(former, capsys):
    command, dest, value = ALIASES[former]
    args = build_parser().parse_args([*command.split(), former, value])
    assert getattr(args, dest) == value
    assert f"note: {former} is now called" in capsys.readouterr().err


def test_json_dash_prints_only_json_on_stdout(capsys):
    code, out, err = run(["ik", "--pose=213,385,359,72.7,-87.5,52.7", "--json", "-"], capsys)
    assert code == 0 and json.loads(out)["chosen"] in (0, 1) and not err
    code, out_flag, _ = run(["ik", "--pose=213,385,359,72.7,-87.5,52.7", "--json"], capsys)
    assert out_flag == out


def test_json_file_is_written_and_said(tmp_path, capsys):
    path = tmp_path / "ik.json"
    code, out, _ = run(["ik", "--pose=213,385,359,72.7,-87.5,52.7", "--json", path], capsys)
    assert code == 0 and f"wrote {path}" in out and json.loads(path.read_text())["valid"] is True


@pytest.mark.parametrize("command", sorted(LEAVES))
def test_help_shows_no_markup(command):
    text = LEAVES[command].format_help()
    assert "``" not in text and not re.search(r":(?:class|func|mod|data|meth):`", text), command
