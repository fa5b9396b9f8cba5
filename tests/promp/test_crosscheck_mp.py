"""Cross-checks against movement_primitives' ProMP (an independent implementation).

movement_primitives uses normalized Gaussian RBFs with centres evenly spaced over
[0, 1] and variance ``h = -1 / (8 N^2 log 0.7)``; our ``GaussianBasis`` with
``normalized=True`` and ``width = sqrt(h) (N - 1)`` is the same basis, so weights,
reconstructions and conditioned distributions can be compared directly.
"""
import numpy as np
from movement_primitives.promp import ProMP

from drake_skills.promp.basis import GaussianBasis, phases, ridge_weights, trajectory_from_weights
from drake_skills.promp.interaction import InteractionProMP

N, D, T = 10, 3, 120


def _matched_basis(n_basis):
    h = -1.0 / (8.0 * n_basis ** 2 * np.log(0.7))
    return GaussianBasis(n_basis, width=np.sqrt(h) * (n_basis - 1), normalized=True)


def _demo(rng):
    z = phases(T)
    a = rng.normal(1.0, 0.2, D)
    return np.stack([a[0] * np.sin(np.pi * z), a[1] * z ** 2, a[2] * np.cos(2 * z)], axis=1)


def test_matched_basis_has_their_phi():
    theirs = ProMP(D, N)._rbfs_1d_sequence(np.linspace(0, 1, T).copy())  # (N, T); it divides T in place
    np.testing.assert_allclose(_matched_basis(N).phi(phases(T)), theirs.T, rtol=1e-12, atol=1e-15)


def test_weights_and_reconstruction_agree():
    Y = _demo(np.random.default_rng(0))
    theirs = ProMP(D, N)
    w_theirs = theirs.weights(np.linspace(0, 1, T), Y, lmbda=1e-8)
    basis = _matched_basis(N)
    w_ours = ridge_weights(Y, basis, ridge=1e-8)
    # same stacking (per dimension); the normal equations are solved differently (pinv vs solve)
    np.testing.assert_allclose(w_ours, w_theirs, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(trajectory_from_weights(w_ours, basis, D, n_steps=T),
                               theirs.trajectory_from_weights(np.linspace(0, 1, T), w_theirs), rtol=0, atol=1e-8)


def _fitted_pair(noise):
    rng = np.random.default_rng(1)
    basis = _matched_basis(N)
    ours = InteractionProMP(D, 0, basis_human=basis, ridge=1e-8, observation_noise=noise)
    ours.fit([_demo(rng) for _ in range(25)])
    theirs = ProMP(D, N).from_weight_distribution(ours.mean_.copy(), ours.cov_.copy())
    return ours, theirs


def test_conditioning_at_one_phase_agrees_with_condition_position():
    noise = 1e-3
    ours, theirs = _fitted_pair(noise)
    y = np.array([0.4, 0.1, 0.9])
    for z in (0.0, 0.37, 1.0):
        post = ours.condition(y[None, :], [z])
        ref = theirs.condition_position(y, y_cov=noise * np.eye(D), t=z, t_max=1.0)
        # tolerance: both are exact formulas in double precision; ref inverts a 3x3 directly
        np.testing.assert_allclose(post.mean_, ref.weight_mean, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(post.cov_, ref.weight_cov, rtol=1e-7, atol=1e-10)


def test_conditioning_on_many_points_equals_chained_condition_position():
    noise = 1e-2
    ours, theirs = _fitted_pair(noise)
    z = np.array([0.05, 0.2, 0.5, 0.8])
    Y = _demo(np.random.default_rng(9))[np.round(z * (T - 1)).astype(int)]
    post = ours.condition(Y, z)
    ref = theirs
    for zi, yi in zip(z, Y):  # sequential Bayesian updates equal the joint update
        ref = ref.condition_position(yi, y_cov=noise * np.eye(D), t=zi, t_max=1.0)
    np.testing.assert_allclose(post.mean_, ref.weight_mean, rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(post.cov_, ref.weight_cov, rtol=1e-6, atol=1e-9)
    mean_traj, _ = post.human_distribution(n_steps=T)
    np.testing.assert_allclose(mean_traj, ref.mean_trajectory(np.linspace(0, 1, T)), rtol=0, atol=1e-7)
