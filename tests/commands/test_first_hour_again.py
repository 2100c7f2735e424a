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


# --- unit slips: exit 2 naming the likely unit (the one rule of carmkin/commands/_common.py) -----------------
@pytest.mark.parametrize("argv, option, words", [
    (["ik", "--pose=0.193,0.406,0.342,1.178,-1.47,1.044"], "--pose", ("given in m?", "0.193 m = 193 mm",
                                                                      "radians?", "1.178 rad = 67.49°")),
    (["ik", "--pose=0.193,0.406,0.342,67.5,-84.2,59.8"], "--pose", ("given in m?",)),
    (["workspace", "--translations-mm", "0", "0.05", "0.1"], "--translations-mm", ("given in m?", "0.05 m = 50 mm")),
    (["singularity", "--q-mm-deg", "0,0.2,0,0.1,1.57,0"], "--q-mm-deg", ("given in m?", "0.2 m = 200 mm",
                                                                        "radians?", "1.57 rad = 89.95°")),
    (["views", "plan", "--target-mm", "0,0.1,0", "--primary-deg", "0", "--secondary-deg", "0"], "--target-mm",
     ("given in m?", "0.1 m = 100 mm")),
    (["reposition", "simulate", "--threshold-deg", "30"], "--threshold-deg", ("given in arcmin?", "30 arcmin = 0.5 deg")),
])
def test_each_listed_unit_slip_exits_2_naming_the_likely_unit(argv, option, words, capsys):
    code, out, err = cli(argv, capsys)
    assert code == 2 and out == ""
    assert_one_line_error(err, option, *words)


def test_the_pose_in_mm_and_degrees_still_solves(capsys):
    code, out, _ = cli(["ik", "--pose=193,406,342,67.5,-84.2,59.8"], capsys)
    assert code == 0 and "branches" in out


@pytest.mark.parametrize("argv", [
    ["views", "plan", "--target-mm", "0,0,0", "--primary-deg", "0", "--secondary-deg", "0", "--json"],  # all zero
    ["views", "plan", "--target-mm", "0,-100,2", "--primary-deg", "0", "--secondary-deg", "0", "--json"],
    ["workspace", "--translations-mm", "0", "2", "--json"],  # 2 m is beyond d0's range: not metres
])
def test_small_values_that_are_not_a_slip_are_accepted(argv, capsys):
    code, _, err = cli(argv, capsys)
    assert code == 0, err


def test_the_slip_rule_reads_as_documented():
    from carmkin.commands._common import METRES_SLIP_BELOW_MM, metres_slip

    assert metres_slip([0.0, 0.1, 0.0]) and metres_slip([-2.9]) and not metres_slip([0.0, 0.0])
    assert not metres_slip([0.1, METRES_SLIP_BELOW_MM]) and not metres_slip([])
    assert metres_slip([0.2], [[0.0, 400.0]]) and not metres_slip([0.5], [[0.0, 400.0]])  # 500 mm out of range


# --- the inconsistencies of the list -------------------------------------------------------------
def test_a_sweep_the_joints_cannot_follow_does_not_end_with_feasible(capsys):
    code, out, _ = cli(["sweep", "plan", "--acquisition-time-s", "1"], capsys)
    assert code == 1
    last = out.strip().splitlines()[-1]
    assert last.startswith("NOT feasible at a 1 s acquisition") and "orbital" in last


def test_a_sweep_the_joints_follow_ends_with_feasible(capsys):
    code, out, _ = cli(["sweep", "plan"], capsys)
    assert code == 0 and out.strip().splitlines()[-1] == "feasible"


@pytest.mark.parametrize("argv", [
    ["views", "map", "--primary-range-deg", "-90,90", "--step-deg", "45", "--patient", "none", "--json", "-"],
    ["views", "map", "--primary-range-deg", "-90", "--step-deg", "45", "--patient", "none", "--json", "-"],
])
def test_a_range_starting_negative_needs_no_equals_sign(argv, capsys):
    code, out, err = cli(argv, capsys)
    if argv[3] == "-90":  # a lone number is still checked as the option asks (LO,HI)
        assert code == 2 and "--primary-range-deg" in err
        return
    assert code == 0, err
    cells = json.loads(out)["cells"]
    assert min(c["primary_deg"] for c in cells) == -90.0 and max(c["primary_deg"] for c in cells) == 90.0


def test_a_joint_vector_starting_negative_needs_no_equals_sign(capsys):
    code, out, err = cli(["singularity", "--q-mm-deg", "-5,200,0,100,0,0"], capsys)
    assert code == 0, err
    assert "table_translation=-5.0000 mm" in out


def test_a_misspelt_option_is_still_an_unknown_option(capsys):
    code, _, err = cli(["views", "map", "-x,1"], capsys)
    assert code == 2 and "unrecognized arguments" in err


def test_urdf_help_promises_nothing_it_does_not_do(capsys):
    code, out, _ = cli(["urdf", "--help"], capsys)
    text = " ".join(out.split())
    assert code == 0
    assert "created if missing" not in text and "its folder must exist" in text


def test_urdf_refuses_a_missing_folder_as_its_help_says(tmp_path, capsys):
    code, _, err = cli(["urdf", "-o", str(tmp_path / "missing" / "c.urdf")], capsys)
    assert code == 2 and not (tmp_path / "missing").exists()


def test_biplane_plan_says_what_it_wrote(tmp_path, capsys):
    page = tmp_path / "b.html"
    code, out, _ = cli(["biplane", "plan", "--standard", "ap", "--html", str(page)], capsys)
    assert page.exists() == (code == 0)
    assert (f"wrote {page}" if code == 0 else f"not written (no plan to show): {page}") in out


def test_workspace_json_keys_carry_their_units(tmp_path, capsys):
    code, out, _ = cli(["workspace", "--translations-mm", "0", "--json", "-"], capsys)
    data = json.loads(out)
    assert code == 0 and list(data) == ["translations_mm"]
    assert list(data["translations_mm"]["0"]) == ["vertical_mm", "wigwag_deg", "horizontal_mm", "angular_deg",
                                                  "orbital_deg"]


def test_robotic_carm_plan_names_its_mount_not_a_motorized_table(capsys):
    code, out, _ = cli(["views", "plan", "--preset", "robotic-carm", "--primary-deg", "0", "--secondary-deg", "0"],
                       capsys)
    assert code == 0
    assert "motorized table" not in out  # the robot's closed form (or the QP with every joint free) places it


# --- refused before any work -----------------------------------------------------------------------------
def test_sweep_reconstruct_without_the_cbct_extra_is_refused_before_planning(monkeypatch, capsys):
    import importlib.util

    import carmkin.sweeps

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "itk" else real(name, *a))
    monkeypatch.setattr(carmkin.sweeps, "plan_sweep", lambda *a, **k: pytest.fail("planned before the check"))
    code, out, err = cli(["sweep", "reconstruct"], capsys)
    assert code == 2 and out == ""
    assert_one_line_error(err, "itk is not installed", 'pip install "carmkin[cbct]"')


def test_view_png_without_a_chromium_is_refused_before_the_scene_is_built(tmp_path, monkeypatch, capsys):
    import carmkin.viz

    monkeypatch.setenv("CARMKIN_CHROMIUM", str(tmp_path / "no-such-chromium"))
    monkeypatch.setattr(carmkin.viz, "CArmViewer", lambda *a, **k: pytest.fail("the scene was built"))
    code, out, err = cli(["view", "--png", str(tmp_path / "v.png")], capsys)
    assert code == 2 and out == "" and not (tmp_path / "v.png").exists()
    assert_one_line_error(err, "CARMKIN_CHROMIUM", "not an executable")



def test_an_xa_dataset_round_trips_with_the_isocentre_the_write_names(tmp_path, capsys):
    """XA angles fix the view's direction, not where its isocentre is: the write names it, the read says what it
    assumes without it, and read back with it the configuration does not move."""
    pytest.importorskip("pydicom", reason="DICOM files need the dicom extra (pydicom)")
    q, path = "0,100,0,100,20,5", tmp_path / "v.dcm"
    code, out, _ = cli(["dicom", "--q-mm-deg", q, "--write-xa", path], capsys)
    assert code == 0
    iso = out.split("--isocenter-mm=")[1].split(",", 3)
    iso = ",".join([iso[0], iso[1], iso[2].split()[0]])
    assert iso == "100,-100,0"  # the isocentre of the preset at q: on the beam, 625 mm from the source
    code, out, _ = cli(["dicom", "--read", path, "--q-mm-deg", q], capsys)
    assert "note: an XA dataset does not say where its isocentre is: assumed at the patient origin" in out
    code, out, _ = cli(["dicom", "--read", path, "--q-mm-deg", q, f"--isocenter-mm={iso}"], capsys)
    assert code == 0 and "note:" not in out
    moves = json.loads(cli(["dicom", "--read", path, "--q-mm-deg", q, f"--isocenter-mm={iso}", "--json", "-"],
                           capsys)[1])["moves"]
    assert max(abs(v) for v in moves.values()) < 1e-6


def test_drr_on_a_cuda_device_torch_cannot_see_is_refused_before_the_ct_loads(monkeypatch, capsys):
    """`drr --device cuda` on a CPU build of torch was an internal error (exit 3) after 99 s of work."""
    import sys
    import types

    import carmkin.interop.drr as drr

    cpu_torch = types.SimpleNamespace(__version__="2.13.0+cpu", cuda=types.SimpleNamespace(is_available=lambda: False))
    monkeypatch.setitem(sys.modules, "torch", cpu_torch)
    monkeypatch.setattr(drr, "load_ct", lambda *a, **k: pytest.fail("the CT was loaded before the device check"))
    code, out, err = cli(["drr", "--device", "cuda"], capsys)
    assert code == 2 and out == ""
    assert_one_line_error(err, "--device cuda", "no CUDA device", "--device cpu")
