"""The model from a measured pose (eq. 4.3) and the propagation of pose noise to γ1..3, D1..3."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from strategies import configurations, systems

import carmkin
from carmkin.reposition import model

MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
#: Agreement of two routes to the same FK (m, rad entries of 4x4 poses).
SAME = 1e-9
finite = dict(allow_nan=False, allow_infinity=False)


@given(systems(), st.data())
def test_model_from_an_exact_pose_reproduces_the_system(system, data):
    """From the true pose at any configuration and its joint readings, eq. 4.3 rebuilds the setup: the model's
    FK equals the system's everywhere (non-isocentric geometries, random setups)."""
    q_measured = data.draw(configurations(system))
    built = model.model_from_pose(system, system.fk(q_measured), q_measured)
    q_other = data.draw(configurations(system))
    np.testing.assert_allclose(built.fk(q_other), system.fk(q_other), atol=SAME)


@given(st.data())
def test_motorized_table_model_and_frozen_chain(data):
    rng_q = [data.draw(st.floats(lo, hi, **finite)) for lo, hi in zip(MOTORIZED.lower, MOTORIZED.upper)]
    q = np.array(rng_q)
    built = model.model_from_pose(MOTORIZED, MOTORIZED.fk(q), q)
    q2 = np.array([data.draw(st.floats(lo, hi, **finite)) for lo, hi in zip(MOTORIZED.lower, MOTORIZED.upper)])
    np.testing.assert_allclose(built.fk(q2), MOTORIZED.fk(q2), atol=SAME)
    q6, q_table = MOTORIZED.split(q2)
    frozen = model.frozen_table_system(MOTORIZED, q_table)
    assert frozen.nq == 6
    np.testing.assert_allclose(frozen.fk(q6), MOTORIZED.fk(q2), atol=SAME)


def test_setup_covariance_agrees_with_monte_carlo():
    from scipy.spatial.transform import Rotation

    system = carmkin.load_preset("siremobile-iso-c3d")
    q = np.array([0.1, 0.05, 0.02, 0.1, 0.1, -0.1])
    T = system.fk(q)
    sd = np.array([0.002, 0.002, 0.002, 0.001, 0.001, 0.001])  # rad, m
    cov = np.diag(sd**2)
    predicted = model.setup_covariance(system, T, q, cov)
    rng = np.random.default_rng(5)
    samples = []
    for _ in range(600):
        x = rng.normal(0.0, sd)
        T_k = T.copy()
        T_k[:3, :3] = Rotation.from_rotvec(x[:3]).as_matrix() @ T[:3, :3]
        T_k[:3, 3] += x[3:]
        samples.append(model._setup_vector(model.setup_from_pose(system, T_k, q)))
    empirical = np.cov(np.array(samples).T)
    ratio = np.diag(empirical) / np.diag(predicted)
    assert np.all((ratio > 0.8) & (ratio < 1.25)), ratio


def test_covariance_frame_change_keeps_the_trace():
    R = carmkin.load_preset("siremobile-iso-c3d").fk(np.zeros(6))[:3, :3]
    cov = np.diag([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    moved = model.to_table_frame(cov, R)
    assert np.trace(moved[:3, :3]) == np.trace(cov[:3, :3])
    assert np.allclose(moved[3:, 3:], R @ cov[3:, 3:] @ R.T)
