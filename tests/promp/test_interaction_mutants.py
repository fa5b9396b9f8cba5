"""Interaction ProMPs: the behaviours `make mutate` found untested (issue 20).

The prefix statistic's dof is exactly D times the directions the samples see well (an
integer, however few samples), its d2 the Mahalanobis distance of the least-squares weights
in them; ``predict_robot`` without phases says what is wrong with its samples.
"""
import numpy as np
import pytest

from drake_skills.promp.basis import GaussianBasis
from drake_skills.promp.interaction import InteractionProMP, prefix_statistics


def _model(rng, d):
    A = rng.standard_normal((d, d))
    return rng.standard_normal(d), A @ A.T / d + 0.05 * np.eye(d)


@pytest.mark.parametrize("D, m, z_end, dof", [(1, 1, 0.0, 1.0), (2, 1, 0.0, 2.0), (1, 3, 0.0, 1.0), (3, 2, 0.3, 6.0),
                                              (2, 40, 1.0, 8.0), (2, 40, 0.5, 4.0)])
def test_prefix_dof_is_D_times_the_directions_the_samples_see_well(D, m, z_end, dof):
    # at seen_rcond 0.03: one sample in one dimension spans one direction (dof 1, not a floor above it); samples all at
    # phase 0 see one direction however many; two samples at 0 and 0.3 see a second at 0.22 of the
    # first; 40 samples of the whole motion see 4 of 6 (eigenvalues 1, 0.52, 0.18, 0.040 | 0.0061,
    # 0.0006 of the largest), of half of it 2 (1, 0.21 | 0.019)
    rng = np.random.default_rng(10 * D + m)
    basis = GaussianBasis(6)
    mean_h, cov_hh = _model(rng, D * 6)
    Phi_o = basis.phi(np.linspace(0.0, z_end, m))
    y = rng.standard_normal((m, D))
    _, d2, got = prefix_statistics(mean_h, cov_hh, Phi_o, y, 0.1, seen_rcond=0.03)
    g = np.linalg.eigvalsh(Phi_o.T @ Phi_o)
    assert got == dof == D * np.sum(g >= 0.03 * g[-1])  # exact: a chi-square quantile is taken at it
    assert d2 >= 0


@pytest.mark.parametrize("rcond", [1e-10, 0.03, 0.3])
def test_prefix_d2_is_the_mahalanobis_distance_of_the_seen_least_squares_weights(rcond):
    # the least-squares weights' coordinates along the seen eigenvectors V of Phi^T Phi: their misfit
    # V^T (w_ls - mu) has covariance sigma^2 g^-1 + V^T Sigma V (per dimension, stacked)
    rng = np.random.default_rng(4)
    basis = GaussianBasis(6)
    mean_h, cov_hh = _model(rng, 12)
    Phi_o = basis.phi(np.linspace(0.0, 0.5, 15))
    y = rng.standard_normal((15, 2))
    g, V = np.linalg.eigh(Phi_o.T @ Phi_o)
    keep = g >= rcond * g[-1]
    Vk = np.kron(np.eye(2), V[:, keep])
    w_ls = np.linalg.lstsq(Phi_o, y, rcond=None)[0].T.reshape(-1)
    e = Vk.T @ (w_ls - mean_h)
    C = 0.1 * np.diag(np.tile(1.0 / g[keep], 2)) + Vk.T @ cov_hh @ Vk
    _, d2, dof = prefix_statistics(mean_h, cov_hh, Phi_o, y, 0.1, seen_rcond=rcond)
    assert dof == 2 * keep.sum() and (keep.sum() < 6) == (rcond > 1e-3)
    assert d2 == pytest.approx(float(e @ np.linalg.solve(C, e)), rel=1e-7)


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
