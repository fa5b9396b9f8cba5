"""Interaction ProMPs: the behaviours `make mutate` found untested (issue 20).

The prefix statistic's dof is exactly ``D * rank(Phi_o)`` (an integer, however few
samples); ``predict_robot`` without phases says what is wrong with its samples.
"""
import numpy as np
import pytest

from drake_skills.promp.basis import GaussianBasis
from drake_skills.promp.interaction import InteractionProMP, prefix_statistics


def _model(rng, d):
    A = rng.standard_normal((d, d))
    return rng.standard_normal(d), A @ A.T / d + 0.05 * np.eye(d)


@pytest.mark.parametrize("D, m, z_end, dof", [(1, 1, 0.0, 1.0), (2, 1, 0.0, 2.0), (1, 3, 0.3, 3.0), (3, 2, 0.3, 6.0),
                                              (2, 40, 1.0, 12.0)])
def test_prefix_dof_is_exactly_D_times_the_rank_of_the_observed_basis(D, m, z_end, dof):
    # one sample in one dimension spans one direction: dof 1, not a floor above it
    rng = np.random.default_rng(10 * D + m)
    basis = GaussianBasis(6)
    mean_h, cov_hh = _model(rng, D * 6)
    Phi_o = basis.phi(np.linspace(0.0, z_end, m))  # rank min(m, 6): 40 samples over the whole motion span all 6
    y = rng.standard_normal((m, D))
    _, d2, got = prefix_statistics(mean_h, cov_hh, Phi_o, y, 0.1)
    assert got == dof  # exact: a chi-square quantile is taken at it
    assert d2 >= 0


def _fitted():
    rng = np.random.default_rng(3)
    p = InteractionProMP(2, 1, basis_human=GaussianBasis(5), basis_robot=GaussianBasis(6))
    return p.fit_weights(rng.standard_normal((30, p.n_weights)))


def test_predict_robot_without_phases_needs_two_samples_and_says_so():
    # One sample cannot be spread over [0, 1]: the error is about the samples the user passed,
    # not about phases the user never gave (it used to say "observed phases must have shape (1), got (2,)").
    p = _fitted()
    with pytest.raises(ValueError, match=r"^observed human samples is too short: 1 sample\(s\), need at least 2$"):
        p.predict_robot(np.zeros((1, 2)))
    # with its phase given, one sample conditions fine
    mean, cov = p.predict_robot(np.zeros((1, 2)), [0.5], n_steps=7)
    assert mean.shape == (7, 1) and cov.shape == (7, 1, 1)


def test_predict_robot_names_non_numeric_samples():
    p = _fitted()
    with pytest.raises(ValueError, match=r"^observed human samples is not numeric \(could not convert string to "
                                         r"float: 'a'\)$"):
        p.predict_robot([["a", "b"], ["c", "d"]])
    with pytest.raises(ValueError, match=r"^observed human samples is not numeric \(setting an array element"):
        p.predict_robot([[0.0, 0.0], [1.0]])  # ragged
    with pytest.raises(ValueError, match=r"^observed human samples must have shape \(any, 2\), got \(3, 3\)$"):
        p.predict_robot(np.zeros((3, 3)))


def test_predict_robot_default_phases_are_evenly_spaced_over_the_whole_motion():
    p = _fitted()
    y = np.random.default_rng(4).standard_normal((5, 2))
    mean, cov = p.predict_robot(y.tolist(), n_steps=9)
    ref_mean, ref_cov = p.condition(y, np.linspace(0.0, 1.0, 5)).robot_distribution(9)
    np.testing.assert_array_equal(mean, ref_mean)
    np.testing.assert_array_equal(cov, ref_cov)
