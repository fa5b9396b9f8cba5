"""The beginning of a motion against many components at once: batched prefix statistics, and a bound that prunes.

:func:`~drake_skills.promp.interaction.prefix_statistics` scores the observed samples
of a motion's beginning against one component. Recognition asks it for every
component at five phases (:data:`~drake_skills.library.incremental.PHASE_GRID`); one
call per pair costs ~100 us of Python and small LAPACK calls, so a library of a
thousand components took seconds. Here the same statistics are computed for many
(component, phase) pairs in a handful of array operations, using what the library
shares: every component's gating covariance is the shared ``Sigma`` times
``c_k = 1 + 1/s_k``. With ``Sigma = L L^T`` and ``G = H H^T``,

    A = sigma^2 I + c G Sigma = L^{-T} B L^T,   B = sigma^2 I + c L^T G L  (symmetric positive definite),

so one Cholesky factor of ``B`` per pair gives the marginal likelihood
(``det A = det B``, ``u^T S A^{-1} u = c |R^{-1} L^T u|^2``) and the effective degrees
of freedom (``tr A^{-1} = |R^{-1}|_F^2``). The results equal the per-pair function to
rounding (``tests/library/test_scale.py`` checks both against each other).

For a large library :func:`prefix_candidates` first rules out the components that
cannot explain the samples, with a lower bound on the fit statistic ``d2`` that
looks at a few samples only (see its Notes); only the others are scored.
"""
from __future__ import annotations

import numpy as np

from drake_skills.promp.basis import GaussianBasis

_LOG_2PI = np.log(2.0 * np.pi)
#: Samples of the observed beginning the pruning bound looks at in its second pass (evenly
#: spaced, the last included; the first pass looks at 3).
N_PROBES = 8
#: Phases at which the basis fit residual of the observed samples is evaluated for the bound.
N_RESIDUAL_PHASES = 8
#: Relative cut-off of the pseudo-inverse of the basis Gram matrix (as in
#: :func:`~drake_skills.promp.interaction.prefix_statistics`).
PINV_RCOND = 1e-10
#: Safety factor on that residual (it is evaluated at a grid of phases, not at every component's).
RESIDUAL_MARGIN = 2.0


def phase_samples(phases: np.ndarray, m: int) -> np.ndarray:
    """``np.linspace(0, f, m)`` for every ``f`` of ``phases`` (n,), shape (n, m), bit for bit."""
    f = np.asarray(phases, float)
    step = f / (m - 1)
    z = np.arange(m, dtype=float)[None, :] * step[:, None]
    z[:, -1] = f
    return z


def basis_rows(basis: GaussianBasis, z: np.ndarray) -> np.ndarray:
    """:meth:`GaussianBasis.phi` at every phase of ``z`` (...,), shape (..., N), the same arithmetic."""
    Phi = np.exp(-0.5 * ((z[..., None] - basis.centers) / basis.sigma) ** 2)
    if basis.normalized:
        Phi /= Phi.sum(axis=-1, keepdims=True)
    return Phi


def _basis_columns(basis: GaussianBasis, z: np.ndarray) -> np.ndarray:
    """:func:`basis_rows` with the basis axis first, shape (N, ...), and one exponential per phase (for the bound).

    With centres ``c_j = j / (N - 1)`` and width ``s = w / (N - 1)``, the normalized
    basis is ``a_j rho^j / sum_i a_i rho^i`` with ``rho = exp(z (N - 1) / w^2)`` and
    ``a_j = exp(-j^2 / (2 w^2))`` (the factor ``exp(-z^2 / 2 s^2)`` cancels); equal to
    the direct form to rounding, used where it cannot overflow.
    """
    N, w = basis.n_basis, basis.width
    if not basis.normalized or (N - 1) ** 2 / w ** 2 > 600.0:
        return np.ascontiguousarray(np.moveaxis(basis_rows(basis, z), -1, 0))
    rho = np.exp(z * ((N - 1) / w ** 2))
    a = np.exp(-0.5 * np.arange(N) ** 2 / w ** 2)
    G = np.empty((N,) + z.shape)
    G[0] = 1.0
    for j in range(1, N):
        np.multiply(G[j - 1], rho, out=G[j])            # rho^j
    G *= a.reshape((N,) + (1,) * z.ndim)
    G /= G.sum(axis=0)
    return G


def _forward(R: np.ndarray, V: np.ndarray) -> np.ndarray:
    """``R^{-1} V`` for lower-triangular ``R`` (n, h, h) and ``V`` (n, h) or (n, h, r), by substitution over rows."""
    X = np.zeros(V.shape)
    h = R.shape[1]
    for i in range(h):
        acc = V[:, i] - (np.einsum("nj,nj...->n...", R[:, i, :i], X[:, :i]) if i else 0.0)
        X[:, i] = acc / (R[:, i, i] if V.ndim == 2 else R[:, i, i, None])
    return X


class PrefixPairs:
    """The observation terms of ``n`` (component, phase) pairs for the samples ``ys``.

    Parameters
    ----------
    means_h : array, shape (n, h)
        Human (gating) means, dimension-major.
    inflate : array, shape (n,)
        ``c = 1 + 1/s`` of each pair's component.
    phases : array, shape (n,)
        Fraction of the component's motion the samples cover, in (0, 1].
    ys : array, shape (m, D)
        The observed samples, evenly spaced in phase over ``[0, phase]``.
    chol : array, shape (h, h)
        Lower Cholesky factor ``L`` of the shared gating covariance ``Sigma``.
    basis : GaussianBasis
    noise_var : float
        sigma^2, the observation noise.
    """

    def __init__(self, means_h, inflate, phases, ys, chol, basis: GaussianBasis, noise_var: float):
        n, h = means_h.shape
        m, D = ys.shape
        N = basis.n_basis
        self.h, self.m, self.D, self.noise = h, m, D, float(noise_var)
        self.inflate = np.asarray(inflate, float)
        Phi = basis_rows(basis, phase_samples(phases, m))          # (n, m, N)
        PhiT = Phi.transpose(0, 2, 1)
        self.P = PhiT @ Phi                                       # (n, N, N)
        r = ys[None] - Phi @ means_h.reshape(n, D, N).transpose(0, 2, 1)  # (n, m, D)
        self.U = PhiT @ r                                         # (n, N, D): H r per dimension
        u = self.U.transpose(0, 2, 1).reshape(n, h)
        self.r2 = np.einsum("nmd,nmd->n", r, r)
        # L^T G L = sum_d L_d^T P L_d, L_d the rows of L of dimension d (two large products per d)
        LtGL = np.zeros((n, h, h))
        for d in range(D):
            Ld = chol[d * N:(d + 1) * N]                          # (N, h)
            Y = (self.P.reshape(n * N, N) @ Ld).reshape(n, N, h)
            LtGL += (Ld.T @ Y.transpose(1, 0, 2).reshape(N, n * h)).reshape(h, n, h).transpose(1, 0, 2)
        B = self.inflate[:, None, None] * LtGL
        B[:, np.arange(h), np.arange(h)] += self.noise
        self.R = np.linalg.cholesky(B)
        x = _forward(self.R, u @ chol)                            # R^{-1} L^T u
        self.explained = self.inflate * np.einsum("ni,ni->n", x, x)
        logdet = 2.0 * np.sum(np.log(np.diagonal(self.R, axis1=1, axis2=2)), axis=1) - h * np.log(self.noise)
        d2_obs = (self.r2 - self.explained) / self.noise
        #: log-likelihood of the samples under each pair, shape (n,)
        self.loglik = -0.5 * (m * D * (_LOG_2PI + np.log(self.noise)) + logdet + d2_obs)

    def fit(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``d2`` and ``dof`` (as :func:`~drake_skills.promp.interaction.prefix_statistics`) of the pairs ``idx``."""
        idx = np.asarray(idx, dtype=int)
        U = self.U[idx]
        Pinv = np.linalg.pinv(self.P[idx], rcond=PINV_RCOND, hermitian=True)
        span = np.einsum("nid,nij,njd->n", U, Pinv, U)
        d2 = np.maximum((span - self.explained[idx]) / self.noise, 0.0)
        R = self.R[idx]
        Rinv = _forward(R, np.broadcast_to(np.eye(self.h), R.shape))
        dof = np.maximum(self.h - self.noise * np.einsum("nij,nij->n", Rinv, Rinv), 1e-9)
        return d2, dof


def residual_bound(ys: np.ndarray, phases: np.ndarray, basis: GaussianBasis, noise_var: float) -> float:
    """The fit residual ``E`` the bound of :func:`prefix_candidates` allows for (see its Notes)."""
    lo, hi = float(phases.min()), float(phases.max())
    grid = np.unique(np.r_[np.geomspace(lo, hi, N_RESIDUAL_PHASES), lo, hi]) if hi > lo else np.array([lo])
    return RESIDUAL_MARGIN * float(fit_residual(ys, grid, basis).max()) + noise_var


def fit_lower_bounds(means_h, inflate, phases, ys, sigma_max: float, basis: GaussianBasis, noise_var: float, *,
                     n_probes: int = N_PROBES, residual: float | None = None) -> np.ndarray:
    """Lower bounds of the fit statistic ``d2`` of every component at every phase, shape (F, K).

    The arguments are those of :func:`prefix_candidates`; ``n_probes`` samples are
    looked at, ``residual`` is :func:`residual_bound` (computed if not given).
    """
    F, K = phases.shape
    m, D = ys.shape
    N = basis.n_basis
    E = residual_bound(ys, phases, basis, noise_var) if residual is None else residual
    probes = np.unique(np.linspace(0, m - 1, min(n_probes, m)).round().astype(int))
    # the phases of the probe samples, as phase_samples(f, m)[:, probes] gives them, probes first: (q, F, K)
    z = probes.astype(float)[:, None, None] * (phases / (m - 1))[None]
    z[probes == m - 1] = phases
    G = _basis_columns(basis, z)                                     # (N, q, F, K)
    M = means_h.reshape(K, D, N)
    rr = np.zeros((F, K))
    for d in range(D):
        r = ys[probes, d][:, None, None] - np.einsum("nqfk,kn->qfk", G, M[:, d])
        rr += np.einsum("qfk,qfk->fk", r, r)
    # lambda_max(Phi_I Phi_I^T) <= (largest column sum) x (largest row sum) of Phi_I (entries >= 0)
    lam = G.sum(axis=1).max(axis=0) * G.sum(axis=0).max(axis=0)      # (F, K)
    # what the directions the pseudo-inverse drops (eigenvalues below PINV_RCOND of the
    # largest, at most m or m N) can add to the residual through the component's mean
    eps = N * PINV_RCOND * m * (1.0 if basis.normalized else N)
    norm_m = np.sqrt(np.einsum("ki,ki->k", means_h, means_h))
    dropped = 2.0 * np.sqrt(eps) * norm_m * float(np.sqrt(np.sum(ys * ys))) + eps * norm_m ** 2
    return rr / (noise_var + inflate * sigma_max * lam) - (E + dropped) / noise_var


def fit_residual(ys: np.ndarray, phases: np.ndarray, basis: GaussianBasis) -> np.ndarray:
    """Squared distance of the samples ``ys`` (m, D) from the span of the basis at each phase, shape (len(phases),).

    The part of the samples no weights can explain; the fit statistic ``d2`` leaves it out.
    """
    m = ys.shape[0]
    Phi = basis_rows(basis, phase_samples(phases, m))               # (g, m, N)
    PhiT = Phi.transpose(0, 2, 1)
    b = PhiT @ ys                                                   # (g, N, D)
    Pinv = np.linalg.pinv(PhiT @ Phi, rcond=PINV_RCOND, hermitian=True)
    return np.maximum(float(np.sum(ys * ys)) - np.einsum("gid,gij,gjd->g", b, Pinv, b), 0.0)


def prefix_candidates(means_h, inflate, phases, ys, sigma_max: float, basis: GaussianBasis, noise_var: float,
                      threshold: float) -> np.ndarray:
    """Which components may explain the observed beginning ``ys``: a mask, shape (K,).

    Parameters
    ----------
    means_h : array, shape (K, h)
    inflate : array, shape (K,)
        ``1 + 1/s_k``.
    phases : array, shape (F, K)
        The phases at which each component will be scored (one row per factor of the grid).
    ys : array, shape (m, D)
    sigma_max : float
        Largest eigenvalue of the shared gating covariance.
    basis : GaussianBasis
    noise_var : float
    threshold : float
        The largest fit statistic ``d2`` any component may have and still explain the
        samples (the novelty quantile at ``h`` degrees of freedom: a prefix observes
        fewer, so its own threshold is lower).

    Returns
    -------
    mask : array of bool, shape (K,)
        False where, at every phase, the lower bound of ``d2`` exceeds ``threshold``.

    Notes
    -----
    For one (component, phase) pair, with ``r`` the residual of the samples from the
    component's mean trajectory and ``C = sigma^2 I + c H^T Sigma H`` their predictive
    covariance, ``d2 = r^T C^{-1} r - E / sigma^2``, where ``E`` is the squared distance
    of the samples from the span of the basis (:func:`fit_residual`). The Mahalanobis
    distance of a subset of the samples never exceeds that of all of them, and
    ``C_II <= (sigma^2 + c lambda_max(Sigma) lambda_max(Phi_I Phi_I^T)) I`` on the probe
    samples ``I``, so

        d2 >= |r_I|^2 / (sigma^2 + c lambda_max(Sigma) lambda_I) - E / sigma^2,

    with ``lambda_I = |Phi_I|_1 |Phi_I|_inf`` (largest column sum times largest row sum,
    1 for a normalized basis; the entries are positive, and the largest singular value
    squared is at most that product).
    Everything but ``E`` is exact at each component's own phase. ``E`` (with the
    pseudo-inverse's cut-off, as ``d2`` computes it) is a function of the phase plus a
    term, through the directions the cut-off drops, that is bounded by the norm of
    the component's mean; the function of the phase is taken as
    :data:`RESIDUAL_MARGIN` times its largest value over :data:`N_RESIDUAL_PHASES`
    phases spanning those of the components, plus ``sigma^2``. That is the one step
    that is not a proof; the test suite checks the bound against the exact ``d2`` of
    every (component, phase) pair and the answers against scoring every component.
    A first pass with 3 probe samples rules out most components, a second with
    :data:`N_PROBES` the rest.
    """
    keep = np.ones(phases.shape[1], bool)
    E = residual_bound(ys, phases, basis, noise_var)
    for q in (3, N_PROBES):  # a coarse pass over all components, a finer one over those left
        idx = np.flatnonzero(keep)
        bound = fit_lower_bounds(means_h[idx], inflate[idx], phases[:, idx], ys, sigma_max, basis, noise_var,
                                 n_probes=q, residual=E)
        keep[idx] = (bound <= threshold).any(axis=0)
    return keep
