"""The necessary condition of carmkin.studies.reach_bound: its identities, and that it never refuses a target
some in-range configuration reaches (soundness), on random geometries and motorized tables."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import finite, geometries, motorized_systems

import carmkin
from carmkin.analytic import five_dof
from carmkin.model.params import CARM_JOINT_NAMES
from carmkin.studies import reach_bound
from carmkin.studies import table_workspace as tw

MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
#: Round-off allowed in the identities (m): sums of products of metre-sized terms.
ROUND_OFF = 1e-12


@given(geometries(), st.lists(st.floats(-np.pi, np.pi, **finite), min_size=5, max_size=5))
def test_vertical_and_horizontal_identities_hold_in_the_base_frame(carm, values):
    """p_z + L a_z − d1 and p_xy + L a_xy − (M + d3) Rz(θ2) e_y are at most |a1| + |a2| long (closed-form FK)."""
    d1, theta2, d3 = values[0] / 10, values[1], values[2] / 10
    p, a = (v[0] for v in five_dof.forward(carm, [d1, theta2, d3, values[3], values[4]]))
    L, M, delta = carm.source_to_orbital_axis, carm.arm_length, abs(carm.a1) + abs(carm.a2)
    assert abs(p[2] + L * a[2] - d1) <= delta + ROUND_OFF
    arm = (M + d3) * np.array([-np.sin(theta2), np.cos(theta2)])
    assert np.linalg.norm(p[:2] + L * a[:2] - arm) <= delta + ROUND_OFF


def _in_range(draw, joint_range):
    lo, hi = joint_range.lower, joint_range.upper
    return draw(st.one_of(st.floats(lo, hi, **finite), st.sampled_from([lo, hi])))


@settings(deadline=None)
@given(motorized_systems(), st.data())
def test_never_refuses_a_reachable_target(system, data):
    """The pose of any configuration moving only the C-arm and table translations (others at zero), limits
    included, is never called out of reach, for every geometry and table."""
    free = [n for n, p in zip(system.joint_names, system.prismatic) if p or n in CARM_JOINT_NAMES]
    q = np.zeros(system.nq)
    for i, name in enumerate(system.joint_names):
        if name in free:
            q[i] = _in_range(data.draw, system.joint_ranges[i])
    assert not reach_bound.cannot_reach(system, system.fk(q), free)


@given(st.sampled_from(["none", "paper", "translations"]), st.data())
def test_never_refuses_a_reachable_target_of_a_study_model(model, data):
    q = np.zeros(MOTORIZED.nq)
    for i, name in enumerate(MOTORIZED.joint_names):
        if name in tw.MODELS[model]:
            q[i] = _in_range(data.draw, MOTORIZED.joint_ranges[i])
    assert not reach_bound.cannot_reach(MOTORIZED, MOTORIZED.fk(q), tw.MODELS[model])


def test_refuses_far_targets_and_says_nothing_for_tilts():
    """A source 3 m above its rest pose is out of every translation model's reach; with tilts or the table
    rotation free the condition does not apply (False: cannot tell)."""
    T = MOTORIZED.fk(np.zeros(MOTORIZED.nq))
    T[1, 3] -= 3.0  # Y0 points down
    for model in ("none", "paper", "translations"):
        assert reach_bound.cannot_reach(MOTORIZED, T, tw.MODELS[model])
    assert not reach_bound.cannot_reach(MOTORIZED, T, tw.MODELS["all"])


def test_decides_most_misses_of_the_paper_model():
    """On 40 study poses the bound proves out of reach only poses the QP misses too, and proves some."""
    poses = MOTORIZED.fk(tw.desired_configurations(MOTORIZED, 40, seed=0))
    refused = [k for k, T in enumerate(poses) if reach_bound.cannot_reach(MOTORIZED, T, tw.MODELS["paper"])]
    assert refused
    assert not any(tw.reachable(MOTORIZED, poses[k], "paper", random_seeds=0, bound=False) for k in refused[:8])
