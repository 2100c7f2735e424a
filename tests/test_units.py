"""Unit slips are refused and named: a length or an angle that cannot be right on a C-arm in the unit asked for
(a 0.5 mm patient, a 0.4 mm panorama, a 1750 m patient) is a typed error whose message names the unit the
value was probably given in (:func:`carmkin.validation.unit_slip`); nothing is converted silently."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from carmkin.cli import main
from carmkin.errors import CarmkinError, PatientModelError
from carmkin.validation import real_scalar, unit_slip


@settings(max_examples=50)
@given(st.floats(0.41, 2.79))  # off the bounds: 2.8 · 1000 · 1e-3 rounds above 2.8
def test_a_length_in_mm_where_m_is_expected_is_named(height_m):
    with pytest.raises(CarmkinError, match=r"given in mm\?"):
        real_scalar(height_m * 1000.0, "height", low=0.4, high=2.8, unit="m")


@settings(max_examples=50)
@given(st.floats(5.0, 170.0))
def test_an_angle_in_degrees_where_rad_is_expected_is_named(angle_deg):
    low, high = math.radians(1.0), math.radians(175.0)
    with pytest.raises(CarmkinError, match=r"given in degrees\?"):
        real_scalar(angle_deg, "angle", low=low, high=high, unit="rad")


def test_no_slip_is_named_when_no_other_unit_fits():
    assert unit_slip(1e9, 0.4, 2.8, "m") == ""
    assert unit_slip(5.0, 0.4, None, "m") == ""  # one-sided: cannot tell
    assert unit_slip(1750.0, 0.4, 2.8, "m") == ": given in mm? 1750 mm = 1.75 m"


def test_a_patient_height_given_in_mm_is_refused_naming_mm():
    from carmkin.patient import ParametricPatient

    with pytest.raises(PatientModelError, match=r"got 1750: given in mm\? 1750 mm = 1.75 m"):
        ParametricPatient(height=1750.0)


@pytest.mark.parametrize("argv, words", [
    (["sweep", "plan", "--patient-box-mm", "0.5,0.3,1.6"], ("--patient-box-mm", "0.5 mm", "given in m? 0.5 m = 500 mm")),
    (["panorama", "plan", "--length-mm", "0.4"], ("--length-mm", "given in m? 0.4 m = 400 mm")),
    (["views", "plan", "--patient-height-mm", "1.75", "--standard", "list"], ("--patient-height-mm", "given in m?")),
])
def test_the_command_line_names_the_slip_in_one_line(argv, words, capsys):
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    assert code == 2 and not out and len(err.strip().splitlines()) == 1
    for word in words:
        assert word in err, (word, err)
