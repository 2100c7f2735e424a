"""Broad phase + exact narrow phase (carmkin.world.bounds: World.clearance / World.nearest) against every pair's
coal distance computed by Pinocchio's computeDistances through World.distances (the independent route): the bounds never exceed a distance, the
smallest distance is the same number, the pairs below a margin are the same pairs."""

import coal
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from strategies import motorized_systems, systems

import carmkin
from carmkin.errors import InvalidConfigurationError
from carmkin.model.sampling import random_configurations
from carmkin.world import Obstacle, World
from carmkin.world.tolerances import BOUND_SLACK

#: Two coal calls on the same pair agree to its GJK/EPA tolerance (1e-6 m), not to the last digit: the
#: result depends on the initial guess each caller keeps (measured: 3.4e-7 m). Exact means this.
SAME_DISTANCE = BOUND_SLACK


def obstacles(rng):
    """A patient-like box, a capsule and a sphere, placed at random near the isocentre (table frame, m)."""
    return [
        Obstacle.box("body", rng.uniform(0.1, 0.5, 3), rng.uniform(-0.4, 0.4, 3)),
        Obstacle.capsule("arm", rng.uniform(0.03, 0.1), rng.uniform(0.1, 0.6), rng.uniform(-0.5, 0.5, 3)),
        Obstacle("head", "sphere", (float(rng.uniform(0.05, 0.15)),), np.eye(4)),
    ]


def degenerate(scene) -> bool:
    """A box of the generated collision model with a negative size (the xacro once sized the inner arm
    ``0.9 arm_length - (R + c_thickness + 0.08)``, negative for short arms, and coal's distances to such a box
    depended on the previous query); the xacro now keeps a stub of 0.1 arm_length, so this never holds."""
    return any(isinstance(g.geometry, coal.Box) and np.any(g.geometry.halfSide < 0)
               for g in scene.geometry_model.geometryObjects)


def check_scene(system, seed: int, n: int = 40, property_based: bool = True):
    rng = np.random.default_rng(seed)
    scene = World(system, obstacles(rng))
    assert not degenerate(scene)
    bounded = scene.bounds
    qs = random_configurations(rng, system, n, beyond=0.0)
    full = np.array([scene.distances(q=q) for q in qs])
    bounds = bounded.lower_bounds(qs)
    assert np.all(bounds <= full), "a bound above coal's distance"
    distance, pair = bounded.nearest(qs)
    np.testing.assert_allclose(distance, full.min(axis=1), rtol=0, atol=SAME_DISTANCE)
    np.testing.assert_allclose(full[np.arange(n), pair], full.min(axis=1), rtol=0, atol=SAME_DISTANCE)
    np.testing.assert_allclose(scene.clearance(qs), distance, rtol=0, atol=SAME_DISTANCE)
    margin = float(rng.uniform(0.0, 0.1))
    cheap = scene.clearance(qs, exact_below=margin)
    below = full.min(axis=1) < margin
    np.testing.assert_allclose(cheap[below], full.min(axis=1)[below], rtol=0, atol=SAME_DISTANCE)
    assert np.all(cheap[~below] >= margin - SAME_DISTANCE)
    assert np.all(cheap[~below] <= full.min(axis=1)[~below] + SAME_DISTANCE)
    # With a stop: a distance below it is its pair's own; one above it is the smallest.
    stopped, stop_pair = scene.nearest(qs, stop_below=margin)
    hit = stopped < margin
    np.testing.assert_allclose(stopped[hit], full[hit, stop_pair[hit]], rtol=0, atol=SAME_DISTANCE)
    np.testing.assert_allclose(stopped[~hit], full[~hit].min(axis=1), rtol=0, atol=SAME_DISTANCE)
    assert np.array_equal(hit, below | (stopped < margin))


@settings(max_examples=10)
@given(systems(), st.integers(0, 2**32 - 1))
def test_bounds_and_exact_distances_on_random_non_isocentric_systems(system, seed):
    check_scene(system, seed)


@settings(max_examples=5)
@given(motorized_systems(min_joints=1), st.integers(0, 2**32 - 1))
def test_bounds_and_exact_distances_on_motorized_tables(system, seed):
    check_scene(system, seed)


def test_motorized_preset():
    check_scene(carmkin.load_preset("siremobile-iso-c3d-motorized-table"), 3, n=100, property_based=False)


def test_robot_held_preset():
    """The robot's bodies (mount frames computed once per configuration, :func:`carmkin.world.bounds.link_poses`)
    against coal on every pair."""
    check_scene(carmkin.load_preset("robotic-carm"), 5, n=60, property_based=False)


def test_link_poses_of_a_robot_are_the_systems_frames():
    from carmkin.world.bounds import link_poses

    system = carmkin.load_preset("robotic-carm")
    qs = random_configurations(np.random.default_rng(2), system, 20, beyond=0.0)
    frames, sources = link_poses(system, qs)
    np.testing.assert_allclose(frames[:, 7:], system.mount_frames(qs), rtol=0, atol=1e-12)
    np.testing.assert_allclose(frames[:, :6], system.dh_frames(qs), rtol=0, atol=1e-12)
    np.testing.assert_allclose(sources, system.fk(qs), rtol=0, atol=1e-12)


def test_bad_configurations_are_refused():
    system = carmkin.load_preset("siremobile-iso-c3d")
    world = World(system)
    for bad in (np.zeros(5), np.full((2, 6), np.nan), np.zeros((2, 2, 6))):
        for call in (world.clearance, world.nearest, world.bounds.lower_bounds):
            with pytest.raises(InvalidConfigurationError, match="qs"):
                call(bad)
