"""Issue "The first hour, again": what a newcomer met on the command line — a biplane preset silently cut to
its frontal plane, a motorized preset's Table 4.5 without a note, unit slips that ran, and the inconsistencies
of its list. Each refusal is one line, exit 2, naming the option and the likely unit or the right command."""

import json

import pytest

from test_cli import assert_one_line_error, cli  # noqa: E402 (tests/commands is on sys.path)


# --- a biplane preset outside `carmkin biplane` ------------------------------------------------------------
@pytest.mark.parametrize("argv", [
    ["ik", "--pose=193,406,342,67.5,-84.2,59.8"],
    ["views", "plan", "--primary-deg", "30", "--secondary-deg", "20"],
    ["views", "map", "--step-deg", "45"],
    ["urdf"],
    ["verify", "--samples", "10"],
    ["workspace", "--translations-mm", "0"],
    ["sweep", "plan"],
    ["singularity"],
])
def test_a_biplane_preset_outside_the_biplane_command_is_refused_naming_it(argv, capsys):
    code, out, err = cli([*argv, "--preset", "angio-biplane"], capsys)
    assert code == 2 and out == ""
    assert_one_line_error(err, "--preset angio-biplane is a biplane preset", "lateral angio-lateral",
                          "carmkin biplane", "--preset angio-floor for the frontal plane alone")


def test_the_biplane_command_still_reads_both_planes(capsys):
    code, out, _ = cli(["biplane", "check", "--preset", "angio-biplane"], capsys)
    assert code == 0 and "frontal angio-floor, lateral angio-lateral" in out


def test_the_library_still_reads_a_biplane_preset_as_its_frontal_plane():
    import carmkin
    from carmkin.presets import biplane_planes

    assert carmkin.load_preset("angio-biplane").name == "angio-biplane"
    assert biplane_planes("angio-biplane") == {"frontal": "angio-floor", "lateral": "angio-lateral"}
    assert biplane_planes("siremobile-iso-c3d") is None


# --- Table 4.5 on a motorized table ----------------------------------------------------------------------
def test_workspace_on_a_motorized_table_says_which_joints_it_holds(capsys):
    code, out, _ = cli(["workspace", "--preset", "siremobile-iso-c3d-motorized-table", "--translations-mm", "0"],
                       capsys)
    assert code == 0
    note = next(line for line in out.splitlines() if line.startswith("note:"))
    assert "11 joints" in note and "table_tilt" in note and "table_rotation" in note and "--table-dofs" in note


def test_workspace_on_the_paper_chain_has_no_note(capsys):
    code, out, _ = cli(["workspace", "--translations-mm", "0"], capsys)
    assert code == 0 and "note:" not in out
