"""Gaussian basis, ridge weights (Eqs. 3-4) and trajectories from weights."""
import numpy as np
import pytest

from drake_skills.promp.basis import (GaussianBasis, phases, ridge_weights, trajectory_covariance,
                                      trajectory_from_weights)


def _smooth(T=200):
    z = phases(T)
    return np.stack([np.sin(2 * np.pi * z), z ** 2 - 0.5 * z, np.exp(-z) * np.cos(3 * z)], axis=1)


@pytest.mark.parametrize("basis", [GaussianBasis(25, width=1.5), GaussianBasis(25, normalized=True)])
def test_weights_reproduce_smooth_trajectory_below_1e_3_rms(basis):
    # Note: the default GaussianBasis(25) (unnormalized, width 1.0) saturates at ~2e-3 RMS on this
    # unit-amplitude signal, mostly at the two ends where only half the Gaussians reach.
    Y = _smooth()
    w = ridge_weights(Y, basis, ridge=1e-10)
    Y_hat = trajectory_from_weights(w, basis, 3, n_steps=Y.shape[0])
    rms = np.sqrt(np.mean((Y_hat - Y) ** 2))
    assert rms < 1e-3, rms


def test_reconstruction_error_falls_with_more_basis_functions():
    Y = _smooth()
    errs = [np.sqrt(np.mean((trajectory_from_weights(ridge_weights(Y, GaussianBasis(n)), GaussianBasis(n), 3,
                                                     n_steps=200) - Y) ** 2)) for n in (5, 10, 20)]
    assert errs[0] > errs[1] > errs[2]


def test_weights_are_stacked_per_dimension():
    Y = _smooth()
    basis = GaussianBasis(8)
    w = ridge_weights(Y, basis)
    assert w.shape == (3 * 8,)
    for d in range(3):
        np.testing.assert_allclose(w[d * 8:(d + 1) * 8], ridge_weights(Y[:, [d]], basis), rtol=0, atol=1e-12)


def test_ridge_weights_at_given_phases_match_uniform_operator():
    Y = _smooth(50)
    basis = GaussianBasis(7, normalized=True)
    np.testing.assert_allclose(ridge_weights(Y, basis, z=phases(50)), ridge_weights(Y, basis), rtol=1e-9, atol=1e-10)


def test_phi_of_normalized_basis_sums_to_one():
    Phi = GaussianBasis(6, width=0.5, normalized=True).phi(np.linspace(0, 1, 33))
    np.testing.assert_allclose(Phi.sum(axis=1), 1.0, rtol=0, atol=1e-12)


def test_trajectory_covariance_matches_sampling():
    rng = np.random.default_rng(0)
    basis, D = GaussianBasis(5), 2
    A = rng.standard_normal((10, 10))
    Sigma = A @ A.T / 10 + 0.01 * np.eye(10)
    mu = rng.standard_normal(10)
    cov = trajectory_covariance(Sigma, basis, D, n_steps=30)
    W = rng.multivariate_normal(mu, Sigma, size=40000)
    Ys = np.stack([trajectory_from_weights(w, basis, D, n_steps=30) for w in W[:4000]])
    # brute force Psi_t Sigma Psi_t^T with Psi_t = I_D (x) phi_t^T
    Phi = basis.phi_uniform(30)
    for t in (0, 13, 29):
        Psi = np.kron(np.eye(D), Phi[t][None, :])
        np.testing.assert_allclose(cov[t], Psi @ Sigma @ Psi.T, rtol=1e-10, atol=1e-12)
    # sample covariance of 4000 trajectories: relative standard error ~ sqrt(2/4000) = 2.2%; allow 10%
    emp = np.einsum("ktd,kte->tde", Ys - Ys.mean(0), Ys - Ys.mean(0)) / Ys.shape[0]
    scale = np.sqrt(np.einsum("tdd->td", cov))
    err = np.abs(emp - cov) / (scale[:, :, None] * scale[:, None, :])
    assert err.max() < 0.1, err.max()


def test_basis_rejects_bad_parameters():
    with pytest.raises(ValueError, match="n_basis"):
        GaussianBasis(1)
    with pytest.raises(ValueError, match="n_basis"):
        GaussianBasis(3.5)
    with pytest.raises(ValueError, match="width"):
        GaussianBasis(5, width=0.0)
    with pytest.raises(ValueError, match="width"):
        GaussianBasis(5, width=np.nan)
    with pytest.raises(ValueError, match="phase must lie"):
        GaussianBasis(5).phi([0.0, 1.2])
    with pytest.raises(ValueError, match="phase has NaN"):
        GaussianBasis(5).phi([0.0, np.nan])
    with pytest.raises(ValueError, match="phase must have 1 dimension"):
        GaussianBasis(5).phi(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="at least 2 time steps"):
        phases(1)


def test_ridge_weights_rejects_bad_input():
    basis = GaussianBasis(5)
    with pytest.raises(ValueError, match="trajectory has NaN at rows 3"):
        Y = np.zeros((10, 2))
        Y[3, 1] = np.nan
        ridge_weights(Y, basis)
    with pytest.raises(ValueError, match="trajectory has inf"):
        ridge_weights(np.full((10, 2), np.inf), basis)
    with pytest.raises(ValueError, match="trajectory must have 2 dimension"):
        ridge_weights(np.zeros(10), basis)
    with pytest.raises(ValueError, match="too short"):
        ridge_weights(np.zeros((1, 2)), basis)
    with pytest.raises(ValueError, match="ridge"):
        ridge_weights(np.zeros((10, 2)), basis, ridge=-1.0)
    with pytest.raises(ValueError, match="cannot determine"):
        ridge_weights(np.zeros((3, 2)), basis, ridge=0.0)
    with pytest.raises(ValueError, match="phase must have shape"):
        ridge_weights(np.zeros((10, 2)), basis, z=np.linspace(0, 1, 9))


def test_trajectory_functions_reject_bad_input():
    basis = GaussianBasis(4)
    with pytest.raises(ValueError, match=r"weights must have shape \(8\)"):
        trajectory_from_weights(np.zeros(7), basis, 2)
    with pytest.raises(ValueError, match="weights has NaN"):
        trajectory_from_weights(np.full(8, np.nan), basis, 2)
    with pytest.raises(ValueError, match=r"covariance must have shape \(8, 8\)"):
        trajectory_covariance(np.eye(7), basis, 2)
    with pytest.raises(ValueError, match="covariance has inf"):
        trajectory_covariance(np.full((8, 8), np.inf), basis, 2)
    with pytest.raises(ValueError, match="at least 2 time steps"):
        trajectory_from_weights(np.zeros(8), basis, 2, n_steps=1)


def test_basis_boundaries_types_and_dict():
    b = GaussianBasis(2.0, width=2)  # the smallest basis; integral floats are accepted
    assert type(b.n_basis) is int and b.n_basis == 2 and type(b.width) is float and b.width == 2.0
    assert b.dict() == {"n_basis": 2, "width": 2.0, "normalized": False}
    assert GaussianBasis(5, 0.5, True).dict() == {"n_basis": 5, "width": 0.5, "normalized": True}
    assert phases(2).tolist() == [0.0, 1.0]
    with pytest.raises(ValueError, match=r"^need at least 2 time steps, got 1$"):
        phases(1)
    with pytest.raises(ValueError, match=r"^n_basis must be an integer >= 2, got 1$"):
        GaussianBasis(1)


def test_phi_rejects_phases_outside_0_1_beyond_1e_9():
    b = GaussianBasis(4)
    assert b.phi([-1e-10, 1 + 1e-10]).shape == (2, 4)  # rounding is tolerated
    with pytest.raises(ValueError, match=r"^phase must lie in \[0, 1\], got \[-0.5, 0.5\]$"):
        b.phi([-0.5, 0.5])
    with pytest.raises(ValueError, match=r"^phase must lie in \[0, 1\], got \[0, 1.5\]$"):
        b.phi([0.0, 1.5])
    assert b.phi([]).shape == (0, 4)


def test_ridge_weights_defaults_and_small_trajectories():
    Y = _smooth(12)
    b = GaussianBasis(5)
    np.testing.assert_array_equal(ridge_weights(Y, b), ridge_weights(Y, b, 1e-6))
    assert not np.allclose(ridge_weights(Y, b), ridge_weights(Y, b, 1e-2))
    assert ridge_weights(Y[:2], b).shape == (15,)  # two samples are enough with a ridge term
    assert ridge_weights(Y[:3], b, 1e-6).shape == (15,)  # fewer samples than weights, with a ridge
    assert ridge_weights(Y[:5], b, 0.0).shape == (15,)  # as many samples as weights, without one
    with pytest.raises(ValueError, match=r"^4 samples cannot determine 5 weights without a ridge term$"):
        ridge_weights(Y[:4], b, 0.0)
    with pytest.raises(ValueError, match=r"^trajectory is too short: 1 sample\(s\), need at least 2$"):
        ridge_weights(Y[:1], b)


def test_trajectory_functions_default_to_100_steps_and_take_given_phases():
    rng = np.random.default_rng(3)
    b = GaussianBasis(6)
    w = rng.standard_normal(12)
    assert trajectory_from_weights(w, b, 2).shape == (100, 2)
    z = np.array([0.0, 0.3, 0.9])
    np.testing.assert_allclose(trajectory_from_weights(w, b, 2, z=z), b.phi(z) @ w.reshape(2, 6).T, rtol=0,
                               atol=1e-14)
    A = rng.standard_normal((12, 12))
    S = A @ A.T
    assert trajectory_covariance(S, b, 2).shape == (100, 2, 2)
    cov = trajectory_covariance(S, b, 2, z=z)
    Psi = np.kron(np.eye(2), b.phi(z)[1][None, :])
    np.testing.assert_allclose(cov[1], Psi @ S @ Psi.T, rtol=1e-10)
    assert cov.shape == (3, 2, 2)


def test_trajectory_covariance_is_psi_sigma_psi_at_every_step_for_seven_joints():
    """7 joints, 15 basis functions, 100 steps (the robot's prediction): every step equals the explicit
    Psi_t Sigma Psi_t^T within 1e-12 relative, and is symmetric exactly."""
    rng = np.random.default_rng(3)
    basis, D = GaussianBasis(15), 7
    A = rng.standard_normal((D * 15, D * 15))
    Sigma = A @ A.T
    cov = trajectory_covariance(Sigma, basis, D, n_steps=100)
    assert cov.shape == (100, D, D)
    Phi = basis.phi_uniform(100)
    for t in range(100):
        Psi = np.kron(np.eye(D), Phi[t][None, :])
        ref = Psi @ Sigma @ Psi.T
        np.testing.assert_allclose(cov[t], ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
        assert np.array_equal(cov[t], cov[t].T)


def test_trajectory_variance_is_the_diagonal_of_the_covariance():
    """7 joints at 100 uniform steps, 2 dimensions at given phases, and 1 dimension: the per-step variances equal
    the diagonals of trajectory_covariance within 1e-12 of the largest."""
    from drake_skills.promp.basis import trajectory_variance

    rng = np.random.default_rng(5)
    for N, D, z in ((20, 7, None), (5, 2, np.array([0.0, 0.3, 0.31, 1.0])), (6, 1, None)):
        basis = GaussianBasis(N)
        A = rng.standard_normal((D * N, D * N))
        Sigma = A @ A.T
        full = trajectory_covariance(Sigma, basis, D, z=z, n_steps=100)
        var = trajectory_variance(Sigma, basis, D, z=z, n_steps=100)
        assert var.shape == full.shape[:2]
        np.testing.assert_allclose(var, np.diagonal(full, axis1=1, axis2=2), rtol=0, atol=1e-12 * np.abs(full).max())
    assert trajectory_variance(np.eye(10), GaussianBasis(5), 2).shape == (100, 2)   # 100 steps by default
    with pytest.raises(ValueError, match=r"covariance must have shape \(10, 10\), got \(7, 7\)"):
        trajectory_variance(np.eye(7), GaussianBasis(5), 2)
    with pytest.raises(ValueError, match="covariance has NaN"):
        trajectory_variance(np.full((10, 10), np.nan), GaussianBasis(5), 2)
