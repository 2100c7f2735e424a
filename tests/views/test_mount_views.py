"""The view search of a robot-held C-arm by the robot's closed form (:mod:`carmkin.views.mount`): every answer is
checked by the FK and by coal on every pair, a view of a clear configuration is found, a target out of the
robot's reach is reported with its reason, and re-planning from a plan's configuration keeps it."""

from __future__ import annotations

import numpy as np
import pytest

import carmkin
from carmkin import views
from carmkin.patient import ParametricPatient
from carmkin.views import mount as mount_search
from carmkin.world import World

ROBOT = carmkin.load_preset("robotic-carm")
PATIENT = ParametricPatient().on_table(ROBOT)
#: Beams and rolls of the closed form's answers (m, rad): :data:`carmkin.analytic.mount.RESIDUAL_TOLERANCE`.
BEAM_TOLERANCE = 1e-9
ORBITAL = ROBOT.joint_names.index("orbital")


def _check(plan, view) -> None:
    assert plan.success, plan.reason
    assert plan.solver == "closed form"
    q = plan.q
    T = ROBOT.fk(q)
    target = np.asarray(view.target)
    w = target - T[:3, 3]
    assert np.linalg.norm(T[:3, 2] - view.direction) <= BEAM_TOLERANCE
    assert np.linalg.norm(w - (w @ T[:3, 2]) * T[:3, 2]) <= BEAM_TOLERANCE
    if view.x_axis is not None:
        assert np.linalg.norm(T[:3, 0] - view.x_axis) <= BEAM_TOLERANCE
    if view.distance is not None:
        assert abs(w @ T[:3, 2] - view.distance) <= BEAM_TOLERANCE
    assert np.all(q >= ROBOT.lower - 1e-9) and np.all(q <= ROBOT.upper + 1e-9)
    assert World(ROBOT, PATIENT).distances(q=q).min() >= carmkin.DEFAULT_MARGIN - 1e-6


def test_the_preset_has_the_closed_form():
    assert mount_search.applies(ROBOT)
    assert not mount_search.applies(carmkin.load_preset("siremobile-iso-c3d"))


def test_a_view_of_a_clear_configuration_is_planned_with_its_roll_and_distance():
    """Configurations clear of table, floor and patient with the orbital slide at the reference (mid-range): the
    view of each one's beam with its roll and distance fixed is planned — its own branch is among the first
    pass's candidates — and every answer checks out."""
    rng = np.random.default_rng(11)
    world = World(ROBOT, PATIENT)
    planned = 0
    while planned < 6:
        q = ROBOT.lower + rng.random(ROBOT.nq) * (ROBOT.upper - ROBOT.lower)
        q[ORBITAL] = 0.5 * (ROBOT.lower[ORBITAL] + ROBOT.upper[ORBITAL])
        q[0] = 0.0
        if world.clearance(q[None])[0] < carmkin.DEFAULT_MARGIN + 0.01:
            continue
        T = ROBOT.fk(q)
        view = views.View(tuple(T[:3, 3] + 0.5 * T[:3, 2]), tuple(T[:3, 2]), distance=0.5, x_axis=tuple(T[:3, 0]))
        _check(views.plan_view(ROBOT, view, patient=PATIENT, qp=False, nearest=False), view)
        planned += 1


@pytest.mark.parametrize("angles", [(0.0, 0.0), (30.0, 20.0), (-60.0, -30.0), (90.0, 0.0)])
def test_a_view_with_a_free_roll_is_planned_and_replanning_from_it_keeps_it(angles):
    view = views.View.from_angles(*angles, (0.0, 0.0, 0.0))
    plan = views.plan_view(ROBOT, view, patient=PATIENT, qp=False, nearest=False)
    _check(plan, view)
    again = views.plan_view(ROBOT, view, patient=PATIENT, q_current=plan.q, qp=False, nearest=False)
    _check(again, view)
    np.testing.assert_allclose(again.q, plan.q, rtol=0, atol=1e-9)
    assert not again.moves or all(move.clear for move in again.moves)


def test_a_target_out_of_the_robots_reach_is_unreachable_with_its_reason():
    """A target 4 m along the table from the robot: no sampled source pose puts the wrist centre within the arm."""
    reach = views.reach_map(ROBOT, (0.0, 0.0, 4.5), [0.0, 30.0], [0.0], patient=None)
    assert not reach.reachable.any()
    assert set(reach.binding.ravel()) == {"mount"}
    assert all("out of reach" in reason or "joint limits" in reason for reason in reach.reason.ravel())
    assert np.isnan(reach.q).all()


def test_worker_processes_give_the_answers_of_one(monkeypatch):
    """A map split over forked workers (the threshold lowered to this small map) answers as one process."""
    from carmkin.views import search

    primary, secondary = np.arange(-90.0, 91.0, 30.0), np.arange(-45.0, 46.0, 45.0)
    one = views.reach_map(ROBOT, (0.0, 0.0, 0.0), primary, secondary, patient=PATIENT, workers=1)
    monkeypatch.setattr(search, "PARALLEL_MIN_CELLS", 4)
    monkeypatch.setattr(search, "CHUNK", 5)
    two = views.reach_map(ROBOT, (0.0, 0.0, 0.0), primary, secondary, patient=PATIENT, workers=2)
    assert np.array_equal(one.q, two.q, equal_nan=True)
    assert np.array_equal(one.reachable, two.reachable) and np.array_equal(one.reason, two.reason)
    np.testing.assert_allclose(one.clearance, two.clearance, rtol=0, atol=1e-12)


def test_plan_view_asks_the_qp_when_the_closed_form_finds_nothing(monkeypatch):
    """With no sample to try (the passes emptied), the closed form leaves the AP view unreachable; plan_view's
    fallback, the QP with every joint free, reaches it (its answer held to the QP's tolerance), and with
    ``qp=False`` the view stays unreachable with the closed form's reason."""
    monkeypatch.setattr(mount_search, "_passes", lambda system, q_ref: [])
    view = views.View.from_angles(0.0, 0.0, (0.0, 0.0, 0.0))
    plain = views.plan_view(ROBOT, view, patient=PATIENT, qp=False, nearest=False)
    assert not plain.success and plain.binding == "mount"
    plan = views.plan_view(ROBOT, view, patient=PATIENT, nearest=False)
    assert plan.success and plan.solver == "qp"
    T = ROBOT.fk(plan.q)
    assert np.linalg.norm(T[:3, 2] - view.direction) <= 2e-6
    assert World(ROBOT, PATIENT).distances(q=plan.q).min() >= carmkin.DEFAULT_MARGIN - 1e-6
