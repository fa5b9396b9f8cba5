"""InteractionProMP: weights, moments, distributions and sampling against direct computations,
and every input check matched on the message a user sees."""
import re

import numpy as np
import pytest

from drake_skills.promp.basis import GaussianBasis, phases, ridge_weights
from drake_skills.promp.interaction import InteractionProMP


def _p(dh=2, dr=1, nh=4, nr=5, **kw):
    return InteractionProMP(dh, dr, basis_human=GaussianBasis(nh), basis_robot=GaussianBasis(nr), **kw)


def _fitted(rng, dh=2, dr=1, nh=4, nr=5):
    p = _p(dh, dr, nh, nr)
    d = p.n_weights
    return p.fit_weights(rng.standard_normal((3 * d, d)) @ rng.standard_normal((d, d)) * 0.3)


def test_defaults_sizes_and_noise():
    p = InteractionProMP(3)
    assert (p.dim_human, p.dim_robot) == (3, 0)
    assert p.basis_human == GaussianBasis(10) and p.basis_robot == GaussianBasis(20)
    assert p.ridge == 1e-6 and p.observation_noise == 0.25
    q = _p(3, 2, 6, 8, ridge=1e-3, observation_noise=0.1)
    assert (q.n_human, q.n_robot, q.n_weights) == (18, 16, 34)
    assert q.ridge == 1e-3 and q.observation_noise == 0.1


def test_weights_stack_the_ridge_weights_of_human_then_robot():
    rng = np.random.default_rng(0)
    p = _p(2, 3, 4, 5, ridge=1e-4)
    human, robot = rng.standard_normal((30, 2)), rng.standard_normal((30, 3))
    w = p.weights(human, robot)
    np.testing.assert_array_equal(w, np.r_[ridge_weights(human, p.basis_human, 1e-4),
                                           ridge_weights(robot, p.basis_robot, 1e-4)])
    h_only = InteractionProMP(2, basis_human=GaussianBasis(4), ridge=1e-4)
    np.testing.assert_array_equal(h_only.weights(human), ridge_weights(human, p.basis_human, 1e-4))


def test_fit_is_the_ml_fit_of_the_stacked_weights():
    rng = np.random.default_rng(1)
    p = _p()
    humans = [rng.standard_normal((20, 2)) for _ in range(6)]
    robots = [rng.standard_normal((20, 1)) for _ in range(6)]
    p.fit(humans, robots)
    W = np.stack([p.weights(h, r) for h, r in zip(humans, robots)])
    np.testing.assert_allclose(p.mean_, W.mean(0), rtol=0, atol=1e-12)
    np.testing.assert_allclose(p.cov_, np.cov(W.T, bias=True) + 1e-6 * np.eye(p.n_weights), rtol=0, atol=1e-12)
    assert p.n_demos_ == 6
    q = InteractionProMP(2, basis_human=GaussianBasis(4)).fit(humans)  # robots=None: human only
    np.testing.assert_allclose(q.mean_, W[:, :8].mean(0), rtol=0, atol=1e-12)
    assert q.fit_weights(W[:3, :8], min_variance=0.5).n_demos_ == 3
    np.testing.assert_allclose(np.diag(q.cov_), np.var(W[:3, :8], axis=0) + 0.5, rtol=0, atol=1e-12)


def test_from_moments_wraps_the_given_moments_unfitted_by_demonstrations():
    rng = np.random.default_rng(2)
    mean = rng.standard_normal(13)
    A = rng.standard_normal((13, 13))
    cov = A @ A.T
    p = InteractionProMP.from_moments(mean, cov, 2, 1, basis_human=GaussianBasis(4), basis_robot=GaussianBasis(5),
                                      observation_noise=0.3)
    np.testing.assert_array_equal(p.mean_, mean)
    np.testing.assert_allclose(p.cov_, cov, rtol=0, atol=1e-12)
    assert p.n_demos_ == 0 and p.observation_noise == 0.3 and p.dim_robot == 1
    h = InteractionProMP.from_moments(mean[:8], cov[:8, :8], 2, basis_human=GaussianBasis(4))
    assert h.dim_robot == 0 and h.n_weights == 8


def test_human_and_robot_distributions_are_the_basis_images_of_the_moments():
    rng = np.random.default_rng(3)
    p = _fitted(rng, dh=2, dr=2, nh=4, nr=5)
    h = p.n_human
    mean_h, cov_h = p.human_distribution()
    Phi = p.basis_human.phi(phases(100))
    assert mean_h.shape == (100, 2) and cov_h.shape == (100, 2, 2)
    np.testing.assert_allclose(mean_h, Phi @ p.mean_[:h].reshape(2, 4).T, rtol=0, atol=1e-12)
    t = 37
    Psi = np.kron(np.eye(2), Phi[t][None, :])  # (2, 8)
    np.testing.assert_allclose(cov_h[t], Psi @ p.cov_[:h, :h] @ Psi.T, rtol=1e-10, atol=1e-12)
    mean_r, cov_r = p.robot_distribution(n_steps=7)
    Phi_r = p.basis_robot.phi(phases(7))
    np.testing.assert_allclose(mean_r, Phi_r @ p.mean_[h:].reshape(2, 5).T, rtol=0, atol=1e-12)
    Psi = np.kron(np.eye(2), Phi_r[3][None, :])
    np.testing.assert_allclose(cov_r[3], Psi @ p.cov_[h:, h:] @ Psi.T, rtol=1e-10, atol=1e-12)
    assert p.robot_distribution()[0].shape == (100, 2)


def test_sample_gives_both_agents_from_one_weight_draw():
    rng = np.random.default_rng(4)
    p = _fitted(rng, dh=2, dr=3, nh=4, nr=5)
    human, robot = p.sample(3, random_state=0)
    assert human.shape == (3, 100, 2) and robot.shape == (3, 100, 3)
    human, robot = p.sample(4, n_steps=9, random_state=1)
    assert human.shape == (4, 9, 2) and robot.shape == (4, 9, 3)
    # recover the weights of each sample from the trajectories: they are one joint draw
    g = np.random.default_rng(1)
    L = np.linalg.cholesky(p.cov_)
    W = p.mean_ + g.standard_normal((4, p.n_weights)) @ L.T
    Phi_h, Phi_r = p.basis_human.phi(phases(9)), p.basis_robot.phi(phases(9))
    np.testing.assert_allclose(human[2], Phi_h @ W[2, :8].reshape(2, 4).T, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(robot[2], Phi_r @ W[2, 8:].reshape(3, 5).T, rtol=1e-10, atol=1e-10)


def test_condition_keeps_the_settings_and_uses_its_own_noise_unless_given():
    rng = np.random.default_rng(5)
    p = _fitted(rng)
    p.observation_noise = 0.2
    y, z = rng.standard_normal((5, 2)), np.linspace(0, 0.5, 5)
    post = p.condition(y, z)
    assert post is not p and post.n_demos_ == p.n_demos_ and post.observation_noise == 0.2
    assert post.basis_human == p.basis_human and post.basis_robot == p.basis_robot and post.ridge == p.ridge
    other = p.condition(y, z, observation_noise=0.05)
    assert other.observation_noise == 0.05
    assert not np.allclose(other.mean_, post.mean_)
    np.testing.assert_array_equal(p.condition(y, z, observation_noise=0.2).mean_, post.mean_)


def test_condition_prefix_defaults_to_the_whole_motion_and_passes_the_noise():
    rng = np.random.default_rng(6)
    p = _fitted(rng)
    y = rng.standard_normal((8, 2))
    np.testing.assert_array_equal(p.condition_prefix(y).mean_, p.condition(y, phases(8)).mean_)
    np.testing.assert_array_equal(p.condition_prefix(y, 0.5, observation_noise=0.01).mean_,
                                  p.condition(y, np.linspace(0, 0.5, 8), observation_noise=0.01).mean_)
    np.testing.assert_array_equal(p.condition_prefix(y, 1.0).cov_, p.condition(y, phases(8)).cov_)


def test_predict_robot_conditions_on_evenly_spaced_phases_by_default():
    rng = np.random.default_rng(7)
    p = _fitted(rng, dh=2, dr=2)
    y = rng.standard_normal((6, 2))
    mean, cov = p.predict_robot(y, n_steps=11)
    ref_mean, ref_cov = p.condition(y, phases(6)).robot_distribution(11)
    np.testing.assert_array_equal(mean, ref_mean)
    np.testing.assert_array_equal(cov, ref_cov)
    z = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5])
    mean, _ = p.predict_robot(y.tolist(), z, observation_noise=0.01)
    np.testing.assert_array_equal(mean, p.condition(y, z, observation_noise=0.01).robot_distribution(100)[0])
    assert p.predict_robot(y)[0].shape == (100, 2)


def test_interaction_promp_messages():
    p = _fitted(np.random.default_rng(8))  # D_h = 2, D_r = 1, 4 + 5 basis functions: 13 weights

    def raises(message, fn, *a, **k):
        with pytest.raises(ValueError, match="^" + re.escape(message)):
            fn(*a, **k)

    raises("need dim_human >= 1 and dim_robot >= 0, got 0, 0", InteractionProMP, 0)
    raises("need dim_human >= 1 and dim_robot >= 0, got 1, -1", InteractionProMP, 1, -1)
    assert InteractionProMP(1, 0).dim_human == 1
    raises("observation_noise must be a positive finite number, got 0.0", InteractionProMP, 2, observation_noise=0)
    raises("this InteractionProMP is not fitted yet: call fit() or from_moments()", _p().human_distribution)
    raises("this InteractionProMP is not fitted yet: call fit() or from_moments()", _p().condition,
           np.zeros((2, 2)), [0, 1])
    raises("this InteractionProMP is not fitted yet: call fit() or from_moments()", _p().log_likelihood_human,
           np.zeros((2, 2)), [0, 1])
    raises("human trajectory must have shape (any, 2), got (10, 3)", p.weights, np.zeros((10, 3)), np.zeros((10, 1)))
    raises("human trajectory is too short: 1 sample(s), need at least 2", p.weights, np.zeros((1, 2)),
           np.zeros((2, 1)))
    raises("human trajectory has NaN at rows 3", p.weights, np.where(np.arange(10)[:, None] == 3, np.nan, 0.0)
           * np.ones((10, 2)), np.zeros((10, 1)))
    raises("this InteractionProMP has a robot part: pass the robot trajectory", p.weights, np.zeros((10, 2)))
    raises("robot trajectory must have shape (any, 1), got (10, 2)", p.weights, np.zeros((10, 2)), np.zeros((10, 2)))
    raises("robot trajectory is too short: 1 sample(s), need at least 2", p.weights, np.zeros((10, 2)),
           np.zeros((1, 1)))
    raises("this InteractionProMP is human-only (dim_robot=0) but a robot trajectory was given",
           InteractionProMP(2, basis_human=GaussianBasis(4)).weights, np.zeros((10, 2)), np.zeros((10, 1)))
    raises("fit needs at least one demonstration", _p().fit, [])
    raises("weights must have shape (any, 13), got (5, 12)", _p().fit_weights, np.zeros((5, 12)))
    raises("weights is too short: 0 sample(s), need at least 1", _p().fit_weights, np.zeros((0, 13)))
    raises("mean must have shape (13), got (12,)", InteractionProMP.from_moments, np.zeros(12), np.eye(13), 2, 1,
           basis_human=GaussianBasis(4), basis_robot=GaussianBasis(5))
    raises("mean has NaN", InteractionProMP.from_moments, np.full(13, np.nan), np.eye(13), 2, 1,
           basis_human=GaussianBasis(4), basis_robot=GaussianBasis(5))
    raises("covariance must have shape (13, 13), got (12, 12)", InteractionProMP.from_moments, np.zeros(13),
           np.eye(12), 2, 1, basis_human=GaussianBasis(4), basis_robot=GaussianBasis(5))
    raises("observed human samples must have shape (any, 2), got (3, 3)", p.condition, np.zeros((3, 3)),
           [0.1, 0.2, 0.3])
    raises("observed human samples is too short: 0 sample(s), need at least 1", p.condition, np.zeros((0, 2)), [])
    raises("observed phases must have shape (3), got (2,)", p.condition, np.zeros((3, 2)), [0.1, 0.2])
    raises("observed phases has inf at rows 1", p.condition, np.zeros((2, 2)), [0.1, np.inf])
    raises("observation_noise must be a positive finite number, got -1.0", p.condition, np.zeros((2, 2)), [0, 1],
           observation_noise=-1)
    raises("observed_fraction must be in (0, 1], got 1.5", p.condition_prefix, np.zeros((3, 2)), 1.5)
    raises("observed_fraction must be in (0, 1], got 0", p.condition_prefix, np.zeros((3, 2)), 0)
    raises("observed human samples is too short: 1 sample(s), need at least 2", p.condition_prefix,
           np.zeros((1, 2)), 0.5)
    raises("observed human samples must have shape (any, 2), got (4, 1)", p.condition_prefix, np.zeros((4, 1)))
    raises("observation_noise must be a positive finite number, got 0.0", p.log_likelihood_human,
           np.zeros((2, 2)), [0, 1], observation_noise=0.0)
    raises("cov_floor must be >= 0, got -0.1", p.log_likelihood_human, np.zeros((2, 2)), [0, 1], cov_floor=-0.1)
    raises("cov_floor must be >= 0, got inf", p.log_likelihood_human, np.zeros((2, 2)), [0, 1], cov_floor=np.inf)
    raises("this InteractionProMP has no robot part (dim_robot=0)",
           InteractionProMP(2, basis_human=GaussianBasis(4)).fit_weights(np.zeros((3, 8))).robot_distribution)
    raises("2 human but 1 robot trajectories", _p().fit, [np.zeros((10, 2))] * 2, [np.zeros((10, 1))])
    assert p.condition_prefix(np.zeros((2, 2)), 1.0).mean_.shape == (13,)
    assert np.isfinite(p.log_likelihood_human(np.zeros((1, 2)), [0.5], cov_floor=0.0)[0])


def test_conditioning_keeps_a_non_default_ridge_and_likelihood_has_no_floor_by_default():
    rng = np.random.default_rng(9)
    p = _p(ridge=1e-3)
    p.fit_weights(rng.standard_normal((40, p.n_weights)))
    y, z = rng.standard_normal((4, 2)), np.linspace(0, 0.6, 4)
    assert p.condition(y, z).ridge == 1e-3
    assert p.log_likelihood_human(y, z) == p.log_likelihood_human(y, z, cov_floor=0.0)
    assert p.log_likelihood_human(y, z)[0] != p.log_likelihood_human(y, z, cov_floor=1.0)[0]


def test_predict_robot_from_two_samples_and_rejects_a_scalar():
    p = _fitted(np.random.default_rng(10))
    two = np.array([[0.0, 0.0], [1.0, 1.0]])
    np.testing.assert_array_equal(p.predict_robot(two)[0], p.condition(two, [0.0, 1.0]).robot_distribution(100)[0])
    with pytest.raises(ValueError, match=r"^observed human samples must have shape \(any, 2\), got \(\)$"):
        p.predict_robot(np.float64(1.0))
