"""Recognition from the beginning of a motion: which skill, and how much of it has been seen.

A prefix of a motion covers an unknown fraction ``f`` of the whole path. For every
component ``k`` and a grid of phases ``f``, the observed samples (evenly spaced along
the observed path, in normalized units) are scored under the component's prefix of
length ``f``, ``vec(y) ~ N(H_f^T mu_k, sigma^2 I + H_f^T Sigma_k H_f)`` (the ``H_t`` of
Eq. 13 over the phases ``[0, f]``), with the gating's predictive covariance
``Sigma_k = c_k Sigma``, ``c_k = 1 + 1/s_k`` (:mod:`drake_skills.library.scale`).

Because every component shares ``Sigma`` up to the scalar ``c_k``, one eigendecomposition
per phase serves all components: with ``Sigma = L L^T`` and ``L^T G L = Q Lambda Q^T``
(``G = H H^T``) and ``v_k = Q^T L^T u_k`` (``u_k = H r_k``),

    u^T S A^{-1} u       = c v^T (sigma^2 I + c Lambda)^{-1} v
    log det(I + S G / s2) = sum_i log(1 + c lambda_i / sigma^2)
    tr(A^{-1})            = sum_i 1 / (sigma^2 + c lambda_i)

so a recognition costs one ``h x h`` eigendecomposition per phase of the grid plus
O(K h) per phase, not O(K h^3). The statistics are those of
:func:`drake_skills.promp.interaction.prefix_statistics` (the marginal log-likelihood,
the chi-square statistic of the part of the misfit the basis spans, and its degrees of
freedom ``D rank(Phi)``, exact under the model), which the tests check this against.

The phase of component ``k`` is the grid phase of highest likelihood within a band
around ``path length observed / component's mean path length`` (the path-length
estimate; the band, :data:`PHASE_BAND`, allows for paths 1.5 times shorter or longer
than the mean); its evidence for the posterior over components is the likelihood
averaged over the phases of its band (the phase is marginalized, not maximized).
"""
from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from drake_skills.library.bounded import put_bounded
from drake_skills.promp.basis import GaussianBasis
from drake_skills.promp.gaussian import logsumexp

_LOG_2PI = np.log(2.0 * np.pi)
#: Phases tried: 1/20 ... 1 in steps of 1/20.
PHASE_GRID = tuple(np.round(np.arange(1, 21) / 20.0, 6))
#: A component's phase is searched within [guess / PHASE_BAND, guess * PHASE_BAND].
PHASE_BAND = 1.5


@lru_cache(maxsize=2048)
def _basis_at(basis: GaussianBasis, f: float, m: int):
    """Phi over ``m`` evenly spaced phases of ``[0, f]`` (m, N), its Gram matrix and pseudo-inverse (cached)."""
    Phi = basis.phi(np.linspace(0.0, f, m))
    PtP = Phi.T @ Phi
    Pinv = np.linalg.pinv(PtP, rcond=1e-10, hermitian=True)
    return Phi, PtP, Pinv


@lru_cache(maxsize=256)
def _basis_terms(basis: GaussianBasis, phases: tuple, m: int):
    """:func:`_basis_at` for each phase, stacked: arrays of shapes (J, m, N), (J, N, N), (J, N, N) (cached, read-only)."""
    parts = [_basis_at(basis, f, m) for f in phases]
    out = tuple(np.stack([p[i] for p in parts]) for i in range(3))
    for a in out:
        a.setflags(write=False)
    return out


#: Stacked eigendecompositions kept per cache for whole phase sets (the sets a controller
#: meets recur: the same few bands and prefix sizes), besides the one entry per phase.
_STACKED_ENTRIES = 64


def _whitened_gram(PtP: np.ndarray, chol: np.ndarray, D: int):
    """Eigendecompositions of ``L^T (I_D (x) PtP_j) L`` for every phase j: (J, h) eigenvalues, (J, h, h) vectors."""
    N = PtP.shape[1]
    Ld = chol.reshape(D, N, -1)                          # rows of L per dimension: (D, N, h)
    Gt = np.einsum("dnh,jnk,dkg->jhg", Ld, PtP, Ld)
    lam, Q = np.linalg.eigh(0.5 * (Gt + Gt.transpose(0, 2, 1)))
    return np.clip(lam, 0.0, None), Q


@dataclass(frozen=True)
class PrefixScores:
    """Per component: the log-likelihood, chi-square statistic, its degrees of freedom and the phase chosen."""

    log_likelihoods: np.ndarray
    mahalanobis_sq: np.ndarray
    dof: np.ndarray
    phases: np.ndarray


def score_phases(y: np.ndarray, phases, means_h: np.ndarray, inflate: np.ndarray, chol: np.ndarray,
                 basis: GaussianBasis, noise_var: float, cache: dict | None = None):
    """Prefix statistics of samples ``y`` (m, D) for every phase of ``phases`` and every component at once.

    Parameters
    ----------
    y : array, shape (m, D)
        Samples evenly spaced along the observed path (normalized units).
    phases : sequence of float, length J
        Phases the last sample may be at, each in (0, 1].
    means_h : array, shape (K, D N)
        Components' human (gating) means, stacked per dimension.
    inflate : array, shape (K,)
        ``c_k`` of the predictive covariance ``c_k Sigma``.
    chol : array, shape (h, h)
        Lower Cholesky factor of the shared gating covariance ``Sigma``.
    basis : GaussianBasis
    noise_var : float
        sigma^2, the variance of an observed sample.
    cache : dict, optional
        Keeps the eigendecompositions for this ``chol`` between calls (the caller
        empties it when ``Sigma`` changes).

    Returns
    -------
    loglik, d2, dof : arrays, shape (J, K)
    """
    m, D = y.shape
    phases = tuple(float(f) for f in phases)
    Phi, PtP, Pinv = _basis_terms(basis, phases, int(m))
    if cache is None:
        lam, Q = _whitened_gram(PtP, chol, D)
    else:
        stacked = cache.setdefault("stacked", OrderedDict())
        hit = stacked.get((phases, int(m)))
        if hit is None:  # one entry per (phase, m): the phase sets asked for vary, the phases themselves recur
            missing = [j for j, f in enumerate(phases) if (f, int(m)) not in cache]
            if missing:
                lam_m, Q_m = _whitened_gram(PtP[missing], chol, D)
                for i, j in enumerate(missing):
                    cache[(phases[j], int(m))] = (lam_m[i], Q_m[i])
            hit = (np.stack([cache[(f, int(m))][0] for f in phases]), np.stack([cache[(f, int(m))][1] for f in phases]))
            put_bounded(stacked, (phases, int(m)), hit, _STACKED_ENTRIES)
        lam, Q = hit
    J, _, N = Phi.shape
    K = means_h.shape[0]
    Mt = means_h.reshape(K, D, N).transpose(0, 2, 1)       # (K, N, D)
    r = y[None, None] - np.matmul(Phi[:, None], Mt[None])   # (J, K, m, D) residuals of the prior means
    rr = np.sum(r * r, axis=(2, 3))
    U = np.matmul(Phi.transpose(0, 2, 1)[:, None], r).transpose(0, 1, 3, 2)   # (J, K, D, N): u = H r
    span = np.sum(np.matmul(U, Pinv[:, None]) * U, axis=(2, 3))              # u^T G^+ u
    v = np.matmul(U.reshape(J, K, D * N) @ chol, Q)                         # (J, K, h): Q^T L^T u
    c = np.asarray(inflate, float)[None, :, None]            # (1, K, 1)
    denom = noise_var + c * lam[:, None, :]                  # (J, K, h)
    explained = c[..., 0] * np.sum(v * v / denom, axis=2)
    d2_obs = (rr - explained) / noise_var
    logdet = np.sum(np.log1p(c * lam[:, None, :] / noise_var), axis=2)
    loglik = -0.5 * (m * D * (_LOG_2PI + np.log(noise_var)) + logdet + d2_obs)
    d2 = np.maximum((span - explained) / noise_var, 0.0)
    rank = D * np.rint(np.einsum("jnk,jkn->j", PtP, Pinv))  # tr(G G^+): directions spanned, per phase
    dof = np.broadcast_to(np.maximum(rank, 1e-9)[:, None], (J, K)).copy()
    return loglik, d2, dof


def score_at_phase(y, f: float, means_h, inflate, chol, basis: GaussianBasis, noise_var: float,
                   cache: dict | None = None):
    """:func:`score_phases` at one phase ``f``: arrays of shape (K,)."""
    ll, d2, dof = score_phases(y, (f,), means_h, inflate, chol, basis, noise_var, cache)
    return ll[0], d2[0], dof[0]


def score_prefix(y: np.ndarray, guess: np.ndarray, means_h: np.ndarray, inflate: np.ndarray, chol: np.ndarray,
                 basis: GaussianBasis, noise_var: float, cache: dict | None = None,
                 band: np.ndarray | None = None) -> PrefixScores:
    """Each component scored at its most likely phase of :data:`PHASE_GRID` near its path-length guess.

    Parameters
    ----------
    y : array, shape (m, D)
    guess : array, shape (K,)
        Observed path length over each component's mean path length.
    band : array of bool, shape (K, len(PHASE_GRID)), optional
        :func:`phase_band` of ``guess`` (computed if not given).
    (the rest as :func:`score_phases`)
    """
    K = means_h.shape[0]
    grid = np.array(PHASE_GRID)
    wanted = phase_band(guess) if band is None else band
    cols = np.flatnonzero(wanted.any(axis=0))
    ll, d2, dof = score_phases(y, tuple(grid[cols]), means_h, inflate, chol, basis, noise_var, cache)
    mask = wanted[:, cols].T                                  # (J', K)
    masked = np.where(mask, ll, -np.inf)
    best = masked.argmax(axis=0)
    k = np.arange(K)
    # the phase is not known: a component's evidence is its likelihood averaged over the phases it
    # allows (uniform), not the best of them, which would favour the components that allow many
    marginal = logsumexp(masked, axis=0) - np.log(mask.sum(axis=0))
    return PrefixScores(marginal, d2[best, k], dof[best, k], grid[cols][best])


def phase_band(guess) -> np.ndarray:
    """Which phases of :data:`PHASE_GRID` each component's band allows: a mask, shape (K, len(PHASE_GRID))."""
    grid = np.array(PHASE_GRID)
    g = np.clip(np.asarray(guess, float), grid[0], 1.0)
    lo, hi = g / PHASE_BAND, np.minimum(g * PHASE_BAND, 1.0)
    wanted = (grid[None, :] >= lo[:, None] - 1e-12) & (grid[None, :] <= hi[:, None] + 1e-12)
    wanted[np.arange(g.size), np.abs(grid[None, :] - g[:, None]).argmin(axis=1)] = True
    return wanted

