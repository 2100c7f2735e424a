"""One vocabulary on the command line: one option name for a joint vector on every command (the former names
hidden, working, and saying so), ``carmkin --version`` and ``carmkin.__version__`` from the package metadata,
and an output folder that is created with a line that says so."""

from __future__ import annotations

import argparse
import importlib.metadata
import re

import pytest

import carmkin
from carmkin.cli import build_parser
from carmkin.commands._common import JOINTS_FLAG, JOINTS_METAVAR
from test_cli import cli as run  # noqa: E402 (tests/commands is on sys.path)

#: The names each command used before the one name (kept hidden for one release).
FORMER = {"view": "--q", "ik": "--current", "panorama shot": "--reference-q-mm-deg"}
#: Options that take a second joint vector with another role (a target), not the configuration worked at.
OTHER_ROLES = {"--target"}


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


def test_a_missing_output_folder_is_created_and_said(tmp_path, capsys):
    target = tmp_path / "new" / "deeper" / "carm.urdf"
    code, _, err = run(["urdf", "-o", target], capsys)
    assert code == 0 and target.read_text().startswith("<?xml")
    assert f"created the folder '{target.parent}'" in err
    code, _, err = run(["urdf", "-o", target], capsys)  # the folder exists now: nothing to say
    assert code == 0 and "created" not in err


def test_an_output_folder_that_cannot_be_made_is_refused_in_one_line(tmp_path, capsys):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    code, _, err = run(["urdf", "-o", blocker / "carm.urdf"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--output" in err and "cannot create the folder" in err
