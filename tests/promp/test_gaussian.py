"""Gaussian helpers: log-densities, Cholesky, KL, moment-matched merge, conditioning."""
from unittest import mock

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from drake_skills.promp import gaussian as g


def _spd(rng, d, ridge=0.1):
    A = rng.standard_normal((d, d))
    return A @ A.T / d + ridge * np.eye(d)


def test_log_density_equals_scipy():
    rng = np.random.default_rng(0)
    d = 12
    mean, cov = rng.standard_normal(d), _spd(rng, d)
    x = rng.standard_normal((50, d)) * 2
    ours = g.log_density(x, mean, g.cholesky(cov))
    np.testing.assert_allclose(ours, multivariate_normal(mean, cov).logpdf(x), rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(g.log_density(x[3], mean, g.cholesky(cov)), ours[3], rtol=1e-12)


def test_gmm_log_density_equals_log_of_scipy_sum():
    rng = np.random.default_rng(1)
    w = np.array([0.2, 0.5, 0.3])
    means = rng.standard_normal((3, 4))
    covs = [_spd(rng, 4) for _ in range(3)]
    x = rng.standard_normal((20, 4))
    ref = np.log(sum(w[k] * multivariate_normal(means[k], covs[k]).pdf(x) for k in range(3)))
    np.testing.assert_allclose(g.gmm_log_density(x, w, means, [g.cholesky(c) for c in covs]), ref, rtol=1e-10)


def test_cholesky_adds_jitter_only_when_needed():
    rng = np.random.default_rng(2)
    S = _spd(rng, 6)
    L = g.cholesky(S)
    np.testing.assert_allclose(L @ L.T, S, rtol=0, atol=1e-13)  # exact: no jitter on a PD matrix
    v = rng.standard_normal((6, 1))
    singular = v @ v.T  # rank 1: the plain factorization fails
    with mock.patch.object(np.linalg, "cholesky", wraps=np.linalg.cholesky) as spy:
        g.cholesky(S)
        assert spy.call_count == 1
        L = g.cholesky(singular)
        assert spy.call_count > 2
    jitter = L @ L.T - singular
    np.testing.assert_allclose(jitter, np.diag(np.diag(jitter)), atol=1e-12)  # only a diagonal was added
    assert 0 < jitter[0, 0] < 1e-6 * np.mean(np.diag(singular))


def test_cholesky_rejects_bad_matrices():
    with pytest.raises(ValueError, match="square"):
        g.cholesky(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="NaN or inf"):
        g.cholesky(np.array([[1.0, np.nan], [np.nan, 1.0]]))
    with pytest.raises(ValueError, match="not positive definite"):
        g.cholesky(-np.eye(3))


def test_kl_gaussian_is_zero_for_identical_and_matches_monte_carlo():
    rng = np.random.default_rng(3)
    d = 4
    m0, S0 = rng.standard_normal(d), _spd(rng, d)
    m1, S1 = rng.standard_normal(d), _spd(rng, d, ridge=0.5)
    assert abs(g.kl_gaussian(m0, S0, m0, S0)) < 1e-12
    kl = g.kl_gaussian(m0, S0, m1, S1)
    x = rng.multivariate_normal(m0, S0, size=200000)
    diff = multivariate_normal(m0, S0).logpdf(x) - multivariate_normal(m1, S1).logpdf(x)
    se = diff.std() / np.sqrt(x.shape[0])
    assert abs(diff.mean() - kl) < 4 * se, (diff.mean(), kl, se)


def test_mc_kl_mixtures_is_seeded_and_zero_for_identical_mixtures():
    rng = np.random.default_rng(4)
    p = (np.array([0.3, 0.7]), rng.standard_normal((2, 3)), np.stack([_spd(rng, 3) for _ in range(2)]))
    q = (np.array([0.5, 0.5]), rng.standard_normal((2, 3)), np.stack([_spd(rng, 3) for _ in range(2)]))
    assert g.mc_kl_mixtures(p, q, 500, random_state=11) == g.mc_kl_mixtures(p, q, 500, random_state=11)
    assert g.mc_kl_mixtures(p, q, 500, random_state=11) != g.mc_kl_mixtures(p, q, 500, random_state=12)
    assert abs(g.mc_kl_mixtures(p, p, 500, random_state=0)) < 1e-12  # same samples, same densities
    assert g.mc_kl_mixtures(p, q, 2000, random_state=0) > 0.1


def test_mc_kl_of_single_gaussians_matches_closed_form():
    rng = np.random.default_rng(5)
    m0, S0, m1, S1 = rng.standard_normal(3), _spd(rng, 3), rng.standard_normal(3), _spd(rng, 3)
    mc = g.mc_kl_mixtures((np.ones(1), m0[None], S0[None]), (np.ones(1), m1[None], S1[None]), 100000, 0)
    exact = g.kl_gaussian(m0, S0, m1, S1)
    assert abs(mc - exact) < 0.05 * exact + 0.02, (mc, exact)


def test_merge_moments_equals_biased_moments_of_pooled_samples():
    rng = np.random.default_rng(6)
    A = rng.standard_normal((17, 5)) + 2.0
    B = rng.standard_normal((9, 5)) @ rng.standard_normal((5, 5))
    mu, S = g.merge_moments(17, A.mean(0), np.cov(A.T, bias=True), 9, B.mean(0), np.cov(B.T, bias=True))
    P = np.concatenate([A, B])
    np.testing.assert_allclose(mu, P.mean(0), rtol=0, atol=1e-10)
    np.testing.assert_allclose(S, np.cov(P.T, bias=True), rtol=0, atol=1e-10)


def test_condition_gaussian_matches_brute_force_formula():
    rng = np.random.default_rng(7)
    d = 7
    mean, cov = rng.standard_normal(d), _spd(rng, d)
    o = np.array([1, 4, 5])
    u = np.array([0, 2, 3, 6])
    x = rng.standard_normal(3)
    noise = 0.05 * np.eye(3)
    mc, Sc = g.condition_gaussian(mean, cov, o, x, noise)
    Soo_inv = np.linalg.inv(cov[np.ix_(o, o)] + noise)
    np.testing.assert_allclose(mc, mean[u] + cov[np.ix_(u, o)] @ Soo_inv @ (x - mean[o]), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(Sc, cov[np.ix_(u, u)] - cov[np.ix_(u, o)] @ Soo_inv @ cov[np.ix_(o, u)],
                               rtol=1e-10, atol=1e-12)
    mask = np.zeros(d, bool)
    mask[o] = True
    np.testing.assert_allclose(g.condition_gaussian(mean, cov, mask, x, noise)[0], mc, rtol=0, atol=0)


def test_check_random_state_normalizes_seeds():
    a = g.check_random_state(3).standard_normal(4)
    np.testing.assert_array_equal(a, g.check_random_state(3).standard_normal(4))
    gen = np.random.default_rng(0)
    assert g.check_random_state(gen) is gen
    with pytest.raises(ValueError, match="random_state"):
        g.check_random_state("seed")


def test_gaussian_functions_reject_bad_input():
    L = np.eye(3)
    with pytest.raises(ValueError, match="NaN or inf"):
        g.log_density(np.array([0.0, np.nan, 0.0]), np.zeros(3), L)
    with pytest.raises(ValueError, match="shape"):
        g.log_density(np.zeros((4, 2)), np.zeros(3), L)
    with pytest.raises(ValueError, match="shape"):
        g.mahalanobis_sq(np.zeros(3), np.zeros(2), L)
    with pytest.raises(ValueError, match="mean has inf"):
        g.kl_gaussian(np.array([np.inf, 0, 0]), np.eye(3), np.zeros(3), np.eye(3))
    with pytest.raises(ValueError, match="dimensions 3 and 2"):
        g.kl_gaussian(np.zeros(3), np.eye(3), np.zeros(2), np.eye(2))
    with pytest.raises(ValueError, match="covariance must have shape"):
        g.condition_gaussian(np.zeros(3), np.eye(2), [0], [1.0])
    with pytest.raises(ValueError, match="observed values must have shape"):
        g.condition_gaussian(np.zeros(3), np.eye(3), [0, 1], [1.0])
    with pytest.raises(ValueError, match="observed values has NaN"):
        g.condition_gaussian(np.zeros(3), np.eye(3), [0], [np.nan])
    with pytest.raises(ValueError, match="supports"):
        g.merge_moments(0, np.zeros(2), np.eye(2), 0, np.zeros(2), np.eye(2))
    with pytest.raises(ValueError, match="second Gaussian covariance has NaN"):
        g.merge_moments(1, np.zeros(2), np.eye(2), 1, np.zeros(2), np.full((2, 2), np.nan))
    with pytest.raises(ValueError, match="cannot merge"):
        g.merge_moments(1, np.zeros(2), np.eye(2), 1, np.zeros(3), np.eye(3))
    p = (np.ones(1), np.zeros((1, 2)), np.eye(2)[None])
    with pytest.raises(ValueError, match="mixture q means"):
        g.mc_kl_mixtures(p, (np.ones(1), np.zeros((2, 2)), np.eye(2)[None]), 10, 0)
    with pytest.raises(ValueError, match="dimensions 2 and 3"):
        g.mc_kl_mixtures(p, (np.ones(1), np.zeros((1, 3)), np.eye(3)[None]), 10, 0)
    with pytest.raises(ValueError, match="tuple"):
        g.mc_kl_mixtures(p, np.zeros(2), 10, 0)
    with pytest.raises(ValueError, match="n_samples"):
        g.mc_kl_mixtures(p, p, 0, 0)
    with pytest.raises(ValueError, match="Gaussian mean must have 1 dimension"):
        g.validate_gaussian(np.zeros((2, 2)), np.eye(2))
