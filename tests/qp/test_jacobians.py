"""Finite-difference checks of every task Jacobian and of the collision rows' distance Jacobian (as pink's
and mink's tests/test_jacobians.py): central differences at hypothesis-drawn configurations and targets, on
the plain and the motorized preset."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from strategies import PRESET

import carmkin
from carmkin.qp.tasks import AimTask, AxisTask, PoseTask
from carmkin.world import World

MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
SYSTEMS = {"plain": PRESET, "motorized": MOTORIZED}
#: Central-difference step (m or rad) and the agreement asked of the analytic Jacobian: truncation error
#: ~ EPS² · |third derivative| and round-off ~ 1e-16 / EPS, both far below it.
EPS = 1e-6
JACOBIAN_TOLERANCE = 1e-6
#: Distances come from coal's GJK, converged to a tolerance, not to round-off: a larger step keeps that noise
#: small in the differences, a pair counts as smooth at q when central differences with two steps agree, and
#: the tolerance (1e-4, against O(0.1–1) for a wrong sign, support mask or witness point) covers what noise
#: is left.
DISTANCE_EPS, DISTANCE_SMOOTHNESS, DISTANCE_TOLERANCE = 1e-4, 1e-6, 1e-4
#: One-sided slopes differing by more than this (EPS · |d''| of a smooth pair is far below) mark a kink.
DISTANCE_KINK = 1e-3


def unit(n):
    return st.lists(st.floats(0.0, 1.0), min_size=n, max_size=n).map(np.array)


def in_range(system, u):
    return system.lower + u * (system.upper - system.lower)


def evaluate(model, data, q):
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)


def central_difference(model, f, q):
    """(dim, nv) central differences of ``f(data)`` (called after FK at q ± EPS e_i)."""
    data = model.createData()
    columns = []
    for i in range(model.nv):
        e = np.zeros(model.nv)
        e[i] = EPS
        evaluate(model, data, q + e)
        plus = np.array(f(data), dtype=float)
        evaluate(model, data, q - e)
        minus = np.array(f(data), dtype=float)
        columns.append((plus - minus) / (2 * EPS))
    return np.array(columns).T


def analytic(model, task, q, which="residual"):
    data = model.createData()
    evaluate(model, data, q)
    return getattr(task, which)(model, data)


def tasks_of(model, T, point, distance):
    return {
        "pose": PoseTask(model, "xray_source", T),
        "axis": AxisTask(model, "xray_source", T[:3, 3], T[:3, 2]),
        "aim": AimTask(model, "xray_source", point, (distance - 0.1, distance + 0.1)),
    }


@pytest.mark.parametrize("name", SYSTEMS)
@pytest.mark.parametrize("kind", ("pose", "axis", "aim"))
@settings(max_examples=20, deadline=None)
@given(data=st.data())
def test_task_jacobians_match_central_differences(name, kind, data):
    system = SYSTEMS[name]
    model = system.pinocchio()[0]
    q = in_range(system, data.draw(unit(system.nq), label="q"))
    target_q = in_range(system, data.draw(unit(system.nq), label="target q"))
    distance = data.draw(st.floats(0.3, 1.2), label="aim distance")
    T = system.fk(target_q)
    task = tasks_of(model, T, T[:3, 3] + distance * T[:3, 2], distance)[kind]
    if kind == "pose":  # log6 is smooth away from a half turn between the pose and the target
        angle = np.linalg.norm(pin.log3(T[:3, :3].T @ system.fk(q)[:3, :3]))
        assume(angle < np.pi - 0.1)
    J, _ = analytic(model, task, q)
    numeric = central_difference(model, lambda d: task.residual(model, d)[1], q)
    assert np.abs(J - numeric).max() <= JACOBIAN_TOLERANCE * max(1.0, np.abs(numeric).max())
    rows = analytic(model, task, q, "inequalities")
    if rows is not None:  # the aim task's distance bounds: h = [hi - s, s - lo], G = [ds, -ds]
        G, _ = rows
        numeric_h = central_difference(model, lambda d: task.inequalities(model, d)[1], q)
        assert np.abs(G + numeric_h).max() <= JACOBIAN_TOLERANCE * max(1.0, np.abs(numeric_h).max())


@pytest.mark.parametrize("name", SYSTEMS)
@settings(max_examples=20, deadline=None)
@given(data=st.data())
def test_distance_jacobian_matches_central_differences(name, data):
    """Rows of d(distance)/dq from coal's witness points and normals against differences of the distances,
    for the separated pairs where the distance is smooth (one-sided differences agree)."""
    system = SYSTEMS[name]
    scene = World(system)
    model = scene.model
    q = in_range(system, data.draw(unit(system.nq), label="q"))
    state = model.createData()
    evaluate(model, state, q)
    d = scene.distances(state)
    near = scene.proximity(d, np.inf)
    J = scene.distance_jacobian(near, state.J)
    probe = model.createData()

    def differences(step):
        """(forward, backward) differences (n_pairs, nv) with ``step``."""
        forward, backward = [], []
        for i in range(model.nv):
            e = np.zeros(model.nv)
            e[i] = step
            forward.append((scene.distances(probe, q=q + e) - d) / step)
            backward.append((d - scene.distances(probe, q=q - e)) / step)
        return np.array(forward).T, np.array(backward).T

    forward, backward = differences(DISTANCE_EPS)
    coarse = 0.5 * (forward + backward)
    fine = 0.5 * np.add(*differences(DISTANCE_EPS / 2))
    # Smooth where the slopes on both sides agree (parallel faces give a kink: left and right slopes differ,
    # while central differences of |x| agree with each other) and central differences with two steps agree.
    smooth = ((d > 1e-3)[:, None] & (np.abs(forward - backward) < DISTANCE_KINK)
              & (np.abs(coarse - fine) < DISTANCE_SMOOTHNESS))
    assume(smooth.sum() > 0)
    central = fine
    assert np.abs(J - central)[smooth].max() <= DISTANCE_TOLERANCE
