"""The one vocabulary of singular cases (§4.3.2) and eq. 4.7's factors, shared by singularity, analytic IK and
the workspace study."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import configurations, systems

from carmkin import analytic_ik
from carmkin import singularity as sing
from carmkin.model import singular_cases
from carmkin.model.singular_cases import CASES, SingularCase


def test_one_vocabulary_for_every_module():
    assert CASES == tuple(SingularCase) and [c.letter for c in CASES] == ["a", "b", "c"]
    assert sing.CASES is CASES and analytic_ik.SINGULAR_CASES is CASES
    assert SingularCase("a") is SingularCase.TABLE_PARALLEL_TO_VERTICAL == "a"
    assert [c.long_name for c in CASES] == ["a_table_parallel_to_vertical", "b_orbital_parallel_to_wigwag",
                                            "c_table_parallel_to_horizontal"]
    assert all(c.title and c.loss for c in CASES)


@settings(max_examples=40)
@given(st.data())
def test_det_closed_form_is_the_determinant_of_pinocchios_jacobian(data):
    system = data.draw(systems())
    q = data.draw(configurations(system, beyond=0.3))
    model = system.pinocchio()[0]
    J = pin.computeFrameJacobian(model, model.createData(), q, model.getFrameId("xray_source"),
                                 pin.LOCAL_WORLD_ALIGNED)
    assert singular_cases.det_closed_form(system.setup, q[2], q[4]) == pytest.approx(np.linalg.det(J), abs=1e-12)


@given(st.data())
def test_factors_and_distances_broadcast_over_configurations(data):
    system = data.draw(systems())
    Q = np.array(data.draw(st.lists(configurations(system), min_size=1, max_size=6)))
    f = singular_cases.factors(system.setup, Q[:, 2], Q[:, 4])
    assert all(v.shape == (len(Q),) for v in f)
    d = singular_cases.distances(f)
    for k, q in enumerate(Q):  # independent of the code: the angles to each set
        assert d[SingularCase.ORBITAL_PARALLEL_TO_WIGWAG][k] == pytest.approx(
            abs(math.asin(abs(math.cos(q[4])))), abs=1e-12)
        assert d[SingularCase.TABLE_PARALLEL_TO_VERTICAL][k] == pytest.approx(
            math.asin(abs(math.sin(system.setup.gamma1))), abs=1e-12)


def test_cases_below_names_every_small_factor_or_the_smallest():
    assert singular_cases.cases_below((0.5, 1e-3, 1e-4), 1e-2) == (CASES[1], CASES[2])
    assert singular_cases.cases_below((0.5, 0.3, 0.4), 1e-2) == (CASES[1],)
