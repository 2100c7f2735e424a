"""The parts of the view search against independent routes: the batched exact clearance against a fresh
collision scene's full computation, the certified contact regions against coal at the configurations they
skip, the closed-form roll against the FK, and the worker processes against one process."""

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import configurations, motorized_systems, systems, unit_vectors

import carmkin
from carmkin.errors import ViewError
from carmkin.patient import ParametricPatient
from carmkin.studies.acceptance import family
from carmkin.world import World
from carmkin.world.tolerances import DISTANCE_ACCURACY
from carmkin.views import View, closed_form, reach_map, search
from carmkin.views.regions import Regions

#: Two coal calls on one pair agree to this (m): GJK's initial guess differs with the order of the calls.
SAME_CALL = DISTANCE_ACCURACY
#: The closed-form roll and the FK's source x axis agree to this (rad).
ROLL_TOLERANCE = 1e-9


def _world(system):
    patient = ParametricPatient.on_table(system)
    return World(system, patient.obstacles()), World(system, patient.obstacles())


@pytest.mark.parametrize("name", carmkin.list_presets())
def test_clearances_are_the_minimum_over_all_pairs(name):
    system = carmkin.load_preset(name)
    world, scene = _world(system)
    rng = np.random.default_rng(1)
    Q = system.lower + rng.random((300, system.nq)) * (system.upper - system.lower)
    d, pair = world.nearest(Q)
    full = np.array([scene.distances(q=q) for q in Q])
    np.testing.assert_allclose(d, full.min(axis=1), rtol=0, atol=SAME_CALL)
    # the pair named is a nearest one (two C segments may tie to the table: angio-ceiling's, 1e-17 m apart)
    np.testing.assert_allclose(full[np.arange(len(Q)), pair], full.min(axis=1), rtol=0, atol=SAME_CALL)
    # With a stop, a distance below it is some pair's own distance; one above it is still the minimum.
    stop = np.median(d)
    d_stop, pair_stop = world.nearest(Q, stop_below=stop)
    below = d_stop < stop
    np.testing.assert_allclose(d_stop[below], full[below, pair_stop[below]], rtol=0, atol=SAME_CALL)
    np.testing.assert_allclose(d_stop[~below], full[~below].min(axis=1), rtol=0, atol=SAME_CALL)
    assert below.any() and (~below).any()


@settings(max_examples=12, deadline=None)
@given(st.data())
def test_clearances_on_random_systems(data):
    system = data.draw(st.one_of(systems(), motorized_systems(min_joints=1)))
    world, scene = _world(system)
    Q = np.array([data.draw(configurations(system)) for _ in range(20)])
    d, _ = world.nearest(Q)
    np.testing.assert_allclose(d, [scene.distances(q=q).min() for q in Q], rtol=0, atol=SAME_CALL)


def _cell_candidates(system, q_ref, target, direction):
    """Configurations of the view (target, direction) as the search's closed form gives them: every wigwag
    sample, several distances per family."""
    frame = system.carm_base_pose if not system.table.joints else (
        system.table_motion(system.split(q_ref)[1]) @ system.carm_base_pose)
    fam = closed_form.families(system, target[None], direction[None], np.linspace(system.lower[system.nq - 4],
                               system.upper[system.nq - 4], 41), frame, q_ref, np.array([[0.0, 2.0]]))
    idx = np.nonzero(fam.feasible)
    Q = [closed_form.joints(system, fam, idx, fam.lo[idx] + f * (fam.hi[idx] - fam.lo[idx]), q_ref)
         for f in np.linspace(0.0, 1.0, 7)]
    return np.vstack(Q)


def _where(system, Q, target, direction):
    """(s, ρ) of configurations Q by the FK: distance source → target along the beam, roll of the source's x
    axis about it in the search's basis."""
    T = system.fk(Q)
    e1, e2 = search._roll_basis(direction[None])
    s = (target - T[:, :3, 3]) @ direction
    x = T[:, :3, 0]
    return np.stack((s, np.arctan2(x @ e2[0], x @ e1[0])), axis=1)


def _claimed(system, target, direction, margin):
    """Regions from every other candidate of the view; returns (claimed, candidates) after checking that a
    fresh scene (coal, every pair) finds each claimed candidate closer than the margin."""
    world, scene = _world(system)
    Q = _cell_candidates(system, np.clip(np.zeros(system.nq), system.lower, system.upper), target, direction)
    where = _where(system, Q, target, direction)
    regions = Regions(world, margin)
    d, pair = world.nearest(Q[::2], stop_below=margin)
    regions.add(np.zeros(len(d), dtype=int), where[::2], d, pair)
    inside = regions.contain(np.zeros(len(Q[1::2]), dtype=int), where[1::2])
    for q in Q[1::2][inside]:
        assert scene.distances(q=q).min() < margin
    # Another cell's regions never claim these candidates.
    assert not regions.contain(np.ones(len(Q[1::2]), dtype=int), where[1::2]).any()
    return int(inside.sum()), len(inside)


#: The mobile C-arms beside the table, whose C touches the table in the steep views below (an angiography
#: stand at the head end keeps its C clear of the table there).
MOBILE = [name for name in carmkin.list_presets() if family(carmkin.load_preset(name)) == "mobile"]


@pytest.mark.parametrize("name", MOBILE)
def test_regions_only_skip_configurations_that_touch(name):
    """Views of the table origin that touch (steep LAO with tilt, the C-arc against the table): the regions
    claim many candidates, and every one touches."""
    system = carmkin.load_preset(name)
    claimed = total = 0
    for p, s in ((60, 30), (75, -30), (45, 40), (80, 20)):
        view = View.from_angles(p, s, (0.0, 0.0, 0.0), "HFS")
        c, n = _claimed(system, np.asarray(view.target), np.asarray(view.direction), 0.02)
        claimed, total = claimed + c, total + n
    print(f"\n{name}: regions claimed {claimed} of {total} candidates; coal finds each one touching")
    if total == 0 and system.nq > 6:  # the C-arm's own joints locked (a robot moves the C): the QP's views only
        pytest.skip(f"{name}: the closed form gives no candidate with the C-arm's joints locked")
    assert claimed > total // 4


@settings(max_examples=15, deadline=None)
@given(st.data())
def test_regions_on_random_systems(data):
    system = data.draw(st.one_of(systems(), motorized_systems(min_joints=1)))
    direction = data.draw(unit_vectors())
    _claimed(system, np.zeros(3), direction, data.draw(st.sampled_from((0.02, 0.2, 0.5))))


@settings(max_examples=30, deadline=None)
@given(st.data(), st.floats(0.3, 1.0))
def test_the_closed_form_roll_is_the_fk_roll(data, s0):
    system = data.draw(st.one_of(systems(), motorized_systems(min_joints=1)))
    q0 = data.draw(configurations(system))
    T = system.fk(q0)
    target, direction = T[:3, 3] + s0 * T[:3, 2], T[:3, 2]
    world, _ = _world(system)
    ctx = search.make_context(system, world, 0.02, q0, [q0])
    ctx = dataclasses.replace(ctx, theta2=np.r_[ctx.theta2, q0[system.nq - 4]])  # q0's own wigwag among the samples
    state = search._State.empty(1, system.nq, Regions(world, 0.02))
    free_roll = np.full((1, 3), np.nan)
    chunk = search._chunk(ctx, target[None], direction[None], np.array([[0.0, 2.0]]), free_roll, np.arange(1), state)
    cand = search._candidates(ctx, chunk, range(len(search.DISTANCE_CHOICES) + 1))
    assert cand is not None  # q0's own family is feasible
    _, _, _, Q, _, where = cand
    fk = _where(system, Q, target, direction)
    np.testing.assert_allclose(where[:, 0], fk[:, 0], rtol=0, atol=1e-9)
    assert np.max(np.abs(np.angle(np.exp(1j * (where[:, 1] - fk[:, 1]))))) < ROLL_TOLERANCE


def test_workers_do_not_change_the_map(monkeypatch):
    monkeypatch.setattr(search, "PARALLEL_MIN_CELLS", 1)
    system = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
    patient = ParametricPatient.on_table(system)
    args = (system, (0.0, 0.0, 0.0), np.arange(-90, 91, 6), np.arange(-45, 46, 9), patient)
    one, two = reach_map(*args, workers=1), reach_map(*args, workers=2)
    for field in ("reachable", "q", "reason", "binding"):
        np.testing.assert_array_equal(getattr(one, field), getattr(two, field))
    # Clearances to coal's round-off: its GJK starts from the previous query's guess (measured: 1.5e-16 m).
    for field in ("clearance", "distance"):
        np.testing.assert_allclose(getattr(one, field), getattr(two, field), rtol=0, atol=1e-12)
    assert one.reachable.any() and (~one.reachable).any()


@pytest.mark.parametrize("junk", [0, -1, 1.5, "2", True])
def test_workers_junk(junk):
    system = carmkin.load_preset("siremobile-iso-c3d")
    with pytest.raises(ViewError, match="workers"):
        reach_map(system, (0, 0, 0), [0], [0], workers=junk)
