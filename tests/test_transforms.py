"""Elementary transforms: the minimal rotation between two directions stays orthonormal up to antiparallel."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from strategies import finite

from carmkin.transforms import rotation_between

vectors = st.lists(st.floats(-1, 1, **finite), min_size=3, max_size=3).map(np.array).filter(
    lambda v: np.linalg.norm(v) > 1e-3)


def _check(a, b, tol: float = 1e-12):
    R = rotation_between(a, b)
    assert np.abs(R @ R.T - np.eye(3)).max() <= 1e-14
    assert abs(np.linalg.det(R) - 1.0) <= 1e-14
    assert np.abs(R @ (a / np.linalg.norm(a)) - b / np.linalg.norm(b)).max() <= tol


@given(vectors, vectors)
def test_rotation_between_random_directions(a, b):
    _check(a, b)


@given(vectors, st.floats(-1e-6, 1e-6, **finite))
def test_rotation_between_nearly_antiparallel_directions(a, eps):
    # the axis a x b is only known to ~1e-16 / |a x b| here, which bounds how exactly R maps a onto b;
    # orthonormality stays at machine precision
    b = -a + eps * np.array([0.3, -0.2, 0.5])
    s = np.linalg.norm(np.cross(a / np.linalg.norm(a), b / np.linalg.norm(b)))
    _check(a, b, tol=1e-12 + 1e-14 / max(s, 1e-300))


def test_rotation_between_the_example_that_broke_the_1_over_1_plus_c_formula():
    _check(np.array([0.71875, 0.09375, 0.109375]), np.array([-1.0, -0.125, -0.15625]))
    _check(np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0]))
