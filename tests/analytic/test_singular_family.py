"""The singular family (case b: cos θ4 = 0, the orbital axis parallel to the wigwag axis) in closed form:
poses sampled exactly on it, on random non-isocentric systems; every answer checked by Pinocchio's FK (the
independent route, not the closed form under test), the batch path equal to the scalar path, θ2 taken
from q_current and θ2 ± θ5 kept."""

import math

import numpy as np
import pinocchio as pin
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import configurations, systems

import carmkin
from carmkin import analytic_ik
from carmkin.transforms import pose_error, wrap_angle

#: Residual (m, rad) every answer must reach: the round trip of the closed form.
FK_TOLERANCE = 1e-9


def pinocchio_pose(system, q):
    model = system.pinocchio()[0]
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
    return data.oMf[model.getFrameId("xray_source")].homogeneous


@st.composite
def family_cases(draw):
    system = draw(systems())
    n = draw(st.integers(1, 8))
    Q = np.array([draw(configurations(system)) for _ in range(n)])
    Q[:, 4] = np.array([draw(st.sampled_from([math.pi / 2, -math.pi / 2])) for _ in range(n)])
    q_current = draw(st.one_of(st.none(), configurations(system)))
    return system, Q, q_current


@settings(max_examples=60)
@given(family_cases())
def test_every_answer_on_the_singular_family_reaches_its_pose(case):
    system, Q, q_current = case
    T = system.fk(Q)
    batch = analytic_ik.solve_batch(system, T, q_current)
    assert batch.reached.all()
    for i in range(len(Q)):
        one = analytic_ik.solve(system, T[i], q_current)
        assert one.numerical == batch.numerical[i]
        np.testing.assert_allclose(one.solutions, batch.solutions[:, i], rtol=0, atol=1e-9)
        assert one.chosen == batch.chosen[i]
        for b in range(2):
            position, angle = pose_error(pinocchio_pose(system, batch.solutions[b, i]), T[i])
            scale = max(1.0, np.abs(batch.solutions[b, i]).max())
            assert position <= FK_TOLERANCE * scale and angle <= FK_TOLERANCE
        if not batch.numerical[i]:  # the closed form of the family answered
            assert batch.singular[i, 1]
            reference = 0.0 if q_current is None else q_current[2]
            assert abs(wrap_angle(batch.solutions[0, i, 2] - reference)) <= 1e-12
            sigma = math.copysign(1.0, math.sin(Q[i, 4]))
            for b in range(2):
                kept = batch.solutions[b, i, 2] + sigma * batch.solutions[b, i, 5] - (Q[i, 2] + sigma * Q[i, 5])
                assert abs(wrap_angle(kept)) <= 1e-9


def test_the_family_is_solved_in_closed_form_away_from_cases_a_and_c():
    """On the preset (sin γ1 = 1) every pose of the family with θ2 = q_current's is away from case c."""
    preset = carmkin.load_preset("siremobile-iso-c3d")
    rng = np.random.default_rng(7)
    Q = rng.uniform(preset.lower, preset.upper, (500, 6))
    Q[:, 4] = rng.choice([math.pi / 2, -math.pi / 2], 500)
    batch = analytic_ik.solve_batch(preset, preset.fk(Q))
    assert not batch.numerical.any() and batch.reached.all()
    assert batch.residual.max() <= FK_TOLERANCE


def test_near_the_family_the_answer_is_the_isolated_solution():
    """|cos θ4| = 1e-7: still singular by |det J|, solved in closed form, and the branch is the sampled q."""
    preset = carmkin.load_preset("siremobile-iso-c3d")
    q = np.array([0.1, 0.2, 0.05, 0.1, math.pi / 2 - 1e-7, 0.3])
    result = analytic_ik.solve(preset, preset.fk(q))
    assert result.singular and not result.numerical
    assert min(np.abs(wrap_angle(s - q)).max() for s in result.solutions) <= 1e-6
    assert max(b.residual for b in result.branches) <= FK_TOLERANCE
