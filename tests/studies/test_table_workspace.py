"""Generalised workspace study over table DOFs (issue 9): desired poses, reach per model, CLI."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import carmkin
from carmkin.commands import workspace as workspace_command
from carmkin.world import World
from carmkin.studies import table_workspace as tw

MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")


def test_desired_configurations_in_range_collision_free_and_seeded():
    qs = tw.desired_configurations(MOTORIZED, 12, seed=3)
    assert qs.shape == (12, MOTORIZED.nq)
    assert np.all(qs >= MOTORIZED.lower) and np.all(qs <= MOTORIZED.upper)
    scene = World(MOTORIZED)
    assert min(scene.distances(q=q).min() for q in qs) >= 0.01
    assert np.array_equal(qs, tw.desired_configurations(MOTORIZED, 12, seed=3))
    assert not np.array_equal(qs, tw.desired_configurations(MOTORIZED, 12, seed=4))


@settings(max_examples=10, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=5, max_size=5).map(np.array))
def test_carm_alone_reaches_poses_of_its_own_configurations(u):
    """Poses generated with every table joint at zero are reached by the C-arm alone (5-DOF closed form)."""
    q = np.zeros(MOTORIZED.nq)
    q[-5:] = MOTORIZED.lower[-5:] + u * (MOTORIZED.upper[-5:] - MOTORIZED.lower[-5:])
    scene = World(MOTORIZED)
    assume(scene.distances(q=q).min() >= 0.01)
    assert tw.reachable(MOTORIZED, MOTORIZED.fk(q), "none", random_seeds=0)


def test_far_pose_is_reachable_by_no_model():
    """A source 3 m above the C-arm base is out of reach of every model (ranges of ±0.2 m at most)."""
    T = MOTORIZED.fk(np.zeros(MOTORIZED.nq))
    T[1, 3] -= 3.0  # Y0 points down
    for model in tw.MODELS:
        assert not tw.reachable(MOTORIZED, T, model, random_seeds=1)


def test_unknown_model_and_missing_joints_raise():
    with pytest.raises(tw.TableWorkspaceError):
        tw.run_study(MOTORIZED, ("floor",), n=1)
    with pytest.raises(tw.TableWorkspaceError, match="lacks"):
        tw.reachable(carmkin.load_preset("siremobile-iso-c3d"), np.eye(4), "translations")
    # "all" frees every table joint the system has: an angiography table has no rotation
    assert set(tw.free_joints(carmkin.load_preset("angio-floor"), "all")) == set(tw.MODELS["all"]) - {"table_rotation"}
    with pytest.raises(tw.TableWorkspaceError):
        tw.desired_configurations(MOTORIZED, 0)


def test_cli_compare_prints_four_rows(capsys, tmp_path):
    import argparse

    parser = argparse.ArgumentParser()
    workspace_command.register(parser)
    args = parser.parse_args(["--table-dofs", "compare", "--poses", "4", "--random-seeds", "1",
                              "--png", str(tmp_path / "reach.png"), "--json", str(tmp_path / "reach.json")])
    assert workspace_command.run(args) == 0
    out = capsys.readouterr().out
    for model in tw.MODELS:
        assert any(line.startswith(model + " ") for line in out.splitlines())
    assert (tmp_path / "reach.png").stat().st_size > 0
    import json

    data = json.loads((tmp_path / "reach.json").read_text())
    assert set(data) == set(tw.MODELS) and all(v["poses"] == 4 for v in data.values())


def test_nested_models_are_proper_subsets():
    assert tw.nested_in("none") == ()
    assert tw.nested_in("all") == ("none", "paper", "translations")
    for model in tw.MODELS:
        for smaller in tw.nested_in(model):
            assert set(tw.MODELS[smaller]) < set(tw.MODELS[model])


def test_worker_processes_and_nested_rows_give_the_answers_of_one_process():
    """The speed-ups change no answer: the reach bound, two worker processes and skipping poses reached by a
    nested model give, pose by pose, what one process solving every pose of every row gives."""
    kwargs = dict(n=8, seed=5, random_seeds=1)
    qs_one, one = tw.run_study(MOTORIZED, workers=1, nested=False, bound=False, **kwargs)
    qs_two, two = tw.run_study(MOTORIZED, workers=2, nested=True, bound=True, **kwargs)
    assert np.array_equal(qs_one, qs_two)
    assert [r.model for r in one] == [r.model for r in two] == list(tw.MODELS)
    for a, b in zip(one, two):
        assert np.array_equal(a.reached, b.reached), a.model
    for r in one:  # a witness of a nested model is a witness of the larger one
        for smaller in tw.nested_in(r.model):
            assert np.all(r.reached >= one[list(tw.MODELS).index(smaller)].reached)


def test_bad_worker_count_raises():
    with pytest.raises(tw.TableWorkspaceError, match="workers"):
        tw.run_study(MOTORIZED, ("none",), n=1, workers=0)
