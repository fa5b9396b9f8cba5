"""The likelihood of a partly observed motion (Eq. 13's marginal) against a direct Gaussian evaluation.

``observation_log_likelihood`` works in weight space through the push-through
identity; here the observation-space Gaussian N(H^T mu, sigma^2 I + H^T S H) over
vec(y) is built explicitly and evaluated with scipy, so every term (the
log-determinant included) is checked.
"""
import numpy as np
import pytest
from scipy.stats import multivariate_normal

from drake_skills.promp.basis import GaussianBasis
from drake_skills.promp.interaction import SEEN_RCOND, InteractionProMP, observation_log_likelihood


def _direct(mean_h, cov_hh, Phi_o, y, noise):
    """log N(vec(y) | H^T mu, noise I + H^T S H) with H^T = I_D (x) Phi_o, vec stacking per dimension."""
    D = y.shape[1]
    HT = np.kron(np.eye(D), Phi_o)  # (m D, D N)
    mean = HT @ mean_h
    cov = noise * np.eye(HT.shape[0]) + HT @ cov_hh @ HT.T
    x = y.T.reshape(-1)  # [y_1(t_1..t_m), y_2(...), ...]
    d2 = (x - mean) @ np.linalg.solve(cov, x - mean)
    return multivariate_normal(mean, cov).logpdf(x), d2, x.size


def _model(rng, D=2, N=6):
    d = D * N
    A = rng.standard_normal((d, d))
    return rng.standard_normal(d), A @ A.T / d + 0.05 * np.eye(d)


@pytest.mark.parametrize("D, m, noise", [(2, 9, 0.05), (3, 4, 0.5), (1, 20, 1e-3)])
def test_observation_log_likelihood_equals_the_observation_space_gaussian(D, m, noise):
    rng = np.random.default_rng(D * 100 + m)
    basis = GaussianBasis(6, normalized=True)
    mean_h, cov_hh = _model(rng, D)
    Phi_o = basis.phi(np.linspace(0.0, 0.4, m))
    y = rng.standard_normal((m, D))
    loglik, d2, n_obs = observation_log_likelihood(mean_h, cov_hh, Phi_o, y, noise)
    ref, ref_d2, ref_n = _direct(mean_h, cov_hh, Phi_o, y, noise)
    assert n_obs == ref_n == m * D
    assert d2 == pytest.approx(ref_d2, rel=1e-8)
    assert loglik == pytest.approx(ref, rel=1e-9, abs=1e-9)


def test_observation_log_likelihood_depends_on_the_covariance_through_the_log_determinant():
    """At the mean (d^2 = 0) only the normalization is left: a wider prior gives a lower density, by the
    exact log-determinant difference."""
    rng = np.random.default_rng(0)
    basis = GaussianBasis(5)
    mean_h, cov_hh = _model(rng, D=2, N=5)
    Phi_o = basis.phi(np.linspace(0.0, 0.5, 7))
    y = Phi_o @ mean_h.reshape(2, 5).T  # exactly the prior mean's trajectory
    narrow, d2, _ = observation_log_likelihood(mean_h, cov_hh, Phi_o, y, 0.1)
    wide, _, _ = observation_log_likelihood(mean_h, 4.0 * cov_hh, Phi_o, y, 0.1)
    assert d2 == pytest.approx(0.0, abs=1e-9)
    ref_narrow, _, _ = _direct(mean_h, cov_hh, Phi_o, y, 0.1)
    ref_wide, _, _ = _direct(mean_h, 4.0 * cov_hh, Phi_o, y, 0.1)
    assert narrow == pytest.approx(ref_narrow, rel=1e-9)
    assert wide == pytest.approx(ref_wide, rel=1e-9)
    assert wide < narrow - 1.0


def test_log_likelihood_human_uses_the_human_block_the_floor_and_the_noise():
    rng = np.random.default_rng(1)
    p = InteractionProMP(2, 3, basis_human=GaussianBasis(5), basis_robot=GaussianBasis(4), observation_noise=0.2)
    W = rng.standard_normal((40, p.n_weights)) @ rng.standard_normal((p.n_weights, p.n_weights)) * 0.3
    p.fit_weights(W)
    z = np.linspace(0.0, 0.7, 11)
    y = rng.standard_normal((11, 2))
    h = p.n_human
    Phi_o = p.basis_human.phi(z)
    for floor, noise in ((0.0, None), (0.5, None), (0.5, 0.01)):
        got = p.log_likelihood_human(y, z, observation_noise=noise, cov_floor=floor)
        ref = _direct(p.mean_[:h], p.cov_[:h, :h] + floor * np.eye(h), Phi_o, y, 0.2 if noise is None else noise)
        assert got[0] == pytest.approx(ref[0], rel=1e-9), (floor, noise)
        assert got[1] == pytest.approx(ref[1], rel=1e-8), (floor, noise)
        assert got[2] == 22


def _direct_fit_statistic(mean_h, cov_hh, Phi_o, y, noise, rcond=SEEN_RCOND):
    """The prefix test's statistic from explicit matrices in the samples' space: the residual ``r`` projected on the
    orthonormal sample-space directions ``E`` the basis sees well (left singular vectors of ``Phi_o`` with squared
    singular value at least ``rcond`` of the largest, per dimension), ``z = E^T r``, against its covariance
    ``E^T (noise I + H^T S H) E``; dof the number of directions (chi-square exactly under the model;
    tests/library/test_prefix_calibration.py)."""
    D = y.shape[1]
    HT = np.kron(np.eye(D), Phi_o)
    r = y.T.reshape(-1) - HT @ mean_h
    Uo, sv, _ = np.linalg.svd(Phi_o, full_matrices=False)
    E = np.kron(np.eye(D), Uo[:, sv ** 2 >= rcond * sv[0] ** 2])
    z = E.T @ r
    C = E.T @ (noise * np.eye(r.size) + HT @ cov_hh @ HT.T) @ E
    return float(z @ np.linalg.solve(C, z)), float(E.shape[1])


@pytest.mark.parametrize("f", [0.4, 0.75])
def test_prefix_recognition_uses_the_observation_likelihood_of_each_component(f):
    """SkillLibrary.recognize on a prefix of known fraction: log-likelihoods are the observation-space Gaussians
    of every component's predictive gating covariance Sigma (1 + 1/s_k) at the phases [0, f] with the learned
    observation noise (log-determinant included); the fit statistic and its dof from explicit matrices."""
    from drake_skills import LibraryConfig, SkillLibrary
    from synthetic import synthetic_demo

    cfg = LibraryConfig(n_samples=40, n_basis_human=6, n_basis_robot=6)
    lib = SkillLibrary(cfg)
    rng = np.random.default_rng(3)
    for i in range(9):
        lib.partial_fit(synthetic_demo(i % 3, rng, T=40))
    demo = synthetic_demo(1, rng, T=40)
    step = np.linalg.norm(np.diff(demo.human, axis=0), axis=1)
    cut = int(np.searchsorted(np.cumsum(step), f * step.sum())) + 1
    prefix = demo.human[:cut + 1]
    rec = lib.recognize(prefix, observed_fraction=f)
    m = int(round(f * 40))
    y = lib.human_samples(prefix, observed_fraction=f)
    assert y.shape == (m, 3)
    Phi_o = cfg.basis_human.phi(np.linspace(0.0, f, m))
    h = lib.n_human
    from brute_force import unshrink

    U = unshrink(cfg, h)                      # the samples see the least-squares weights S^-1 w
    G = U @ lib.shared_covariance() @ U.T
    noise = lib.observation_noise()
    for k, c in enumerate(lib.components):
        S = G * (1.0 + 1.0 / c.support)
        ref, _, _ = _direct(U @ c.mean[:h], S, Phi_o, y, noise)
        ref_d2, ref_dof = _direct_fit_statistic(U @ c.mean[:h], S, Phi_o, y, noise)
        assert rec.log_likelihoods[k] == pytest.approx(ref, rel=1e-9)
        assert rec.mahalanobis_sq[k] == pytest.approx(ref_d2, rel=1e-6, abs=1e-8)
        assert rec.dof[k] == pytest.approx(ref_dof, rel=1e-9)
        assert 0 < rec.dof[k] <= h
    assert rec.status == "skill" and rec.component == lib.recognize(demo.human, observed_fraction=1.0).component


@pytest.mark.parametrize("D, m, noise", [(2, 9, 0.05), (3, 4, 0.5), (1, 20, 1e-3)])
def test_prefix_statistics_equal_the_observation_space_gaussian_and_the_explicit_fit_statistic(D, m, noise):
    """The reference the library's batched prefix scoring is checked against (tests/brute_force.py), itself
    checked here: its log-likelihood (log-determinant included), statistic and dof from explicit matrices."""
    from drake_skills.promp.interaction import prefix_statistics

    rng = np.random.default_rng(D * 10 + m)
    basis = GaussianBasis(6, normalized=True)
    mean_h, cov_hh = _model(rng, D)
    Phi_o = basis.phi(np.linspace(0.0, 0.6, m))
    y = (np.kron(np.eye(D), Phi_o) @ mean_h).reshape(D, m).T + 0.3 * rng.standard_normal((m, D))
    loglik, d2, dof = prefix_statistics(mean_h, cov_hh, Phi_o, y, noise)
    ref, _, _ = _direct(mean_h, cov_hh, Phi_o, y, noise)
    ref_d2, ref_dof = _direct_fit_statistic(mean_h, cov_hh, Phi_o, y, noise)
    assert loglik == pytest.approx(ref, rel=1e-9)
    assert d2 == pytest.approx(ref_d2, rel=1e-6, abs=1e-9)
    assert dof == pytest.approx(ref_dof, rel=1e-9) and 0 < dof <= D * 6
