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


def _with_min_eigenvalue(rng, d, lam_min, scale):
    """A symmetric matrix with mean |diagonal| ~ scale and smallest eigenvalue lam_min * scale."""
    Q, _ = np.linalg.qr(rng.standard_normal((d, d)))
    lam = np.linspace(1.0, 2.0, d)
    lam[0] = lam_min
    S = scale * (Q * lam) @ Q.T
    return 0.5 * (S + S.T)


@pytest.mark.parametrize("scale", [1e-2, 1.0, 1e2])
def test_cholesky_jitter_grows_tenfold_up_to_1e_minus_3_of_the_mean_diagonal(scale):
    """Jitter tries 1e-10 ... 1e-3 times mean|diag|: an eigenvalue of -5e-4 (relative) is fixed with
    a diagonal of 1e-3 (relative), one of -1.5e-3 is not."""
    rng = np.random.default_rng(8)
    S = _with_min_eigenvalue(rng, 5, -5e-4, scale)
    ref = np.mean(np.abs(np.diag(S)))
    L = g.cholesky(S)
    added = L @ L.T - S
    np.testing.assert_allclose(added, 1e-3 * ref * np.eye(5), rtol=1e-6, atol=1e-9 * ref)
    with pytest.raises(ValueError, match=r"^covariance is not positive definite \(Cholesky failed even with jitter\)$"):
        g.cholesky(_with_min_eigenvalue(rng, 5, -1.5e-3, scale))
    # the smallest jitter that works is the one used: 1e-9 (the second try) for an eigenvalue of -5e-10
    S = _with_min_eigenvalue(rng, 5, -5e-10, scale)
    L = g.cholesky(S)
    np.testing.assert_allclose(np.diag(L @ L.T - S), 1e-9 * np.mean(np.abs(np.diag(S))), rtol=1e-3)


def test_cholesky_tries_exactly_eight_jitters():
    """max_tries=8: jitters 1e-10 .. 1e-3 (relative); fewer tries give up earlier."""
    rng = np.random.default_rng(9)
    S = _with_min_eigenvalue(rng, 4, -5e-4, 1.0)
    g.cholesky(S)  # needs the eighth
    with pytest.raises(ValueError, match="not positive definite"):
        g.cholesky(S, max_tries=7)
    L = g.cholesky(S, jitter=1e-3, max_tries=1)  # one try, at 1e-3
    assert np.allclose(L @ L.T - S, 1e-3 * np.mean(np.abs(np.diag(S))) * np.eye(4), rtol=1e-6)


def test_cholesky_of_a_zero_matrix_uses_a_tiny_absolute_jitter():
    """mean|diag| = 0: the jitter is relative to 1e-300, so zero stays (numerically) zero."""
    L = g.cholesky(np.zeros((3, 3)))
    assert np.all(np.isfinite(L)) and np.abs(L).max() < 1e-100


def test_cholesky_messages():
    with pytest.raises(ValueError, match=r"^covariance must be square, got shape \(2, 3\)$"):
        g.cholesky(np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"^covariance must be square, got shape \(4,\)$"):
        g.cholesky(np.zeros(4))
    with pytest.raises(ValueError, match=r"^covariance has NaN or inf entries$"):
        g.cholesky(np.array([[1.0, 0.0], [0.0, np.inf]]))
    np.testing.assert_allclose(g.cholesky([[4, 2], [2, 3]]), np.linalg.cholesky(np.array([[4.0, 2], [2, 3]])))


def test_cholesky_symmetrizes_before_factorizing():
    S = np.array([[4.0, 2.0], [1.0, 3.0]])  # the factor of (S + S^T) / 2
    L = g.cholesky(S)
    np.testing.assert_allclose(L @ L.T, [[4.0, 1.5], [1.5, 3.0]], rtol=0, atol=1e-14)


def test_mahalanobis_sq_equals_explicit_inverse_for_one_and_many_points():
    rng = np.random.default_rng(10)
    S = _spd(rng, 4)
    mean = rng.standard_normal(4)
    X = rng.standard_normal((6, 4))
    d2 = g.mahalanobis_sq(X, mean, np.linalg.cholesky(S))
    ref = np.einsum("ni,ij,nj->n", X - mean, np.linalg.inv(S), X - mean)
    np.testing.assert_allclose(d2, ref, rtol=1e-10)
    assert d2.shape == (6,)
    one = g.mahalanobis_sq(X[2].tolist(), mean, np.linalg.cholesky(S))
    assert one.shape == () and one == pytest.approx(ref[2], rel=1e-10)


def test_mahalanobis_sq_messages():
    L = np.eye(3)
    msg = r"^points must have shape \(d,\) or \(n, d\) and mean \(d,\) with d = 3, got {} and {}$"
    with pytest.raises(ValueError, match=msg.format(r"\(1, 2, 3\)", r"\(3,\)")):
        g.mahalanobis_sq(np.zeros((1, 2, 3)), np.zeros(3), L)  # only the number of dimensions is wrong
    with pytest.raises(ValueError, match=msg.format(r"\(4, 2\)", r"\(3,\)")):
        g.mahalanobis_sq(np.zeros((4, 2)), np.zeros(3), L)  # only the points' length is wrong
    with pytest.raises(ValueError, match=msg.format(r"\(3,\)", r"\(2,\)")):
        g.mahalanobis_sq(np.zeros(3), np.zeros(2), L)  # only the mean is wrong
    with pytest.raises(ValueError, match=r"^points have NaN or inf entries$"):
        g.mahalanobis_sq(np.array([0.0, np.inf, 0.0]), np.zeros(3), L)


def test_log_density_of_many_points_has_one_value_per_point():
    rng = np.random.default_rng(11)
    S = _spd(rng, 3)
    X = rng.standard_normal((5, 3))
    out = g.log_density(X, np.zeros(3), np.linalg.cholesky(S))
    assert out.shape == (5,)
    np.testing.assert_allclose(out, multivariate_normal(np.zeros(3), S).logpdf(X), rtol=1e-12)


def test_gmm_log_density_accepts_lists_and_one_point():
    w, means = [0.25, 0.75], [[0.0, 0.0], [1.0, 1.0]]
    chols = [np.eye(2), 2.0 * np.eye(2)]
    out = g.gmm_log_density([0.5, -0.5], w, np.array(means), chols)
    ref = np.log(0.25 * multivariate_normal([0, 0], np.eye(2)).pdf([0.5, -0.5])
                 + 0.75 * multivariate_normal([1, 1], 4 * np.eye(2)).pdf([0.5, -0.5]))
    assert out.shape == (1,) and out[0] == pytest.approx(ref, rel=1e-12)


def test_kl_gaussian_equals_the_closed_form_written_out():
    rng = np.random.default_rng(12)
    m0, S0, m1, S1 = rng.standard_normal(5), _spd(rng, 5), rng.standard_normal(5), _spd(rng, 5, ridge=0.3)
    S1_inv = np.linalg.inv(S1)
    ref = 0.5 * (np.trace(S1_inv @ S0) + (m1 - m0) @ S1_inv @ (m1 - m0) - 5
                 + np.log(np.linalg.det(S1) / np.linalg.det(S0)))
    assert g.kl_gaussian(m0, S0, m1, S1) == pytest.approx(ref, rel=1e-10)
    assert g.kl_gaussian(m0.tolist(), S0.tolist(), m1.tolist(), S1.tolist()) == pytest.approx(ref, rel=1e-10)
    assert g.kl_gaussian(m1, S1, m0, S0) != pytest.approx(ref, rel=1e-3)  # not symmetric


def test_kl_gaussian_messages():
    ok = (np.zeros(2), np.eye(2))
    with pytest.raises(ValueError, match=r"^first Gaussian mean has NaN at rows 1$"):
        g.kl_gaussian(np.array([0.0, np.nan]), np.eye(2), *ok)
    with pytest.raises(ValueError, match=r"^second Gaussian covariance has inf at rows 0$"):
        g.kl_gaussian(*ok, np.zeros(2), np.array([[np.inf, 0.0], [0.0, 1.0]]))
    with pytest.raises(ValueError, match=r"^second Gaussian mean must have 1 dimension\(s\), got shape \(1, 2\)$"):
        g.kl_gaussian(*ok, np.zeros((1, 2)), np.eye(2))
    with pytest.raises(ValueError, match=r"^KL between Gaussians of dimensions 2 and 3$"):
        g.kl_gaussian(*ok, np.zeros(3), np.eye(3))
    with pytest.raises(ValueError, match=r"^covariance is not positive definite"):
        g.kl_gaussian(*ok, np.zeros(2), -np.eye(2))


def test_merge_moments_accepts_zero_and_fractional_supports():
    rng = np.random.default_rng(13)
    m1, S1, m2, S2 = rng.standard_normal(3), _spd(rng, 3), rng.standard_normal(3), _spd(rng, 3)
    mu, S = g.merge_moments(0, m1, S1, 2.0, m2, S2)  # a zero support contributes nothing
    np.testing.assert_allclose(mu, m2, rtol=0, atol=1e-14)
    np.testing.assert_allclose(S, S2, rtol=0, atol=1e-14)
    mu, S = g.merge_moments(0.25, m1, S1, 0, m2, S2)
    np.testing.assert_allclose(mu, m1, rtol=0, atol=1e-14)
    mu, S = g.merge_moments(0.25, m1, S1, 0.5, m2, S2)  # supports summing to less than 1
    np.testing.assert_allclose(mu, (m1 + 2 * m2) / 3, rtol=0, atol=1e-14)
    np.testing.assert_allclose(S, (S1 + 2 * S2) / 3 + (2 / 9) * np.outer(m1 - m2, m1 - m2), rtol=0, atol=1e-14)


@pytest.mark.parametrize("s_i, s_j", [(-1.0, 2.0), (2.0, -0.5), (np.nan, 1.0), (1.0, np.inf), (0.0, 0.0)])
def test_merge_moments_rejects_bad_supports(s_i, s_j):
    with pytest.raises(ValueError, match=r"^supports must be finite, >= 0 and not both 0, got "):
        g.merge_moments(s_i, np.zeros(2), np.eye(2), s_j, np.zeros(2), np.eye(2))


def test_merge_moments_and_conditioning_messages_name_the_argument():
    with pytest.raises(ValueError, match=r"^first Gaussian mean has NaN"):
        g.merge_moments(1, np.array([np.nan, 0.0]), np.eye(2), 1, np.zeros(2), np.eye(2))
    with pytest.raises(ValueError, match=r"^second Gaussian mean must have 1 dimension"):
        g.merge_moments(1, np.zeros(2), np.eye(2), 1, np.zeros((2, 1)), np.eye(2))
    with pytest.raises(ValueError, match=r"^cannot merge Gaussians of dimensions 2 and 3$"):
        g.merge_moments(1, np.zeros(2), np.eye(2), 1, np.zeros(3), np.eye(3))
    with pytest.raises(ValueError, match=r"^observation covariance must have shape \(2, 2\), got \(3, 3\)$"):
        g.condition_gaussian(np.zeros(4), np.eye(4), [0, 1], [0.0, 0.0], np.eye(3))
    with pytest.raises(ValueError, match=r"^observation covariance has NaN at rows 0$"):
        g.condition_gaussian(np.zeros(4), np.eye(4), [0, 1], [0.0, 0.0], np.array([[np.nan, 0], [0, 1]]))
    with pytest.raises(ValueError, match=r"^random_state must be None, an int or a numpy Generator, got str$"):
        g.check_random_state("seed")
    assert isinstance(g.check_random_state(np.int64(3)), np.random.Generator)
    assert isinstance(g.check_random_state(None), np.random.Generator)


def test_sample_mixture_draws_from_each_component_in_proportion():
    means = np.array([[0.0, 0.0], [100.0, 0.0]])
    covs = np.stack([np.eye(2), np.eye(2)])
    x = g.sample_mixture([1.0, 3.0], means, covs, 4000, random_state=0)  # weights need not sum to 1
    assert x.shape == (4000, 2)
    far = x[:, 0] > 50
    # binomial(4000, 0.75): standard deviation 27, allow 4
    assert abs(far.sum() - 3000) < 110
    np.testing.assert_allclose(x[far].mean(0), [100.0, 0.0], atol=0.1)  # 4 standard errors of 3000 samples
    np.testing.assert_allclose(np.cov(x[~far].T), np.eye(2), atol=0.15)
    assert not (np.diff(far.astype(int)) == 0).all()  # shuffled, not grouped by component
    np.testing.assert_array_equal(x, g.sample_mixture([1.0, 3.0], means, covs, 4000, random_state=0))


def test_mc_kl_mixtures_messages():
    p = (np.ones(1), np.zeros((1, 2)), np.eye(2)[None])
    with pytest.raises(ValueError, match=r"^mixture p weights must be >= 0 with a positive sum$"):
        g.mc_kl_mixtures((np.array([-1.0]), np.zeros((1, 2)), np.eye(2)[None]), p, 10, 0)
    with pytest.raises(ValueError, match=r"^mixture q weights must be >= 0 with a positive sum$"):
        g.mc_kl_mixtures(p, (np.array([0.0]), np.zeros((1, 2)), np.eye(2)[None]), 10, 0)
    with pytest.raises(ValueError, match=r"^mixture p weights is too short: 0 sample\(s\), need at least 1$"):
        g.mc_kl_mixtures((np.zeros(0), np.zeros((0, 2)), np.zeros((0, 2, 2))), p, 10, 0)
    with pytest.raises(ValueError, match=r"^mixture q covariances must have shape \(1, 2, 2\), got \(1, 3, 3\)$"):
        g.mc_kl_mixtures(p, (np.ones(1), np.zeros((1, 2)), np.eye(3)[None]), 10, 0)
    with pytest.raises(ValueError, match=r"^mixture p must be a tuple \(weights, means, covs\)$"):
        g.mc_kl_mixtures((np.ones(1), np.zeros((1, 2))), p, 10, 0)
    with pytest.raises(ValueError, match=r"^n_samples must be a positive integer, got 2.5$"):
        g.mc_kl_mixtures(p, p, 2.5, 0)
    assert g.mc_kl_mixtures(p, p, 1, 0) == 0.0
    assert g.mc_kl_mixtures(p, p, 3.0, 0) == 0.0  # an integral float is a count


def test_validate_gaussian_messages():
    with pytest.raises(ValueError, match=r"^Gaussian covariance must have shape \(2, 2\), got \(3, 3\)$"):
        g.validate_gaussian(np.zeros(2), np.eye(3))
    mean, cov = g.validate_gaussian([1, 2], [[1, 0], [0, 1]])
    assert mean.dtype == float and cov.dtype == float


def test_mc_kl_mixtures_defaults_to_2000_samples_and_allows_zero_weights():
    rng = np.random.default_rng(14)
    p = (np.array([0.3, 0.7]), rng.standard_normal((2, 2)), np.stack([np.eye(2)] * 2))
    q = (np.array([0.0, 1.0]), rng.standard_normal((2, 2)), np.stack([np.eye(2)] * 2))  # a zero weight is valid
    assert g.mc_kl_mixtures(p, q, random_state=3) == g.mc_kl_mixtures(p, q, 2000, random_state=3)
    assert g.mc_kl_mixtures(p, q, random_state=3) != g.mc_kl_mixtures(p, q, 2001, random_state=3)
    with pytest.raises(ValueError, match=r"^mixture p weights must have 1 dimension\(s\), got shape \(1, 2\)$"):
        g.mc_kl_mixtures((np.array([[0.5, 0.5]]), p[1], p[2]), q, 10, 0)


def test_gmm_log_density_with_a_zero_weight_ignores_that_component_silently():
    import warnings

    means, chols = np.array([[0.0], [5.0]]), [np.eye(1), np.eye(1)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = g.gmm_log_density([[0.0]], [0.0, 1.0], means, chols)
    assert out[0] == pytest.approx(multivariate_normal(5.0, 1.0).logpdf(0.0), rel=1e-12)


def test_inverse_lower_is_the_triangular_inverse_and_refuses_a_singular_factor():
    """LAPACK's triangular inverse: lower triangular, L @ L^-1 = I within 1e-12, the general inverse within 1e-12."""
    rng = np.random.default_rng(4)
    A = rng.normal(size=(45, 45))
    L = np.linalg.cholesky(A @ A.T + 45 * np.eye(45))
    Li = g.inverse_lower(L)
    assert Li.shape == (45, 45) and Li.flags["C_CONTIGUOUS"]
    assert np.array_equal(Li, np.tril(Li))
    np.testing.assert_allclose(L @ Li, np.eye(45), rtol=0, atol=1e-12)
    np.testing.assert_allclose(Li, np.linalg.inv(L), rtol=0, atol=1e-12)
    assert g.inverse_lower(np.zeros((0, 0))).shape == (0, 0)
    singular = L.copy()
    singular[3, 3] = 0.0
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        g.inverse_lower(singular)
    with pytest.raises(ValueError, match="square"):
        g.inverse_lower(np.ones((2, 3)))
    # only the lower triangle is read: junk above it changes nothing; F-ordered and 1 x 1 inputs
    junk = L + np.triu(np.full((45, 45), 7.0), 1)
    np.testing.assert_array_equal(g.inverse_lower(junk), Li)
    np.testing.assert_array_equal(g.inverse_lower(np.asfortranarray(L)), Li)
    assert g.inverse_lower(np.array([[4.0]])).tolist() == [[0.25]]
