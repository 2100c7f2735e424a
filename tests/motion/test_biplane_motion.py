"""Both planes of a biplane moved together (issue 37): the state holds the table's and both planes' joints, the
certificate covers plane against plane as well as each plane against table, floor and patient; checked at dense
samples with the biplane world's own clearance (a different route: branch and bound between the planes)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from carmkin.biplane import BiplaneWorld, load_biplane, plan_biplane
from carmkin.motion import END_TOLERANCE, MotionPlanner
from carmkin.patient import ParametricPatient

DENSE_ANGLE, DENSE_LENGTH = math.radians(0.05), 5e-5
BIPLANE = load_biplane("angio-biplane")
PATIENT = ParametricPatient.on_table(BIPLANE.frontal)


@pytest.fixture(scope="module")
def planner():
    return MotionPlanner(BIPLANE, PATIENT)


def dense_minimum(world, Q, step_cap=600):
    prismatic = np.array(BIPLANE.prismatic)
    step = np.where(prismatic, DENSE_LENGTH, DENSE_ANGLE)
    smallest = math.inf
    for a, b in zip(Q[:-1], Q[1:]):
        n = min(step_cap, max(1, int(np.ceil(np.max(np.abs(b - a) / step)))))
        for t in np.linspace(0.0, 1.0, n + 1):
            smallest = min(smallest, world.clearance(a + t * (b - a)).minimum)
    return smallest


def test_the_state_holds_both_planes_and_the_pairs_between_them(planner):
    scene = planner.scene
    assert scene.nq == BIPLANE.nq and scene.joint_names == BIPLANE.joint_names
    assert any(a.startswith("frontal ") and b.startswith("lateral ") for a, b in scene.pair_names)
    rest = np.array(BIPLANE.rest)
    world = BiplaneWorld(BIPLANE, PATIENT)
    assert planner.certifier.distances(rest).min() == pytest.approx(world.clearance(rest).minimum, abs=2e-6)


@pytest.mark.parametrize("view", ["lao-30", "lateral-left", "rao-35-caudal-35"])
def test_a_standard_pair_is_reached_from_rest_with_the_planes_certified_clear(planner, view):
    plan = plan_biplane(BIPLANE, view, patient=PATIENT, q_current=np.array(BIPLANE.rest))
    assert plan.success and plan.motion is not None and plan.motion.success, plan.motion
    trajectory = planner.plan(np.array(BIPLANE.rest), plan.q)
    assert trajectory.success
    world = BiplaneWorld(BIPLANE, PATIENT)
    smallest = dense_minimum(world, trajectory.waypoints)
    assert smallest >= planner.margin - END_TOLERANCE - 2e-6
    assert trajectory.min_clearance <= smallest + 2e-6
