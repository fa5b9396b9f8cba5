"""A cheap lower bound on the prefix fit statistic, to prune a large library before scoring it.

:func:`~drake_skills.library.prefix.score_prefix` scores the observed beginning of a
motion against every component at every phase of its band: for a library of a
thousand components that is most of the cost of recognizing a prefix, and almost
all of those components cannot explain the samples at all. :func:`prefix_candidates`
rules them out with a lower bound on the fit statistic ``d2`` that looks at a few
samples only (see its Notes); only the others are scored. The recognition is the
same as scoring every component (``tests/library/test_scale.py`` checks both the
bound against the exact ``d2`` and the answers against scoring all components).
"""
from __future__ import annotations

import numpy as np

from drake_skills.promp.basis import GaussianBasis

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
