"""Unit slips are refused and named: a length or an angle that cannot be right on a C-arm in the unit asked for
(a 0.5 mm patient, a 0.4 mm panorama, a 1750 m patient) is a typed error whose message names the unit the
value was probably given in (:func:`carmkin.validation.unit_slip`); nothing is converted silently."""

from __future__ import annotations

import functools
import math

import numpy as np

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


# --- the library: a joint vector and an obstacle given in mm or degrees ------------------------------------------
from strategies import PRESET, configurations, motorized_systems  # noqa: E402 (tests/ is on sys.path)

from carmkin.errors import CollisionSceneError, InvalidConfigurationError  # noqa: E402
from carmkin.model.system import PLAUSIBLE_PRISMATIC, PLAUSIBLE_REVOLUTE  # noqa: E402
from carmkin.robot.collision import Obstacle  # noqa: E402



@functools.cache
def _motorized():
    import carmkin

    return carmkin.load_preset("siremobile-iso-c3d-motorized-table")


@settings(max_examples=40, deadline=None)
@given(st.data())
def test_fk_given_mm_is_refused_exactly_when_no_metre_value_could_mean_it(data):
    """Prismatic values of an in-range q written in mm: refused iff one of them exceeds the stated bound, and the
    message names that value read back in m (the oracle: the q we converted)."""
    system = data.draw(st.sampled_from(["preset", "motorized", "random"]))
    system = {"preset": None, "motorized": _motorized()}.get(system) or data.draw(motorized_systems(max_joints=3))
    q = data.draw(configurations(system))
    prismatic = np.array(system.prismatic)
    q_mm = np.where(prismatic, q * 1000.0, q)
    too_big = np.abs(q_mm[prismatic]) > PLAUSIBLE_PRISMATIC
    if not too_big.any():
        assert np.allclose(system.fk(q_mm), system.fk(q_mm, check_units=False))
        return
    with pytest.raises(InvalidConfigurationError, match=r"given in mm\? ") as info:
        system.fk(q_mm)
    first = int(np.flatnonzero(prismatic)[np.argmax(too_big)])
    assert f"q[{first}] ({system.joint_names[first]})" in str(info.value)
    assert f"= {q[first]:.4g} m" in str(info.value)
    with pytest.raises(InvalidConfigurationError):  # a batch too, naming the row
        system.fk(np.array([q, q_mm]))


@settings(max_examples=40, deadline=None)
@given(st.data())
def test_fk_given_degrees_is_refused_beyond_two_turns(data):
    system = data.draw(st.sampled_from([None, "motorized"]))
    system = _motorized() if system else PRESET
    q = data.draw(configurations(system))
    revolute = ~np.array(system.prismatic)
    joint = data.draw(st.sampled_from(np.flatnonzero(revolute).tolist()))
    q[joint] = data.draw(st.floats(PLAUSIBLE_REVOLUTE * 1.001, 359.0)) * data.draw(st.sampled_from([1.0, -1.0]))
    with pytest.raises(InvalidConfigurationError, match=rf"q\[{joint}\] .* given in degrees\? "):
        system.fk(q)
    system.fk(q, check_units=False)  # the solvers' path takes it (an overflow guard only)


def test_an_ik_branch_far_out_of_range_still_gets_its_pose():
    """Near singular case (c) the analytic IK's branches reach metres to kilometres: the IK and the validity
    check evaluate them through ``check_units=False`` and report them out of range, never refuse the call."""
    from carmkin import analytic_ik
    from carmkin.robot import validity

    system = PRESET
    T = system.fk([0.0, 0.2, 0.0, 0.1, 0.0, 0.0])
    T = T.copy()
    T[:3, 3] += (500.0, -300.0, 200.0)  # a pose 600 m away: exact branches with joint values of hundreds of m
    result = analytic_ik.solve(system, T)
    assert np.abs(result.solutions).max() > PLAUSIBLE_PRISMATIC
    for q in result.solutions:
        assert not validity.check(system, q).reachable


@pytest.mark.parametrize("make, words", [
    (lambda: Obstacle.box("patient", (500.0, 300.0, 1600.0)), ("'patient'", "size 500 m", "given in mm? 500 mm = 0.5 m")),
    (lambda: Obstacle("head", "sphere", (90.0,)), ("'head'", "size 90 m", "given in mm? 90 mm = 0.09 m")),
    (lambda: Obstacle.box("torso", (0.4, 0.25, 0.7), (0.0, 320.0, 100.0)), ("'torso'", "centre", "given in mm? 320 mm")),
])
def test_an_obstacle_in_mm_is_refused_naming_the_slip(make, words):
    with pytest.raises(CollisionSceneError) as info:
        make()
    for word in words:
        assert word in str(info.value), (word, str(info.value))


@settings(max_examples=50)
@given(st.lists(st.floats(0.02, 2.0), min_size=3, max_size=3))
def test_a_body_sized_box_in_m_is_taken_and_the_same_in_mm_is_not(size_m):
    assert Obstacle.box("b", size_m).size == tuple(size_m)
    with pytest.raises(CollisionSceneError, match=r"given in mm\?"):  # 20 mm and more read as m: beyond 10 m
        Obstacle.box("b", [s * 1000.0 for s in size_m])


@settings(max_examples=40)
@given(st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3))
def test_a_target_in_mm_is_refused_when_no_metre_target_could_mean_it(target_m):
    from carmkin.validation import MAX_DISTANCE, target_point

    assert target_point(target_m, "target").tolist() == target_m
    target_mm = [v * 1000.0 for v in target_m]
    if max(map(abs, target_mm)) <= MAX_DISTANCE:  # within 10 mm of the origin: a plausible point in m too
        target_point(target_mm, "target")
        return
    with pytest.raises(CarmkinError, match=r"target must lie within 10 m .* given in mm\? "):
        target_point(target_mm, "target")


def test_plan_sweep_names_a_target_in_mm_not_a_joint():
    """A sweep around (0, -100, 0) 'mm': refused on the target, before the planner's own joint values could be
    blamed (they reach 100 m when the target does)."""
    from carmkin.errors import SweepError
    from carmkin.sweeps import plan_sweep

    with pytest.raises(SweepError, match=r"^target .*given in mm\? 100 mm = 0.1 m"):
        plan_sweep(PRESET, [0.0, -100.0, 0.0], n_views=10)


def test_a_view_target_in_mm_is_refused_naming_the_slip():
    """100 mm above the origin given as (0, -100, 0): the view says "given in mm?" instead of a 20 s search
    ending in "unreachable"."""
    from carmkin.errors import ViewError
    from carmkin.views import View

    with pytest.raises(ViewError, match=r"target .*given in mm\? 100 mm = 0\.1 m"):
        View.from_angles(0.0, 0.0, (0.0, -100.0, 0.0))
    assert View.from_angles(0.0, 0.0, (0.0, -0.1, 0.0)).target == (0.0, -0.1, 0.0)
