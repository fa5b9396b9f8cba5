"""Batch baselines: labeled maximum likelihood and EM mixture."""
import numpy as np
import pytest
from scipy.stats import multivariate_normal

from drake_skills.library.batch import Mixture, batch_em, labeled_ml
from drake_skills.promp.gaussian import mc_kl_mixtures


def _clusters(rng, n_per=(40, 60, 50), d=4):
    centres = np.array([[0.0] * d, [10.0] + [0.0] * (d - 1), [0.0, 10.0] + [0.0] * (d - 2)])
    X = np.concatenate([c + rng.standard_normal((n, d)) @ np.diag(rng.uniform(0.3, 1.0, d))
                        for c, n in zip(centres, n_per)])
    y = np.repeat(["a", "b", "c"], n_per)
    return X, y, centres


def test_labeled_ml_moments_equal_numpy():
    X, y, _ = _clusters(np.random.default_rng(0))
    m = labeled_ml(X, y, min_variance=0.0)
    assert m.labels == ("a", "b", "c")
    np.testing.assert_allclose(m.weights, [40 / 150, 60 / 150, 50 / 150], rtol=0, atol=1e-15)
    for k, lab in enumerate("abc"):
        np.testing.assert_allclose(m.means[k], X[y == lab].mean(0), rtol=0, atol=1e-12)
        np.testing.assert_allclose(m.covs[k], np.cov(X[y == lab].T, bias=True), rtol=0, atol=1e-12)
    m2 = labeled_ml(X, y, min_variance=0.5)
    np.testing.assert_allclose(m2.covs - m.covs, 0.5 * np.eye(4)[None].repeat(3, 0), atol=1e-12)


def test_labeled_ml_with_one_sample_per_label_uses_min_variance():
    m = labeled_ml(np.arange(6.0).reshape(2, 3), ["x", "y"], min_variance=1e-3)
    np.testing.assert_allclose(m.covs, 1e-3 * np.eye(3)[None].repeat(2, 0))
    with pytest.raises(ValueError, match="label 'x' has 1 sample.*min_variance > 0"):
        labeled_ml(np.arange(6.0).reshape(2, 3), ["x", "y"], min_variance=0.0)


def test_batch_em_recovers_three_separated_clusters():
    X, y, centres = _clusters(np.random.default_rng(1))
    m = batch_em(X, 3, random_state=0)
    order = [int(np.argmin(np.linalg.norm(m.means - c, axis=1))) for c in centres]
    assert sorted(order) == [0, 1, 2]
    np.testing.assert_allclose(m.means[order], centres, atol=0.4)  # ~4 standard errors of a 40-sample mean
    np.testing.assert_allclose(m.weights[order], [40 / 150, 60 / 150, 50 / 150], atol=1e-6)
    pred = m.predict(X)
    truth = np.array([order[ord(c) - ord("a")] for c in y])
    assert (pred == truth).all()
    # and it is close to the labeled solution
    kl = mc_kl_mixtures(labeled_ml(X, y).as_tuple(), m.as_tuple(), 2000, random_state=0)
    assert kl < 0.01, kl


def test_batch_em_is_seeded():
    X, _, _ = _clusters(np.random.default_rng(2))
    a, b = batch_em(X, 3, random_state=5), batch_em(X, 3, random_state=5)
    np.testing.assert_array_equal(a.means, b.means)
    np.testing.assert_array_equal(a.covs, b.covs)


def test_mixture_log_density_matches_scipy():
    rng = np.random.default_rng(3)
    X, y, _ = _clusters(rng)
    m = labeled_ml(X, y)
    Q = rng.standard_normal((7, 4)) * 5
    ref = np.log(sum(m.weights[k] * multivariate_normal(m.means[k], m.covs[k]).pdf(Q) for k in range(3)))
    np.testing.assert_allclose(m.log_density(Q), ref, rtol=1e-10)
    np.testing.assert_allclose(m.log_density(Q[0]), ref[:1], rtol=1e-10)
    w, mu, S = m.as_tuple()
    assert w.shape == (3,) and mu.shape == (3, 4) and S.shape == (3, 4, 4)


def test_batch_functions_reject_bad_input():
    X = np.random.default_rng(4).standard_normal((10, 3))
    bad = X.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="weights W has NaN at rows 2"):
        labeled_ml(bad, range(10))
    with pytest.raises(ValueError, match="weights W has inf"):
        batch_em(np.full((10, 3), np.inf), 2)
    with pytest.raises(ValueError, match="9 labels for 10"):
        labeled_ml(X, range(9))
    with pytest.raises(ValueError, match="2 dimension"):
        batch_em(X[:, 0], 2)
    with pytest.raises(ValueError, match="too short: 3 sample"):
        batch_em(X[:3], 4)
    with pytest.raises(ValueError, match="too short: 0 sample"):
        labeled_ml(np.zeros((0, 3)), [])
    with pytest.raises(ValueError, match="distinct"):
        batch_em(np.ones((10, 3)), 2)
    with pytest.raises(ValueError, match="n_components"):
        batch_em(X, 0)
    with pytest.raises(ValueError, match="reg_covar"):
        batch_em(X, 2, reg_covar=0.0)
    with pytest.raises(ValueError, match="random_state"):
        batch_em(X, 2, random_state="x")
    m = labeled_ml(X, [0] * 10)
    with pytest.raises(ValueError, match=r"points must have shape \(n, 3\)"):
        m.log_density(np.zeros((2, 4)))
    with pytest.raises(ValueError, match="points has NaN"):
        m.predict(np.full((2, 3), np.nan))
    with pytest.raises(ValueError, match="sum to 1"):
        Mixture(np.array([0.5, 0.2]), np.zeros((2, 3)), np.stack([np.eye(3)] * 2))
    with pytest.raises(ValueError, match="not positive definite"):
        Mixture(np.ones(1), np.zeros((1, 3)), -np.eye(3)[None])
