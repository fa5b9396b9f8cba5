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


def _raises(message, fn, *a, **k):
    import re

    with pytest.raises(ValueError, match="^" + re.escape(message)):
        fn(*a, **k)


def test_mixture_stores_read_only_validated_arrays():
    S = np.array([[[2.0, 1.0], [0.0, 2.0]]])  # symmetrized on the way in
    m = Mixture([1.0], [[0.0, 1.0]], S, labels=["a"])
    np.testing.assert_array_equal(m.covs[0], [[2.0, 0.5], [0.5, 2.0]])
    assert m.weights.dtype == float and m.means.tolist() == [[0.0, 1.0]] and m.labels == ("a",)
    assert m.n_components == 1 and m.dim == 2
    for a in (m.weights, m.means, m.covs):
        with pytest.raises(ValueError):
            a[0] = 0.0
    one_d = Mixture(np.ones(1), np.zeros((1, 1)), np.ones((1, 1, 1)))  # one column is enough
    assert one_d.dim == 1 and one_d.labels is None
    zero_weight = Mixture(np.array([0.0, 1.0]), np.zeros((2, 1)), np.ones((2, 1, 1)))  # a zero weight is allowed
    np.testing.assert_allclose(zero_weight.log_density(np.zeros((1, 1))), [np.log(1 / np.sqrt(2 * np.pi))])
    assert zero_weight.predict(np.zeros((3, 1))).tolist() == [1, 1, 1]


def test_mixture_messages():
    eye = np.eye(2)[None]
    _raises("mixture weights must have 1 dimension(s), got shape (1, 1)", Mixture, np.ones((1, 1)), np.zeros((1, 2)),
            eye)
    _raises("mixture weights is too short: 0 sample(s), need at least 1", Mixture, np.ones(0), np.zeros((0, 2)),
            np.zeros((0, 2, 2)))
    _raises("mixture means must have shape (1, any), got (2, 2)", Mixture, np.ones(1), np.zeros((2, 2)), eye)
    _raises("mixture means have no columns", Mixture, np.ones(1), np.zeros((1, 0)), np.zeros((1, 0, 0)))
    _raises("mixture covariances must have shape (1, 2, 2), got (1, 3, 3)", Mixture, np.ones(1), np.zeros((1, 2)),
            np.eye(3)[None])
    _raises("mixture weights must be non-negative and sum to 1, got sum 0.5", Mixture, np.array([0.5]),
            np.zeros((1, 2)), eye)
    _raises("mixture weights must be non-negative and sum to 1, got sum 1", Mixture, np.array([1.5, -0.5]),
            np.zeros((2, 2)), np.stack([np.eye(2)] * 2))
    _raises("mixture weights must be non-negative and sum to 1, got sum 1", Mixture, np.array([1.0 + 2e-9]),
            np.zeros((1, 2)), eye)
    assert Mixture(np.array([1.0 + 5e-10]), np.zeros((1, 2)), eye).n_components == 1  # within 1e-9
    _raises("mixture covariance 1 is not positive definite", Mixture, np.array([0.5, 0.5]), np.zeros((2, 2)),
            np.stack([np.eye(2), -np.eye(2)]))
    _raises("2 labels for 1 components", Mixture, np.ones(1), np.zeros((1, 2)), eye, labels=["a", "b"])
    m = Mixture(np.ones(1), np.zeros((1, 2)), eye)
    _raises("points must have shape (n, 2), got (2, 2, 1)", m.log_density, np.zeros((2, 2, 1)))
    _raises("points has NaN at rows 0", m.component_log_densities, np.array([np.nan, 0.0]))


def test_labeled_ml_messages_and_boundaries():
    X = np.random.default_rng(5).standard_normal((6, 2))
    _raises("weights W has no columns: shape (3, 0)", labeled_ml, np.zeros((3, 0)), [0, 1, 2])
    _raises("weights W is too short: 0 sample(s), need at least 1", labeled_ml, np.zeros((0, 2)), [])
    _raises("weights W must have 2 dimension(s), got shape (6,)", labeled_ml, X[:, 0], range(6))
    _raises("min_variance must be >= 0, got -1.0", labeled_ml, X, range(6), -1.0)
    _raises("min_variance must be >= 0, got nan", labeled_ml, X, range(6), np.nan)
    _raises("label 'b' has 2 sample(s) in 2 dimensions: its covariance is singular; use min_variance > 0",
            labeled_ml, X, ["a", "a", "a", "b", "b", "a"], 0.0)
    m = labeled_ml(X[:2], ["only", "only"])  # 2 samples in 2 dimensions: the default min_variance makes it PD
    assert m.labels == ("only",) and m.n_components == 1
    three = labeled_ml(X[:3], ["x"] * 3, 0.0)  # 3 samples in 2 dimensions: enough without min_variance
    np.testing.assert_allclose(three.covs[0], np.cov(X[:3].T, bias=True), rtol=0, atol=1e-12)
    _raises("labeled_ml: mixture covariance 0 is not positive definite; raise min_variance", labeled_ml,
            np.ones((3, 2)), ["x"] * 3, 0.0)  # enough samples, but all equal


def test_batch_em_passes_its_settings_to_scikit_learn(monkeypatch):
    import sklearn.mixture

    seen = {}
    real = sklearn.mixture.GaussianMixture

    def spy(**kwargs):
        seen.update(kwargs)
        return real(**kwargs)

    monkeypatch.setattr(sklearn.mixture, "GaussianMixture", spy)
    X, _, _ = _clusters(np.random.default_rng(6))
    batch_em(X, 3, random_state=7)
    expected_seed = int(np.random.default_rng(7).integers(2 ** 31 - 1))
    assert seen == dict(n_components=3, covariance_type="full", n_init=5, reg_covar=1e-6, max_iter=500,
                        random_state=expected_seed)
    batch_em(X, 2, random_state=np.random.default_rng(7), n_init=2, reg_covar=1e-3, max_iter=50)
    assert seen == dict(n_components=2, covariance_type="full", n_init=2, reg_covar=1e-3, max_iter=50,
                        random_state=expected_seed)


def test_batch_em_messages_and_boundaries():
    X, _, _ = _clusters(np.random.default_rng(7), n_per=(5, 5, 5))
    assert batch_em(X, 1, random_state=0).n_components == 1
    assert batch_em(X[:2], 1, random_state=0).n_components == 1  # one component needs two points
    assert batch_em(X[:3], 3, random_state=0, n_init=1).n_components == 3  # as many distinct points as components
    _raises("n_components must be an integer >= 1, got 0", batch_em, X, 0)
    _raises("n_components must be an integer >= 1, got 2.5", batch_em, X, 2.5)
    _raises("n_components must be an integer >= 1, got True", batch_em, X, True)
    _raises("n_init must be an integer >= 1, got 0", batch_em, X, 2, n_init=0)
    _raises("n_init must be an integer >= 1, got 1.5", batch_em, X, 2, n_init=1.5)
    _raises("n_init must be an integer >= 1, got True", batch_em, X, 2, n_init=True)
    _raises("reg_covar must be positive, got nan", batch_em, X, 2, reg_covar=np.nan)
    _raises("weights W is too short: 1 sample(s), need at least 2", batch_em, X[:1], 1)
    _raises("weights W is too short: 2 sample(s), need at least 3", batch_em, X[:2], 3)
    W = np.array([[0.0, 1.0], [0.0, 1.0], [2.0, 3.0]])  # 2 distinct rows, 3 distinct values
    _raises("weights W has only 2 distinct row(s), cannot fit 3 components", batch_em, W, 3)
    m = batch_em(X, 2.0, random_state=0)  # an integral float is a count
    assert m.n_components == 2 and abs(m.weights.sum() - 1) < 1e-12


def test_zero_weight_component_gives_no_warning_and_one_column_is_enough():
    import warnings

    m = Mixture(np.array([0.0, 1.0]), np.zeros((2, 1)), np.ones((2, 1, 1)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # log(0) of the zero weight must not warn
        out = m.component_log_densities(np.zeros((1, 1)))
    assert out[0, 0] == -np.inf
    one = labeled_ml(np.arange(6.0)[:, None], list("aabbcc"))
    assert one.dim == 1 and one.labels == ("a", "b", "c")
    _raises("reg_covar must be positive, got 0.0", batch_em, np.arange(12.0).reshape(6, 2), 2, reg_covar=0.0)
