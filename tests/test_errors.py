"""Bad input raises typed errors that name the problem."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from strategies import PRESET

import carmkin
from carmkin import (
    CArmGeometry,
    InvalidConfigurationError,
    InvalidParameterError,
    InvalidPoseError,
    JointRange,
    TableSetup,
    UnknownPresetError,
)
from carmkin.cli import main


def test_unknown_preset_names_the_available_ones():
    with pytest.raises(UnknownPresetError, match="siremobile-iso-c3d"):
        carmkin.load_preset("no-such-c-arm")


def test_list_presets_lists_the_shipped_files():
    assert "siremobile-iso-c3d" in carmkin.list_presets()


@pytest.mark.parametrize("field", ["length_offset", "orbital_offset", "source_to_detector", "detector_width"])
def test_negative_lengths_are_rejected(field):
    with pytest.raises(InvalidParameterError, match=field):
        replace(PRESET.carm, **{field: -0.1})


def test_lower_above_upper_is_rejected():
    with pytest.raises(InvalidParameterError, match=r"wigwag: lower limit .* > upper limit"):
        JointRange(0.2, -0.2, "wigwag")


@pytest.mark.parametrize("value", [math.nan, math.inf])
def test_nan_parameters_are_rejected(value):
    with pytest.raises(InvalidParameterError, match="a1"):
        replace(PRESET.carm, a1=value)
    with pytest.raises(InvalidParameterError, match="gamma2"):
        TableSetup(0.1, value, 0.0, 0.0, 0.0, 0.0)


def test_pixel_counts_must_be_positive_integers():
    with pytest.raises(InvalidParameterError, match="detector_columns"):
        replace(PRESET.carm, detector_columns=0)
    with pytest.raises(InvalidParameterError, match="detector_rows"):
        replace(PRESET.carm, detector_rows=600.5)


@pytest.mark.parametrize("q", [np.zeros(5), np.zeros((3, 7)), np.zeros((2, 2, 6)), "abc"])
def test_fk_rejects_wrong_shapes(q):
    with pytest.raises(InvalidConfigurationError, match="q"):
        PRESET.fk(q)


def test_fk_rejects_nan():
    with pytest.raises(InvalidConfigurationError, match="NaN"):
        PRESET.fk([0, 0, math.nan, 0, 0, 0])


def test_from_pose_rejects_non_rigid_input():
    T = np.eye(4)
    T[0, 0] = 2.0
    with pytest.raises(InvalidPoseError, match="orthonormal"):
        TableSetup.from_pose(T)
    with pytest.raises(InvalidPoseError, match="det"):
        TableSetup.from_pose(np.diag([1.0, 1.0, -1.0, 1.0]))
    with pytest.raises(InvalidPoseError, match="shape"):
        TableSetup.from_pose(np.eye(3))


def test_preset_file_with_bad_limits_is_rejected(tmp_path):
    text = (carmkin.presets._preset_dir() / "siremobile-iso-c3d.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("wigwag_min_deg = -10.0", "wigwag_min_deg = 30.0"))
    with pytest.raises(InvalidParameterError, match="wigwag"):
        carmkin.load_preset(bad)


def test_cli_reports_unknown_preset_as_an_error(capsys):
    assert main(["urdf", "--preset", "nope"]) == 2
    assert "unknown preset 'nope'" in capsys.readouterr().err


def test_geometry_requires_joint_ranges():
    with pytest.raises(InvalidParameterError, match="vertical"):
        CArmGeometry(1.0, 0.5, vertical=(0.0, 0.4))


def test_preset_errors_are_typed_carmkin_errors():
    from carmkin.errors import NearSingularSetupError, PresetError

    assert issubclass(PresetError, InvalidParameterError) and issubclass(UnknownPresetError, PresetError)
    assert issubclass(NearSingularSetupError, InvalidParameterError)
    with pytest.raises(UnknownPresetError, match=r"did you mean 'siremobile-iso-c3d'\?"):
        carmkin.load_preset("siremobile-iso-c3")
    with pytest.raises(UnknownPresetError, match=r"no preset file 'missing/x.toml'"):
        carmkin.load_preset("missing/x.toml")


@pytest.mark.parametrize("value", [1j, np.complex128(0.2), "0.2", True, None, [0.2], np.array([0.2])])
def test_joint_range_refuses_non_real_values_without_a_warning(value):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InvalidParameterError, match=r"wigwag.upper must be a real number"):
            JointRange(0.0, value, "wigwag")


def test_cli_reports_a_misspelled_preset_key_in_one_line(tmp_path, capsys):
    text = (carmkin.presets._preset_dir() / "siremobile-iso-c3d.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("a1_mm = 0.0", "a1_mn = 50.0"))
    assert main(["urdf", "--preset", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "unknown key 'a1_mn' in [carm]; did you mean 'a1_mm'?" in err and "Traceback" not in err
