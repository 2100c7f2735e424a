"""One kinematic state per configuration: its pose and distances are those of independent routes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import PRESET

import carmkin
from carmkin.robot import validity
from carmkin.world import World
from carmkin.robot.state import KinematicState

MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")


@pytest.mark.parametrize("system", [PRESET, MOTORIZED], ids=["plain", "motorized"])
@settings(max_examples=15, deadline=None)
@given(data=st.data())
def test_state_agrees_with_closed_form_fk_and_fresh_distances(system, data):
    u = np.array(data.draw(st.lists(st.floats(0.0, 1.0), min_size=system.nq, max_size=system.nq)))
    q = system.lower + u * (system.upper - system.lower)
    scene = World(system)
    state = KinematicState(scene.model, q, scene)
    assert np.abs(state.source_pose - system.fk(q)).max() <= 1e-12
    fresh = World(system).distances(q=q)
    assert np.array_equal(state.distances, fresh)
    assert state.min_distance == fresh.min()
    report = validity.check(system, q, margin=0.01, world=scene, state=state)
    alone = validity.check(system, q, margin=0.01)  # its own scene and forward kinematics
    assert (report.joints, report.collisions, report.table_in_cone) == (alone.joints, alone.collisions, alone.table_in_cone)
    assert report.min_distance == alone.min_distance == fresh.min()


def test_state_of_another_configuration_is_refused():
    scene = World(PRESET)
    q = 0.5 * (PRESET.lower + PRESET.upper)
    state = KinematicState(scene.model, q, scene)
    with pytest.raises(carmkin.InvalidConfigurationError, match="another configuration"):
        validity.check(PRESET, q + 0.01, world=scene, state=state)
    with pytest.raises(carmkin.InvalidConfigurationError):
        KinematicState(scene.model, np.zeros(5))
