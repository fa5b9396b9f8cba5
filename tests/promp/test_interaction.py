"""Interaction ProMP: ML fit, conditioning (Eq. 13), sampling."""
import numpy as np
import pytest

from drake_skills.promp.basis import GaussianBasis, phases
from drake_skills.promp.gaussian import condition_gaussian
from drake_skills.promp.interaction import InteractionProMP


def _random_model(rng, dh=3, dr=2, nh=6, nr=8):
    p = InteractionProMP(dh, dr, basis_human=GaussianBasis(nh), basis_robot=GaussianBasis(nr))
    d = p.n_weights
    A = rng.standard_normal((d, d))
    return p.fit_weights(rng.standard_normal((3 * d, d)) @ A * 0.3 + rng.standard_normal(d))


def _explicit_H(p, z):
    """Observation matrix H^T (m*D_h, d): human rows only, stacked per dimension."""
    Phi = p.basis_human.phi(z)
    HT = np.zeros((len(z) * p.dim_human, p.n_weights))
    HT[:, :p.n_human] = np.kron(np.eye(p.dim_human), Phi)
    return HT


def test_condition_equals_closed_form_gaussian_conditional():
    rng = np.random.default_rng(0)
    p = _random_model(rng)
    z = np.array([0.0, 0.1, 0.35, 0.5])
    y = rng.standard_normal((4, 3))
    noise = 0.3
    post = p.condition(y, z, observation_noise=noise)
    # joint of [w; o] with o = H^T w + eps, then condition on o (computed independently)
    HT = _explicit_H(p, z)
    d, m = p.n_weights, HT.shape[0]
    mean_j = np.concatenate([p.mean_, HT @ p.mean_])
    cov_j = np.block([[p.cov_, p.cov_ @ HT.T], [HT @ p.cov_, HT @ p.cov_ @ HT.T + noise * np.eye(m)]])
    mu_ref, cov_ref = condition_gaussian(mean_j, cov_j, np.arange(d, d + m), y.T.reshape(-1))
    np.testing.assert_allclose(post.mean_, mu_ref, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(post.cov_, cov_ref, rtol=1e-7, atol=1e-8)


def test_condition_robot_block_only_equals_block_of_full_posterior():
    from drake_skills.promp.interaction import condition_on_observations

    rng = np.random.default_rng(3)
    p = _random_model(rng)
    z = np.linspace(0.0, 0.6, 9)
    y = rng.standard_normal((9, 3))
    Phi_o = p.basis_human.phi(z)
    mean, cov = condition_on_observations(p.mean_, p.cov_, Phi_o, y, 0.2)
    h = p.n_human
    mean_r, cov_r = condition_on_observations(p.mean_, p.cov_, Phi_o, y, 0.2, start=h)
    np.testing.assert_allclose(mean_r, mean[h:], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(cov_r, cov[h:, h:], rtol=1e-10, atol=1e-12)


def test_conditioned_mean_passes_through_observations_as_noise_vanishes():
    rng = np.random.default_rng(1)
    p = _random_model(rng)
    z = np.array([0.2, 0.6])  # fewer observations than basis functions: exact interpolation
    y = rng.standard_normal((2, 3))
    errs = []
    for noise in (1e-2, 1e-4, 1e-6):
        post = p.condition(y, z, observation_noise=noise)
        pred = p.basis_human.phi(z) @ post.mean_[:p.n_human].reshape(3, -1).T
        errs.append(np.abs(pred - y).max())
    assert errs[0] > errs[1] > errs[2]
    assert errs[-1] < 1e-4


def test_prefix_conditioning_uses_only_observed_phases():
    rng = np.random.default_rng(2)
    p = _random_model(rng)
    y = rng.standard_normal((30, 3))
    post = p.condition_prefix(y, observed_fraction=0.3)
    ref = p.condition(y, np.linspace(0, 0.3, 30))
    np.testing.assert_allclose(post.mean_, ref.mean_)
    with pytest.raises(ValueError, match="observed_fraction"):
        p.condition_prefix(y, observed_fraction=0.0)


def test_conditioning_recovers_robot_of_held_out_demo():
    """A tight single-skill model: robot = linear function of the human + small noise."""
    rng = np.random.default_rng(3)
    T = 100
    z = phases(T)
    humans, robots = [], []
    for _ in range(41):
        a = rng.normal(0, 1.0, size=3)
        human = np.stack([np.sin(np.pi * z) * (2 + a[0]), z * (3 + a[1]), z ** 2 * (1 + a[2])], axis=1)
        robot = np.stack([0.5 * a[0] * z, -0.3 * a[1] * np.sin(np.pi * z / 2)], axis=1) + 0.002 * rng.standard_normal((T, 2))
        humans.append(human)
        robots.append(robot)
    p = InteractionProMP(3, 2, basis_human=GaussianBasis(8), basis_robot=GaussianBasis(10), observation_noise=1e-3)
    p.fit(humans[:40], robots[:40])
    mean, cov = p.predict_robot(humans[40])
    prior_mean, _ = p.robot_distribution()
    err = np.sqrt(np.mean((mean - robots[40]) ** 2))
    prior_err = np.sqrt(np.mean((prior_mean - robots[40]) ** 2))
    assert err < 0.02, err
    assert err < 0.2 * prior_err
    assert cov.shape == (T, 2, 2)


def test_sample_is_seeded_and_matches_moments():
    rng = np.random.default_rng(4)
    p = _random_model(rng, dh=2, dr=1, nh=4, nr=4)
    h1, r1 = p.sample(5, random_state=7)
    h2, r2 = p.sample(5, random_state=7)
    np.testing.assert_array_equal(h1, h2)
    h, r = p.sample(20000, n_steps=20, random_state=0)
    mean_h, cov_h = p.human_distribution(n_steps=20)
    # standard error of a mean over 20000 samples: std/141; allow 5 standard errors
    tol = 5 * np.sqrt(np.einsum("tdd->td", cov_h)) / np.sqrt(20000)
    assert (np.abs(h.mean(axis=0) - mean_h) < tol).all()
    for bad in (0, -1, 2.5, True):   # 0 was numpy's "cannot reshape array of size 0"
        with pytest.raises(ValueError, match="n must be a positive integer"):
            p.sample(bad)
    assert p.sample(1)[0].shape == (1, 100, 2)   # one draw is fine


def test_interaction_rejects_bad_input():
    p = _random_model(np.random.default_rng(5))
    with pytest.raises(ValueError, match="NaN"):
        p.condition(np.full((3, 3), np.nan), [0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="shape"):
        p.condition(np.zeros((3, 2)), [0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="shape"):
        p.condition(np.zeros((3, 3)), [0.1, 0.2])
    with pytest.raises(ValueError, match="phase"):
        p.condition(np.zeros((2, 3)), [0.1, 1.5])
    with pytest.raises(ValueError, match="not fitted"):
        InteractionProMP(3, 2).robot_distribution()
    with pytest.raises(ValueError, match="robot"):
        InteractionProMP(3, 2).weights(np.random.rand(10, 3))
    with pytest.raises(ValueError, match="too short"):
        InteractionProMP(3, 0).weights(np.zeros((1, 3)))


def test_the_block_diagonal_helper_is_np_kron_with_an_identity():
    """interaction._blocks(M, D) equals np.kron(np.eye(D), M) exactly, square or rectangular blocks, D = 1 included."""
    from drake_skills.promp.interaction import _blocks

    rng = np.random.default_rng(1)
    for shape, D in (((15, 15), 3), ((7, 4), 2), ((5, 5), 1), ((3, 0), 2)):
        M = rng.normal(size=shape)
        np.testing.assert_array_equal(_blocks(M, D), np.kron(np.eye(D), M))
