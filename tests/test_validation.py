"""The boundary helpers of carmkin.validation: what they accept, what they refuse, and how they say so."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from carmkin.errors import CarmkinError, InvalidConfigurationError
from carmkin.validation import MAGNITUDE_LIMIT, real_array, real_scalar


@given(arrays(np.float64, st.integers(0, 5), elements=st.floats(-MAGNITUDE_LIMIT, MAGNITUDE_LIMIT)))
def test_finite_real_arrays_pass_unchanged(a):
    out = real_array(a, "x", (None,))
    assert out.dtype == np.float64 and np.array_equal(out, a)


@given(arrays(np.int64, 3, elements=st.integers(-1000, 1000)))
def test_integers_become_floats(a):
    assert np.array_equal(real_array(a, "x", (3,)), a.astype(float))


@pytest.mark.parametrize("value, words", [
    (None, "got None"), ("1.5", "got '1.5'"), (b"1", "got b'1'"), (True, "booleans"), ([True, False], "booleans"),
    (1 + 0j, "complex"), (np.array([1.0, 2.0], dtype=complex), "complex"), ([1.0, np.nan], "finite"),
    ([np.inf], "finite"), ([[1.0], [1.0, 2.0]], "got"), ({"a": 1}, "dtype object"), (1e300, "within ±1e+06"),
    (2**60, "too large"),
])
def test_junk_is_refused_with_the_name_and_the_value(value, words):
    with pytest.raises(CarmkinError) as info:
        real_array(value, "q_current", None)
    assert "q_current" in str(info.value) and words in str(info.value)


def test_shape_and_unit_are_named():
    with pytest.raises(InvalidConfigurationError, match=r"q must be real numbers \(m\) of shape \(6,\), got shape \(5,\)"):
        real_array(np.zeros(5), "q", (6,), error=InvalidConfigurationError, unit="m")
    assert real_array(np.zeros((7, 6)), "q", (None, 6)).shape == (7, 6)


def test_scalar_bounds():
    assert real_scalar(2, "margin", low=0.0) == 2.0
    with pytest.raises(CarmkinError, match=r"margin must be within \[0, inf\] m, got -1"):
        real_scalar(-1, "margin", low=0.0, unit="m")
    with pytest.raises(CarmkinError, match="shape"):
        real_scalar([1.0], "margin")
