"""The world: the documented pair list, signed distances, grouped clearance, and the distance Jacobian."""

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import PRESET

from carmkin.errors import CollisionSceneError, PatientModelError
from carmkin.robot.collision import Obstacle, carm_pair_names, link_of
from carmkin.world import World

SOURCE_HOUSING = PRESET.body.source_housing  # box in the source frame, centre at z = -hs_z/2 + 0.03


def source_point(q, local):
    """A point given in the xray_source frame, in the table frame (closed-form FK, not Pinocchio)."""
    T = PRESET.fk(q)
    return T[:3, :3] @ np.asarray(local) + T[:3, 3]


def test_pair_list_excludes_adjacent_and_irrelevant_pairs():
    scene = World(PRESET)
    links = set(scene.link_pairs())
    for excluded in [("table", "carm_cart"), ("carm_cart", "table"), ("dh_frame_3", "dh_frame_4"),
                     ("dh_frame_4", "dh_frame_3"), ("dh_frame_2", "carm_cart"), ("dh_frame_2", "floor"),
                     ("table", "floor")]:
        assert excluded not in links
    for moving in ("dh_frame_3", "dh_frame_4", "dh_frame_5", "dh_frame_6", "xray_source", "detector"):
        assert (moving, "table") in links and (moving, "floor") in links
    # every C segment and both detector boxes are paired with the table
    names = {a for a, b in scene.pairs if b == "table_0"}
    assert {f"dh_frame_6_{k}" for k in range(8)} <= names and {"detector_0", "detector_1"} <= names


def test_obstacles_are_paired_with_every_moving_part():
    box = Obstacle.box("patient", (0.4, 0.25, 1.6), (0.0, -0.1, 0.0))
    scene = World(PRESET, [box])
    plain = World(PRESET)
    moving = {a for a, _ in plain.pairs}
    assert {a for a, b in scene.pairs if b == "patient"} == moving
    assert len(scene) == len(plain) + len(moving)


def test_link_of():
    assert link_of("dh_frame_6_7") == "dh_frame_6" and link_of("table_0") == "table" and link_of("patient") == "patient"
    assert carm_pair_names(["table_0", "carm_cart_0"]) == []


@pytest.mark.parametrize("gap", [0.03, 0.005, -0.02])
def test_signed_distance_to_a_box_beside_the_source_housing(gap):
    """A 0.1 m cube placed ``gap`` beyond the housing's +X face (negative: overlapping) is at distance gap."""
    q = np.array([0.1, 0.2, 0.05, 0.1, 0.4, -0.3])
    hx, _, hz = SOURCE_HOUSING
    center = source_point(q, [hx / 2 + gap + 0.05, 0.0, -hz / 2 + 0.03])
    R = PRESET.fk(q)[:3, :3]
    scene = World(PRESET, [Obstacle.box("probe", (0.1, 0.1, 0.1), center, R)])
    distances = scene.distances(q=q)
    k = scene.pairs.index(("xray_source_0", "probe"))
    assert distances[k] == pytest.approx(gap, abs=1e-5)


def test_bad_obstacles_are_rejected():
    with pytest.raises(CollisionSceneError, match="shape"):
        Obstacle("x", "cone", (1.0,))
    with pytest.raises(CollisionSceneError, match="positive"):
        Obstacle.box("x", (0.1, -0.1, 0.1))
    with pytest.raises(CollisionSceneError, match="already used"):
        World(PRESET, [Obstacle.box("table_0", (0.1, 0.1, 0.1))])
    with pytest.raises(PatientModelError, match="patient"):
        World(PRESET, ["not an obstacle"])
    with pytest.raises(CollisionSceneError, match="system"):
        World("siremobile-iso-c3d")


def test_grouped_clearance_is_the_minimum_per_group_of_every_pair():
    """World.grouped against the pair distances grouped by hand from the pair names."""
    patient = [Obstacle.box("body", (0.4, 0.25, 1.6), (0.0, -0.1, 0.0)), Obstacle("head", "sphere", (0.1,), np.eye(4))]
    world = World(PRESET, patient)
    rng = np.random.default_rng(4)
    for _ in range(20):
        q = PRESET.lower + rng.uniform(size=6) * (PRESET.upper - PRESET.lower)
        d = world.distances(q=q)
        by_hand = {"patient": min(x for x, (_, b) in zip(d, world.pairs) if b in ("body", "head")),
                   "table": min(x for x, (_, b) in zip(d, world.pairs) if b.startswith("table_")),
                   "floor": min(x for x, (_, b) in zip(d, world.pairs) if b.startswith("floor_"))}
        assert world.grouped(q) == pytest.approx(by_hand, abs=2e-6)
        assert min(by_hand.values()) == pytest.approx(float(world.clearance(q)[0]), abs=2e-6)


@settings(max_examples=40)
@given(st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6), st.integers(0, 2**31 - 1))
def test_distance_jacobian_matches_finite_differences(u, seed):
    """d' = J dq for the near pairs, checked by central differences (box-box distances are only
    piecewise smooth: a 15 % relative tolerance; a sign or frame error gives 200 %)."""
    q = PRESET.lower + np.array(u) * (PRESET.upper - PRESET.lower)
    scene = World(PRESET, [Obstacle.box("patient", (0.4, 0.25, 1.6), (0.0, -0.1, 0.0))])
    model = scene.model
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    distances = scene.distances(data)
    near = scene.proximity(distances, 0.3)
    rows = scene.distance_jacobian(near, data.J)
    dq = np.random.default_rng(seed).normal(size=model.nv) * 1e-4
    here = distances[near.index]
    forward = scene.distances(q=q + dq)[near.index] - here
    backward = here - scene.distances(q=q - dq)[near.index]
    pred = rows @ dq
    scale = np.linalg.norm(rows, axis=1) * np.linalg.norm(dq)
    # at a kink of a box pair's distance (the witness features switch) the Jacobian is one side's derivative
    # and the central difference averages the two: each row must match the central or a one-sided difference
    ok = [np.abs(d - pred) <= 0.15 * scale + 2e-6 for d in ((forward + backward) / 2, forward, backward)]
    assert np.all(ok[0] | ok[1] | ok[2])


def test_one_policy_for_every_preset():
    """The pair list is the same documented policy whatever the table joints: the motorized preset's extra
    links (table_tilt_link, ...) carry no geometry of their own, so its pairs are the plain preset's."""
    import carmkin

    motorized = World(carmkin.load_preset("siremobile-iso-c3d-motorized-table"))
    assert motorized.pairs == World(PRESET).pairs
    for a, b in motorized.link_pairs():
        assert a in ("dh_frame_2", "dh_frame_3", "dh_frame_4", "dh_frame_5", "dh_frame_6", "xray_source", "detector")
        assert b in ("table", "floor") and (a, b) != ("dh_frame_2", "floor")
