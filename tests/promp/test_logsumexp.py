"""The project's logsumexp against scipy's (it replaces it on the hot paths of recognition)."""
import numpy as np
import pytest
from scipy.special import logsumexp as scipy_logsumexp

from drake_skills.promp.gaussian import logsumexp


@pytest.mark.parametrize("axis", [None, 0, 1])
def test_logsumexp_equals_scipys_with_minus_infinity_rows_and_columns(axis):
    rng = np.random.default_rng(0)
    a = rng.normal(scale=300.0, size=(6, 5))   # exp alone would overflow and underflow
    a[1, :] = -np.inf                          # a row all -inf
    a[:, 2] = -np.inf                          # a column all -inf
    a[4, 3] = -np.inf
    with np.errstate(divide="ignore"):
        expect = scipy_logsumexp(a, axis=axis)
    got = logsumexp(a, axis=axis)
    assert np.shape(got) == np.shape(expect)
    np.testing.assert_allclose(got, expect, rtol=1e-12, atol=0)   # -inf where scipy gives -inf


def test_logsumexp_of_a_vector_is_a_float_and_all_minus_infinity_gives_minus_infinity():
    got = logsumexp(np.array([0.0, np.log(3.0)]))
    assert isinstance(got, float) and got == pytest.approx(np.log(4.0), abs=1e-15)
    assert logsumexp(np.full(4, -np.inf)) == -np.inf
    np.testing.assert_array_equal(logsumexp(np.full((3, 2), -np.inf), axis=0), [-np.inf, -np.inf])
