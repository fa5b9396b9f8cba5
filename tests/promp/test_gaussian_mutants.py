"""Gaussian helpers: the behaviours `make mutate` found untested (issue 20).

float32 inputs are computed in float64; a rank-deficient mixture component is
sampled with the jitter its density is evaluated with; a weight-0 component is
never drawn from.
"""
import numpy as np
import pytest

from drake_skills.promp import gaussian as g


def _spd(rng, d, ridge=0.1):
    A = rng.standard_normal((d, d))
    return A @ A.T / d + ridge * np.eye(d)


def test_float32_inputs_are_computed_in_float64():
    rng = np.random.default_rng(0)
    d = 6
    S = _spd(rng, d).astype(np.float32)
    L = g.cholesky(S)
    assert L.dtype == np.float64
    # the factor of the float32 matrix read exactly as float64, not a float32 factorization (~1e-7 off)
    np.testing.assert_allclose(L, np.linalg.cholesky(S.astype(np.float64)), rtol=0, atol=1e-14)

    x = rng.standard_normal((5, d)).astype(np.float32)
    mean = rng.standard_normal(d).astype(np.float32)
    ref = g.mahalanobis_sq(x.astype(np.float64), mean.astype(np.float64), L)
    # x - mean in float32 would be off by ~1e-7 relative
    np.testing.assert_allclose(g.mahalanobis_sq(x, mean, L), ref, rtol=1e-13, atol=0)

    w = np.array([0.3, 0.7], np.float32)
    means = rng.standard_normal((2, d))
    chols = [g.cholesky(_spd(rng, d)) for _ in range(2)]
    ref = g.gmm_log_density(x, w.astype(np.float64), means, chols)
    # log of a float32 weight would be off by ~3e-8
    np.testing.assert_allclose(g.gmm_log_density(x, w, means, chols), ref, rtol=0, atol=1e-13)


def test_sample_mixture_draws_a_rank_deficient_component_with_the_jittered_factor():
    # A rank-1 covariance: numpy's own Cholesky sampling raises LinAlgError; the density uses
    # g.cholesky's jitter, and so must the sampling (mc_kl_mixtures used to fail here).
    v = np.array([1.0, 2.0, -1.0])
    S = np.outer(v, v)
    mean = np.array([0.5, -1.0, 2.0])
    x = g.sample_mixture([1.0], [mean], [S], 4000, random_state=0)
    assert x.shape == (4000, 3)
    # every draw on the line mean + t v (jitter ~1e-5 across it)
    off = (x - mean) - np.outer((x - mean) @ v / (v @ v), v)
    assert np.abs(off).max() < 1e-4
    # its spread along the line is |v|: the sample variance within 5 % (n = 4000: se 2.2 %)
    t = (x - mean) @ v / (v @ v)
    assert abs(t.var() - 1.0) < 0.05
    kl = g.mc_kl_mixtures(([1.0], [mean], [S]), ([1.0], [mean], [S + np.eye(3)]), 500, random_state=1)
    assert np.isfinite(kl) and kl > 0


def test_sample_mixture_equals_numpy_cholesky_sampling_for_a_positive_definite_mixture():
    # The rewrite kept the random stream: results computed before it (RESULTS.md KLs) still hold.
    rng = np.random.default_rng(2)
    w = np.array([0.2, 0.8])
    means = rng.standard_normal((2, 4))
    covs = np.stack([_spd(rng, 4) for _ in range(2)])
    x = g.sample_mixture(w, means, covs, 300, random_state=5)
    ref_rng = np.random.default_rng(5)
    counts = ref_rng.multinomial(300, w)
    ref = np.concatenate([ref_rng.multivariate_normal(means[k], covs[k], size=c, method="cholesky")
                          for k, c in enumerate(counts) if c > 0])
    np.testing.assert_array_equal(x, ref[ref_rng.permutation(300)])


def test_sample_mixture_never_factorizes_a_weight_zero_component():
    # A weight-0 slot whose covariance is not a covariance at all is never touched.
    x = g.sample_mixture([1.0, 0.0], [np.zeros(2), np.zeros(2)], [np.eye(2), -np.eye(2)], 50, random_state=0)
    assert x.shape == (50, 2)
    with pytest.raises(ValueError, match=r"^covariance is not positive definite \(Cholesky failed even with jitter\)$"):
        g.sample_mixture([0.5, 0.5], [np.zeros(2), np.zeros(2)], [np.eye(2), -np.eye(2)], 50, random_state=0)
