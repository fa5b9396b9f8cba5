"""Gaussian basis functions over phase and ridge-regression weights (Eqs. 3-4).

Weights are stacked per dimension, ``w = [w_1; ...; w_D]`` with ``w_d`` the
``N`` weights of dimension ``d`` (Eq. 4), so a trajectory ``Y`` of shape
``(T, D)`` maps to a vector of length ``D * N``. The block-diagonal
``(T*D) x (N*D)`` design matrix is never built: all dimensions share one
``N x N`` ridge system.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from drake_skills._checks import as_finite_array


@dataclass(frozen=True)
class GaussianBasis:
    """``n_basis`` Gaussians with centres evenly spaced over phase ``[0, 1]``.

    Parameters
    ----------
    n_basis : int
        Number of basis functions N (>= 2).
    width : float
        Standard deviation of each Gaussian as a multiple of the spacing
        between neighbouring centres (1.0 gives a smooth, well-conditioned fit).
    normalized : bool
        If True every row of Phi is divided by its sum (the classic ProMP basis).
    """

    n_basis: int
    width: float = 1.0
    normalized: bool = False

    def __post_init__(self):
        if int(self.n_basis) != self.n_basis or self.n_basis < 2:
            raise ValueError(f"n_basis must be an integer >= 2, got {self.n_basis!r}")
        if not np.isfinite(self.width) or self.width <= 0:
            raise ValueError(f"width must be positive, got {self.width!r}")
        object.__setattr__(self, "n_basis", int(self.n_basis))
        object.__setattr__(self, "width", float(self.width))

    @property
    def centers(self) -> np.ndarray:
        return np.linspace(0.0, 1.0, self.n_basis)

    @property
    def sigma(self) -> float:
        return self.width / (self.n_basis - 1)

    def phi(self, z) -> np.ndarray:
        """Basis matrix.

        Parameters
        ----------
        z : array, shape (T,)
            Phases, each in [0, 1].

        Returns
        -------
        Phi : array, shape (T, N)
        """
        z = as_finite_array(z, "phase", ndim=1)
        if z.size and (z.min() < -1e-9 or z.max() > 1 + 1e-9):
            raise ValueError(f"phase must lie in [0, 1], got [{z.min():g}, {z.max():g}]")
        Phi = np.exp(-0.5 * ((z[:, None] - self.centers[None, :]) / self.sigma) ** 2)
        if self.normalized:
            Phi /= Phi.sum(axis=1, keepdims=True)
        return Phi

    def phi_uniform(self, n_steps: int) -> np.ndarray:
        """Phi at ``n_steps`` evenly spaced phases over [0, 1] (cached, read-only)."""
        return _phi_uniform(self, int(n_steps))

    def dict(self) -> dict:
        return {"n_basis": self.n_basis, "width": self.width, "normalized": self.normalized}


def phases(n_steps: int) -> np.ndarray:
    """``n_steps`` evenly spaced phases over [0, 1]."""
    if n_steps < 2:
        raise ValueError(f"need at least 2 time steps, got {n_steps}")
    return np.linspace(0.0, 1.0, n_steps)


@lru_cache(maxsize=64)
def _phi_uniform(basis: GaussianBasis, n_steps: int) -> np.ndarray:
    Phi = basis.phi(phases(n_steps))
    Phi.setflags(write=False)
    return Phi


@lru_cache(maxsize=64)
def _ridge_operator(basis: GaussianBasis, n_steps: int, ridge: float) -> np.ndarray:
    """``(Phi^T Phi + ridge I)^{-1} Phi^T``, shape (N, T), for uniform phases."""
    Phi = _phi_uniform(basis, n_steps)
    A = Phi.T @ Phi + ridge * np.eye(basis.n_basis)
    P = np.linalg.solve(A, Phi.T)
    P.setflags(write=False)
    return P


def ridge_weights(Y, basis: GaussianBasis, ridge: float = 1e-6, z=None) -> np.ndarray:
    """Ridge-regression weights of a trajectory, stacked per dimension (Eqs. 3-4).

    Parameters
    ----------
    Y : array, shape (T, D)
        Trajectory sampled at phases ``z``.
    basis : GaussianBasis
    ridge : float
        Ridge factor (the paper's beta in Eq. 3), >= 0.
    z : array, shape (T,), optional
        Phases of the samples; evenly spaced over [0, 1] if omitted.

    Returns
    -------
    w : array, shape (D * N,)
        ``[w_1; ...; w_D]``.
    """
    Y = as_finite_array(Y, "trajectory", ndim=2)
    T = Y.shape[0]
    if T < 2:
        raise ValueError(f"trajectory is too short: {T} sample(s), need at least 2")
    if not np.isfinite(ridge) or ridge < 0:
        raise ValueError(f"ridge must be >= 0, got {ridge!r}")
    if ridge == 0 and T < basis.n_basis:
        raise ValueError(f"{T} samples cannot determine {basis.n_basis} weights without a ridge term")
    if z is None:
        P = _ridge_operator(basis, T, float(ridge))
        W = P @ Y  # (N, D)
    else:
        z = as_finite_array(z, "phase", shape=(T,))
        Phi = basis.phi(z)
        W = np.linalg.solve(Phi.T @ Phi + ridge * np.eye(basis.n_basis), Phi.T @ Y)
    return W.T.reshape(-1)  # stacked per dimension: (D, N) -> (D*N,)


def trajectory_from_weights(w, basis: GaussianBasis, n_dims: int, z=None, n_steps: int = 100) -> np.ndarray:
    """Trajectory of stacked weights.

    Parameters
    ----------
    w : array, shape (n_dims * N,)
    basis : GaussianBasis
    n_dims : int
    z : array, shape (T,), optional
        Phases; ``n_steps`` evenly spaced phases if omitted.

    Returns
    -------
    Y : array, shape (T, n_dims)
    """
    w = as_finite_array(w, "weights", shape=(n_dims * basis.n_basis,))
    Phi = basis.phi_uniform(n_steps) if z is None else basis.phi(z)
    return Phi @ w.reshape(n_dims, basis.n_basis).T  # (T, N) @ (N, D)


def trajectory_variance(Sigma, basis: GaussianBasis, n_dims: int, z=None, n_steps: int = 100) -> np.ndarray:
    """Per-step variance of each dimension of the trajectory of weights ~ N(mu, Sigma).

    The diagonals of :func:`trajectory_covariance` (``var[t, d] = phi_t^T Sigma_dd phi_t``) from the
    diagonal blocks of ``Sigma`` alone: a controller that shows or bounds each joint's spread needs
    no cross-joint covariance, and this costs about a fourth of it (7 joints, 20 basis functions,
    100 steps: 0.07 against 0.28 ms on one machine).

    Returns
    -------
    var : array, shape (T, n_dims)
    """
    N = basis.n_basis
    Sigma = as_finite_array(Sigma, "covariance", shape=(n_dims * N, n_dims * N))
    Phi = basis.phi_uniform(n_steps) if z is None else basis.phi(z)
    d = np.arange(n_dims)
    blocks = Sigma.reshape(n_dims, N, n_dims, N)[d, :, d, :]                  # (D, N, N)
    return np.einsum("dtj,tj->td", np.matmul(Phi[None], blocks), Phi)


def trajectory_covariance(Sigma, basis: GaussianBasis, n_dims: int, z=None, n_steps: int = 100) -> np.ndarray:
    """Per-step covariance of the trajectory of weights ~ N(mu, Sigma).

    Returns
    -------
    cov : array, shape (T, n_dims, n_dims)
        ``cov[t] = Psi_t Sigma Psi_t^T`` with ``Psi_t = I_D (x) phi_t^T``.
    """
    N = basis.n_basis
    Sigma = as_finite_array(Sigma, "covariance", shape=(n_dims * N, n_dims * N))
    Phi = basis.phi_uniform(n_steps) if z is None else basis.phi(z)
    # cov[t, d, e] = sum_ij Phi[t, i] S[d, i, e, j] Phi[t, j]: one small matmul per
    # dimension d, then a reduction over j. One big (T x N) @ (N x D*D*N) product would be
    # the same flops, but it crosses OpenBLAS's threading threshold and on a 2-core
    # machine costs 3-5x more in thread start-up than it saves (measured: 0.29 vs 0.05 ms).
    # The reduction over j as a batched product (t, d, e, j) @ (t, j, 1): the einsum it replaces cost
    # 1.5x more (7 joints, 15 basis functions, 100 steps: 0.25 against 0.16 ms on one machine).
    T = Phi.shape[0]
    tmp = np.matmul(Phi[None], Sigma.reshape(n_dims, N, n_dims * N))  # (d, t, e*j)
    cov = np.matmul(tmp.reshape(n_dims, T, n_dims, N).transpose(1, 0, 2, 3), Phi[:, None, :, None])[..., 0]
    return 0.5 * (cov + cov.transpose(0, 2, 1))
