"""The motion certificate (issue 37): a segment it calls clear keeps the threshold at dense exact samples (0.05° /
0.05 mm), a violation it reports is one, and the path minimum it certifies is at most every exact sample and
within the stated tolerance of the smallest — on the Iso-C 3D, the motorized table and the robot-held C-arm, with
a patient; checked by an independent route (world.distances on every pair at every dense sample)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import carmkin
from carmkin.motion import END_TOLERANCE, Certifier
from carmkin.patient import ParametricPatient
from carmkin.world import DEFAULT_TOLERANCE, World
from carmkin.world.tolerances import DISTANCE_ACCURACY

#: Dense sampling of the acceptance: 0.05° of any revolute joint, 0.05 mm of any prismatic joint per step.
DENSE_ANGLE, DENSE_LENGTH = math.radians(0.05), 5e-5
PRESETS = ("siremobile-iso-c3d", "siremobile-iso-c3d-motorized-table", "robotic-carm", "angio-floor")


def world_of(name):
    system = carmkin.load_preset(name)
    return World(system, ParametricPatient.on_table(system))


WORLDS = {}


def get_world(name):
    if name not in WORLDS:
        WORLDS[name] = world_of(name)
    return WORLDS[name]


def dense_distances(world, q_a, q_b, max_samples=4000):
    """(n, ) smallest exact distance at dense samples of q_a → q_b (every pair), and the sample count."""
    system = world.system
    step = np.where(system.prismatic, DENSE_LENGTH, DENSE_ANGLE)
    n = max(1, int(np.ceil(np.max(np.abs(q_b - q_a) / step))))
    n = min(n, max_samples)
    t = np.linspace(0.0, 1.0, n + 1)
    return np.array([world.distances(q=q_a + s * (q_b - q_a)).min() for s in t]), t


def random_pair(rng, system, reach):
    lo, hi = system.lower, system.upper
    q_a = rng.uniform(lo, hi)
    q_b = np.clip(q_a + rng.uniform(-reach, reach, system.nq) * (hi - lo), lo, hi)
    return q_a, q_b


@pytest.mark.parametrize("name", PRESETS)
@settings(max_examples=6, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**31 - 1), threshold=st.sampled_from([-0.05, 0.0, 0.01, 0.05]))
def test_clear_segments_keep_the_threshold_at_dense_samples(name, seed, threshold):
    world = get_world(name)
    cert = Certifier.for_world(world)
    rng = np.random.default_rng(seed)
    q_a, q_b = random_pair(rng, world.system, 0.15)
    d_a, d_b = world.distances(q=q_a).copy(), world.distances(q=q_b).copy()
    check = cert.segment(q_a, q_b, d_a, d_b, threshold)
    dense, t = dense_distances(world, q_a, q_b)
    if check.clear:
        assert dense.min() >= threshold - END_TOLERANCE - DISTANCE_ACCURACY
        assert check.bound <= dense.min() + DISTANCE_ACCURACY  # a lower bound of the sampled distances
    if check.violation:  # a violation it reports is a real sample below the threshold
        q = q_a + check.t * (q_b - q_a)
        assert world.distances(q=q).min() < threshold


@pytest.mark.parametrize("name", PRESETS[:2])
@settings(max_examples=4, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**31 - 1))
def test_path_minimum_is_certified_and_tight(name, seed):
    world = get_world(name)
    cert = Certifier.for_world(world)
    rng = np.random.default_rng(seed)
    q0, q1 = random_pair(rng, world.system, 0.1)
    q2 = np.clip(q1 + rng.uniform(-0.05, 0.05, world.system.nq) * (world.system.upper - world.system.lower),
                 world.system.lower, world.system.upper)
    Q = np.array([q0, q1, q2])
    bound, segment, pair, t = cert.minimum(Q)
    dense = [dense_distances(world, Q[i], Q[i + 1]) for i in range(2)]
    samples = np.concatenate([d for d, _ in dense])
    assert bound <= samples.min() + DISTANCE_ACCURACY
    # within the tolerance of the true minimum; the true minimum lies at most L h / 2 below the smallest sample
    # (the chain speed bounds, h the samples' spacing in t), an independent Lipschitz argument
    gap = max(float(cert.rates(Q[i], Q[i + 1]).max()) * (t[1] - t[0]) / 2 for i, (_, t) in enumerate(dense))
    assert bound >= samples.min() - gap - DEFAULT_TOLERANCE - 2 * DISTANCE_ACCURACY


def test_uncertifiable_segment_through_the_table_is_refused():
    """A segment that passes through the table: not clear, and its violation is a real one."""
    world = get_world("siremobile-iso-c3d")
    system = world.system
    cert = Certifier.for_world(world)
    q_a = np.zeros(system.nq)
    q_a[system.joint_names.index("vertical")] = 0.2
    q_b = q_a.copy()
    q_b[system.joint_names.index("angular")] = math.radians(90.0)
    check = cert.segment(q_a, q_b, world.distances(q=q_a).copy(), world.distances(q=q_b).copy(), 0.01)
    dense, _ = dense_distances(world, q_a, q_b)
    assert dense.min() < 0.01  # the route says the segment does not keep 10 mm
    assert not check.clear
