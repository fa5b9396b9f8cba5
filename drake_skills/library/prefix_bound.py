"""A cheap lower bound on the prefix fit statistic, to prune a large library before scoring it.

:func:`~drake_skills.library.prefix.score_prefix` scores the observed beginning of a
motion against every component at every phase of its band: for a library of a
thousand components that is most of the cost of recognizing a prefix, and almost
all of those components cannot explain the samples at all. :func:`prefix_candidates`
rules them out with a lower bound on the fit statistic ``d2`` that looks at a few
samples only (see :func:`fit_lower_bounds`); only the others are scored. The recognition is the
same as scoring every component (``tests/library/test_scale.py`` checks both the
bound against the exact ``d2`` and the answers against scoring all components).
"""
from __future__ import annotations

import numpy as np

from drake_skills.library.prefix import _basis_terms
from drake_skills.promp.basis import GaussianBasis

#: Samples of the observed beginning the pruning bound looks at (evenly spaced, the last included).
N_PROBES = 8
#: Relative cut-off of the pseudo-inverse of the basis Gram matrix (as in
#: :func:`~drake_skills.promp.interaction.prefix_statistics`).
PINV_RCOND = 1e-10


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


def fit_residual(ys: np.ndarray, phases: np.ndarray, basis: GaussianBasis) -> np.ndarray:
    """Squared distance of the samples ``ys`` (m, D) from the span of the basis at each phase, shape (len(phases),).

    The part of the samples no weights can explain; the fit statistic ``d2`` leaves it
    out. Computed with the same (cached) basis terms as
    :func:`~drake_skills.library.prefix.score_phases`.
    """
    m = ys.shape[0]
    Phi, _, Pinv = _basis_terms(basis, tuple(float(f) for f in phases), int(m))
    b = Phi.transpose(0, 2, 1) @ ys                                 # (g, N, D)
    return np.maximum(float(np.sum(ys * ys)) - np.einsum("gid,gij,gjd->g", b, Pinv, b), 0.0)


def fit_lower_bounds(means_h, inflate, phases, ys, sigma_max: float, basis: GaussianBasis, noise_var: float, *,
                     n_probes: int = N_PROBES, residual: np.ndarray | None = None,
                     unshrink: np.ndarray | None = None) -> np.ndarray:
    """Lower bounds of the fit statistic ``d2`` of every component at every phase of ``phases``, shape (K, J).

    Parameters
    ----------
    means_h : array, shape (K, h)
        Components' human (gating) means, dimension-major.
    inflate : array, shape (K,)
        ``1 + 1/s_k``.
    phases : array, shape (J,)
        Phases of the last sample, in (0, 1] (the grid prefix recognition searches).
    ys : array, shape (m, D)
        The observed samples, evenly spaced over ``[0, phase]``.
    sigma_max : float
        Largest eigenvalue of the shared gating covariance.
    basis : GaussianBasis
    noise_var : float
        sigma^2, the observation noise.
    n_probes : int
        Samples looked at.
    residual : array, shape (J,), optional
        :func:`fit_residual` at ``phases`` (computed if not given).
    unshrink : array, shape (N, N), optional
        ``S^-1`` of the recognition's model (each dimension's weights mapped to the ones
        the samples see: ``mu' = S^-1 mu``, ``Sigma' = S^-1 Sigma S^-T`` per dimension),
        with ``means_h`` and ``sigma_max`` those of ``mu`` and ``Sigma``. The bound then
        uses the basis ``Phi S^-1`` at the probes, whose norm is far below
        ``|Phi| |S^-1|`` (the directions ``S^-1`` stretches are those the basis barely
        sees), with absolute values in the row and column sums.

    Notes
    -----
    For one (component, phase) pair, with ``r`` the residual of the samples from the
    component's mean trajectory and ``C = sigma^2 I + c H^T Sigma H`` their predictive
    covariance, ``d2 = r^T C^{-1} r - E / sigma^2``, where ``E`` is the squared distance
    of the samples from the span of the basis (:func:`fit_residual`, exact at each
    phase). The Mahalanobis distance of a subset ``I`` of the samples never exceeds that
    of all of them, and ``C_II <= (sigma^2 + c lambda_max(Sigma) lambda_I) I`` with
    ``lambda_I = |Phi_I|_1 |Phi_I|_inf`` (largest column sum times largest row sum, an
    upper bound of the largest eigenvalue of ``Phi_I Phi_I^T`` for positive entries), so

        d2 >= |r_I|^2 / (sigma^2 + c lambda_max(Sigma) lambda_I) - E / sigma^2.

    ``E`` is computed as ``d2`` computes it, with the pseudo-inverse's cut-off; the
    directions the cut-off drops can add a term bounded by the norm of the
    component's mean, which is subtracted too.
    """
    phases = np.asarray(phases, float)
    K = means_h.shape[0]
    m, D = ys.shape
    N = basis.n_basis
    E = fit_residual(ys, phases, basis) if residual is None else np.asarray(residual, float)   # (J,)
    probes = np.unique(np.linspace(0, m - 1, min(n_probes, m)).round().astype(int))
    # the phases of the probe samples, as np.linspace(0, f, m)[probes] gives them: (q, J)
    z = probes.astype(float)[:, None] * (phases / (m - 1))[None]
    z[probes == m - 1] = phases
    G = _basis_columns(basis, z)                                     # (N, q, J)
    if unshrink is not None:
        G = np.einsum("in,iqj->nqj", np.asarray(unshrink, float), G)   # rows of Phi S^-1
    q, J = z.shape
    # the mean trajectories at the probes minus the samples, (K, D q J), one product and one 2-d difference
    r = (means_h.reshape(K * D, N) @ G.reshape(N, q * J)).reshape(K, D * q * J)
    r -= np.broadcast_to(ys[probes].T[:, :, None], (D, q, J)).reshape(-1)
    r = r.reshape(K, D * q, J)
    rr = np.einsum("kij,kij->kj", r, r)                              # (K, J)
    A = np.abs(G) if unshrink is not None else G
    lam = A.sum(axis=1).max(axis=0) * A.sum(axis=0).max(axis=0)      # (J,)
    # what the directions the pseudo-inverse drops (eigenvalues below PINV_RCOND of the
    # largest, at most m or m N) can add to the residual through the component's mean
    eps = N * PINV_RCOND * m * (1.0 if basis.normalized else N)
    mh = means_h if unshrink is None else (means_h.reshape(K, D, N) @ np.asarray(unshrink, float).T).reshape(K, -1)
    norm_m = np.sqrt(np.einsum("ki,ki->k", mh, mh))   # of the means the samples see
    dropped = 2.0 * np.sqrt(eps) * norm_m * float(np.sqrt(np.sum(ys * ys))) + eps * norm_m ** 2
    return rr / (noise_var + np.outer(inflate, sigma_max * lam)) - (E[None, :] + dropped[:, None]) / noise_var


def prefix_candidates(means_h, inflate, phases, allowed, ys, sigma_max: float, basis: GaussianBasis,
                      noise_var: float, threshold: float, unshrink: np.ndarray | None = None) -> np.ndarray:
    """Which components may explain the observed beginning ``ys``: a mask, shape (K,).

    ``allowed`` (K, J) says at which of ``phases`` each component will be scored;
    ``threshold`` is the largest fit statistic ``d2`` a component may have and still
    explain the samples (the novelty quantile at ``h`` degrees of freedom: a prefix
    observes fewer, so its own threshold is lower). A component is ruled out where the
    lower bound of :func:`fit_lower_bounds` exceeds ``threshold`` at every phase it allows,
    first looking at 3 samples, then at :data:`N_PROBES` for the components left.
    """
    allowed = np.asarray(allowed, bool)
    phases = np.asarray(phases, float)
    keep = allowed.any(axis=1)
    E = np.zeros(phases.size)
    used = np.flatnonzero(allowed.any(axis=0))
    E[used] = fit_residual(ys, phases[used], basis)
    for q in (3, N_PROBES):  # a coarse pass over all components, a finer one over those left
        idx = np.flatnonzero(keep)
        if not idx.size:
            break
        cols = np.flatnonzero(allowed[idx].any(axis=0))
        bound = fit_lower_bounds(means_h[idx], inflate[idx], phases[cols], ys, sigma_max, basis, noise_var,
                                 n_probes=q, residual=E[cols], unshrink=unshrink)
        keep[idx] = ((bound <= threshold) & allowed[np.ix_(idx, cols)]).any(axis=1)
    return keep
