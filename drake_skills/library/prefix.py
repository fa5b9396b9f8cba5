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
O(K h) per phase, not O(K h^3). The fit statistic is the chi-square statistic of the
least-squares weights the samples give in the directions they see well (eigenvalues of
``Phi^T Phi`` at least :data:`~drake_skills.promp.interaction.SEEN_RCOND` of the largest, ``n`` per
dimension; read at each call, so a changed share needs new libraries' caches): with
those directions ``V``, their eigenvalues ``g`` and ``B = V_g^T Sigma V_g``
(``V_g = I_D (x) V g^{1/2}``) ``= R Gamma R^T``, the coordinates
``v_k = R^T (I_D (x) g^{-1/2} V^T H y - V_g^T mu_k)`` have variances ``sigma^2 + c gamma_i``,
again one eigendecomposition per phase for all components. The statistics are those of
:func:`drake_skills.promp.interaction.prefix_statistics` (the marginal log-likelihood,
``d2`` and its ``D n`` degrees of freedom, exact under the model), which the tests
check this against.

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
from drake_skills.promp import interaction

_LOG_2PI = np.log(2.0 * np.pi)
#: Phases tried: 1/20 ... 1 in steps of 1/20.
PHASE_GRID = tuple(np.round(np.arange(1, 21) / 20.0, 6))
#: A component's phase is searched within [guess / PHASE_BAND, guess * PHASE_BAND].
PHASE_BAND = 1.5


@lru_cache(maxsize=2048)
def _basis_at(basis: GaussianBasis, f: float, m: int):
    """Phi over ``m`` evenly spaced phases of ``[0, f]`` (m, N) and its Gram matrix (cached, read-only; prefix
    scoring, and Eq. (13) on a prefix in ``RecognitionMixin._condition``)."""
    Phi = basis.phi(np.linspace(0.0, f, m))
    G = Phi.T @ Phi
    for a in (Phi, G):
        a.setflags(write=False)
    return Phi, G


@lru_cache(maxsize=256)
def _basis_terms(basis: GaussianBasis, phases: tuple, m: int):
    """:func:`_basis_at` for each phase, stacked: arrays of shapes (J, m, N), (J, N, N) (cached, read-only)."""
    parts = [_basis_at(basis, f, m) for f in phases]
    out = tuple(np.stack([p[i] for p in parts]) for i in range(2))
    for a in out:
        a.setflags(write=False)
    return out


#: Stacked eigendecompositions kept per cache for whole phase sets (the sets a controller
#: meets recur: the same few bands and prefix sizes), besides the one entry per phase.
_STACKED_ENTRIES = 64
#: Entries kept per cache for single phases (the 20 grid phases at a dozen prefix sizes fit).
_PHASE_ENTRIES = 512


def _gram(PtP: np.ndarray, chol: np.ndarray, D: int) -> np.ndarray:
    """``L^T (I_D (x) PtP_j) L`` for every phase j, symmetrized: (J, h, h)."""
    N = PtP.shape[1]
    Ld = chol.reshape(D, N, -1)                          # rows of L per dimension: (D, N, h)
    Gt = sum(np.matmul(Ld[d].T, np.matmul(PtP, Ld[d])) for d in range(D))   # sum_d L_d^T PtP_j L_d
    return 0.5 * (Gt + Gt.transpose(0, 2, 1))


def _whitened_gram(PtP: np.ndarray, chol: np.ndarray, D: int):
    """Eigendecompositions of ``L^T (I_D (x) PtP_j) L`` for every phase j: (J, h) eigenvalues, (J, h, h) vectors."""
    lam, Q = np.linalg.eigh(_gram(PtP, chol, D))
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
    phases = tuple(float(f) for f in phases)
    loglik = prefix_loglik(y, phases, means_h, inflate, chol, basis, noise_var, cache)
    d2, dof = fit_statistic(y, phases, means_h, inflate, chol, basis, noise_var, cache)
    return loglik, d2, dof


def prefix_loglik(y: np.ndarray, phases, means_h: np.ndarray, inflate: np.ndarray, chol: np.ndarray,
                  basis: GaussianBasis, noise_var: float, cache: dict | None = None) -> np.ndarray:
    """The log-likelihoods (J, K) of :func:`score_phases` alone (its parameters), without the fit statistic."""
    m, D = y.shape
    phases = tuple(float(f) for f in phases)
    Phi = _basis_terms(basis, phases, int(m))[0]
    lam, Q = _per_phase(cache, "gram", phases, int(m), lambda fs: _whitened_gram(_basis_terms(basis, fs, int(m))[1],
                                                                                  chol, D))
    J, _, N = Phi.shape
    K = means_h.shape[0]
    # every phase's prior means in one product, (J m, N) x (N, K D): the residuals laid out (J, m, K D), the
    # samples tiled once per component (a broadcast over a short last axis costs several times more)
    Mt = means_h.reshape(K, D, N).transpose(2, 0, 1).reshape(N, K * D)
    r = np.tile(y, K)[None] - (Phi.reshape(J * m, N) @ Mt).reshape(J, m, K * D)
    rr = np.einsum("jmc,jmc->jc", r, r).reshape(J, K, D).sum(axis=2)
    U = np.matmul(Phi.transpose(0, 2, 1), r).reshape(J, N, K, D).transpose(0, 2, 3, 1)   # (J, K, D, N): u = H r
    v = np.matmul(U.reshape(J, K, D * N) @ chol, Q)                         # (J, K, h): Q^T L^T u
    c = np.asarray(inflate, float)[None, :, None]            # (1, K, 1)
    cl = c * lam[:, None, :]
    explained = c[..., 0] * np.sum(v * v / (noise_var + cl), axis=2)
    d2_obs = (rr - explained) / noise_var
    logdet = np.sum(np.log1p(cl / noise_var), axis=2)
    return -0.5 * (m * D * (_LOG_2PI + np.log(noise_var)) + logdet + d2_obs)


def loglik_one(y: np.ndarray, phases: tuple, mean_h: np.ndarray, chol: np.ndarray, basis: GaussianBasis,
               noise_var: float, cache: dict | None = None) -> np.ndarray:
    """:func:`prefix_loglik` of one Gaussian (``mean_h`` (h,), covariance ``chol chol^T``, no inflation), shape (J,).

    One model needs no eigendecomposition (what lets :func:`prefix_loglik` scale the covariance per component):
    with ``B_j = L^T (I_D (x) PtP_j) L`` and the Cholesky factor ``K_j`` of ``sigma^2 I + B_j``, the samples' misfit
    is ``(|r|^2 - |K_j^-1 L^T H r|^2) / sigma^2`` and the log-determinant ``2 sum log diag K_j - h log sigma^2``
    (Woodbury). ``cache`` keeps ``K_j^-1`` and the log-determinant per phase for this ``chol`` and ``noise_var``
    (a fifth of the cost of the eigendecompositions when a library has just learned).
    """
    m, D = y.shape
    Phi = _basis_terms(basis, phases, int(m))[0]                             # (J, m, N)
    W, logdet = _per_phase(cache, "woodbury", phases, int(m),
                           lambda fs: _woodbury_terms(_basis_terms(basis, fs, int(m))[1], chol, D, noise_var))
    J, _, N = Phi.shape
    r = y[None] - Phi @ mean_h.reshape(D, N).T                               # (J, m, D)
    rr = np.einsum("jmd,jmd->j", r, r)
    u = np.matmul(Phi.transpose(0, 2, 1), r).transpose(0, 2, 1).reshape(J, D * N, 1)   # (J, D N, 1): H r
    x = np.matmul(W, chol.T @ u)[..., 0]                                     # (J, h): K_j^-1 L^T H r
    d2_obs = (rr - np.einsum("jh,jh->j", x, x)) / noise_var
    return -0.5 * (m * D * (_LOG_2PI + np.log(noise_var)) + logdet + d2_obs)


def _woodbury_terms(PtP: np.ndarray, chol: np.ndarray, D: int, noise_var: float):
    """For every phase j: ``K_j^-1`` (J, h, h), ``K_j`` the Cholesky factor of ``sigma^2 I + L^T (I_D (x) PtP_j) L``,
    and ``log det(I + L^T (I_D (x) PtP_j) L / sigma^2)`` (J,)."""
    B = _gram(PtP, chol, D)
    h = B.shape[1]
    try:
        K = np.linalg.cholesky(B + noise_var * np.eye(h))
    except np.linalg.LinAlgError:
        # rounding left B with negative eigenvalues beyond the noise (a singular unshrink, e.g. fewer samples than
        # basis functions): the eigendecomposition, clipped at 0 as prefix_loglik's, with W^T W = (sigma^2 I + B)^-1
        lam, Q = np.linalg.eigh(B)
        lam = np.clip(lam, 0.0, None)
        W = (Q / np.sqrt(noise_var + lam)[:, None, :]).transpose(0, 2, 1)
        return W, np.log1p(lam / noise_var).sum(axis=1)
    logdet = 2.0 * np.log(np.diagonal(K, axis1=1, axis2=2)).sum(axis=1) - h * np.log(noise_var)
    return np.linalg.inv(K), logdet


def fit_statistic(y: np.ndarray, phases, means_h: np.ndarray, inflate: np.ndarray, chol: np.ndarray,
                  basis: GaussianBasis, noise_var: float, cache: dict | None = None):
    """The fit statistic ``d2`` of :func:`score_phases` and its degrees of freedom, arrays of shape (J, K).

    The coordinates need no residual of the samples: ``v_k = a_j - mu_k^T M_j`` with
    ``a_j = W_j^T H_j y`` (:func:`fit_terms`), one (K, h) x (h, h) product per phase.
    """
    m, D = y.shape
    phases = tuple(float(f) for f in phases)
    W, M, gam = fit_terms(basis, phases, int(m), chol, D, cache)
    d2 = np.ascontiguousarray(misfit_d2(y, phases, means_h, inflate, W, M, gam, basis, noise_var).T)   # (J, K)
    dof = seen_dof(basis, phases, int(m), D)  # at least D: the best-seen direction always counts
    return d2, np.repeat(dof[:, None], d2.shape[1], axis=1)


def misfit_d2(y: np.ndarray, phases: tuple, means_h: np.ndarray, inflate: np.ndarray, W: np.ndarray,
              M: np.ndarray, gam: np.ndarray, basis: GaussianBasis, noise_var: float) -> np.ndarray:
    """``sum_i v_i^2 / (sigma^2 + c_k gamma_i)`` of every component at every phase, shape (K, J).

    ``W``, ``M``, ``gam``: :func:`fit_terms`' maps and variances (all columns, or the
    best-seen ones of the pruning bound). Laid out (K, J w), contiguous, squared and divided
    in place and summed by a product: a (J, K, w) layout summed over its short last axis cost
    2-3x more at K = 1000 than the products themselves. The padding's columns are 0 in ``v``
    (zero maps), their variance sigma^2.
    """
    J, w = gam.shape
    v = coordinates(y, phases, means_h, W, M, basis)                       # (K, J w), a new array
    var = np.asarray(inflate, float)[:, None] * gam.reshape(1, J * w)
    var += noise_var
    np.multiply(v, v, out=v)
    np.divide(v, var, out=v)
    return (v.reshape(-1, w) @ np.ones(w)).reshape(-1, J)


def coordinates(y: np.ndarray, phases: tuple, means_h: np.ndarray, W: np.ndarray, M: np.ndarray,
                basis: GaussianBasis) -> np.ndarray:
    """The misfit's coordinates ``v = W_j^T H_j y - M_j^T mu_k`` of every component at every phase.

    ``W``, ``M`` (J, h, n): :func:`fit_terms`' maps, all their columns or some of them.
    Returns shape (K, J n), C-contiguous, per component: ``[k, j n + i]`` is coordinate ``i``
    at phase ``j`` (laid out so that the statistics are contiguous products, not sums over a
    short strided axis).
    """
    m, D = y.shape
    Phi = _basis_terms(basis, tuple(phases), int(m))[0]
    J, _, N = Phi.shape
    Hy = np.matmul(Phi.transpose(0, 2, 1), y).transpose(0, 2, 1).reshape(J, D * N)   # H y, dimension-major
    n = W.shape[2]
    Mt = M.transpose(1, 0, 2).reshape(D * N, J * n)                                 # one product for every phase
    v = means_h @ Mt
    np.subtract(np.einsum("jh,jhn->jn", Hy, W).reshape(1, J * n), v, out=v)
    return v


def fit_terms(basis: GaussianBasis, phases: tuple, m: int, chol: np.ndarray, D: int, cache: dict | None = None,
              most: int | None = None):
    """Per phase, the maps of the fit statistic (kept in ``cache``), padded to ``h = D N`` columns.

    ``most``: only the ``most`` best-seen directions of each dimension (``D most``
    columns; the pruning bound of :mod:`~drake_skills.library.prefix_bound`).

    Returns
    -------
    W, M : arrays, shape (J, h, w)
        From ``H y`` and from a component's mean to the coordinates ``v`` (``w = h``, or
        ``D most``; columns: the coordinates in ascending order of prior variance, the
        padding first; read-only).
    gamma : array, shape (J, w)
        The coordinates' prior variances per unit ``c`` (0 in the padding, whose columns
        of ``W`` and ``M`` are zero: its coordinates are 0 and add nothing).
    """
    kind = "fit" if most is None else f"fit{int(most)}"
    return _per_phase(cache, kind, tuple(phases), int(m), lambda fs: _fit_terms(basis, fs, int(m), chol, D, most))


def seen_dof(basis: GaussianBasis, phases, m: int, D: int) -> np.ndarray:
    """The fit statistic's degrees of freedom at each phase, shape (J,): D times the directions seen (read-only)."""
    return _seen_dof(basis, tuple(float(f) for f in phases), int(m), int(D), interaction.SEEN_RCOND)


@lru_cache(maxsize=256)
def _seen_dof(basis: GaussianBasis, phases: tuple, m: int, D: int, rcond: float) -> np.ndarray:
    out = np.array([D * _seen_directions(basis, f, m, rcond)[1].size for f in phases], float)
    out.setflags(write=False)
    return out


def _fit_terms(basis: GaussianBasis, phases: tuple, m: int, chol: np.ndarray, D: int, most: int | None = None):
    """:func:`fit_terms`, computed (one batched eigendecomposition per number of directions seen)."""
    N = basis.n_basis
    h = D * N
    J = len(phases)
    width = h if most is None else D * min(int(most), N)
    W, M = np.zeros((J, h, width)), np.zeros((J, h, width))
    gam = np.zeros((J, width))
    dirs = [_seen_directions(basis, f, m, interaction.SEEN_RCOND) for f in phases]
    if most is not None:                                             # eigenvalues ascending: the last are best seen
        dirs = [(V[:, max(g.size - int(most), 0):], g[max(g.size - int(most), 0):]) for V, g in dirs]
    for n in sorted({g.size for _, g in dirs}):
        js = [j for j, (_, g) in enumerate(dirs) if g.size == n]
        V = np.stack([dirs[j][0] for j in js])                       # (G, N, n)
        g = np.stack([dirs[j][1] for j in js])[:, None, :]           # (G, 1, n)
        Vg, Vs = np.zeros((len(js), h, D * n)), np.zeros((len(js), h, D * n))
        for d in range(D):                                           # I_D (x) V g^(+-1/2), block diagonal
            Vg[:, d * N:(d + 1) * N, d * n:(d + 1) * n] = V * np.sqrt(g)
            Vs[:, d * N:(d + 1) * N, d * n:(d + 1) * n] = V / np.sqrt(g)
        LV = np.matmul(chol.T, Vg)
        B = np.matmul(LV.transpose(0, 2, 1), LV)                     # Vg^T Sigma Vg
        gj, R = np.linalg.eigh(0.5 * (B + B.transpose(0, 2, 1)))     # ascending
        k = D * n
        W[js, :, width - k:] = np.matmul(Vs, R)
        M[js, :, width - k:] = np.matmul(Vg, R)
        gam[js, width - k:] = np.clip(gj, 0.0, None)
    for a in (W, M, gam):
        a.setflags(write=False)
    return W, M, gam


@lru_cache(maxsize=2048)
def _seen_directions(basis: GaussianBasis, f: float, m: int, rcond: float):
    """Eigenvectors (N, n) and eigenvalues (n,) of ``Phi^T Phi`` at least ``rcond`` of the largest (cached)."""
    g, V = np.linalg.eigh(_basis_at(basis, f, m)[1])
    keep = g >= rcond * g[-1]
    out = np.ascontiguousarray(V[:, keep]), g[keep].copy()
    for a in out:
        a.setflags(write=False)
    return out


def _per_phase(cache: dict | None, kind: str, phases: tuple, m: int, compute):
    """``compute(phases)`` (a tuple of arrays stacked over the phases), kept per phase and per phase set in ``cache``.

    ``cache[kind]`` holds the last :data:`_PHASE_ENTRIES` entries per ``(phase, m)`` (the
    phases recur; the sets asked for vary; a caller streaming arbitrary fixed fractions
    would otherwise grow it without end) and the last :data:`_STACKED_ENTRIES` stacked
    sets; ``compute`` is called for the phases missing only.
    """
    if cache is None:
        return compute(phases)
    store = cache.setdefault(kind, {"stacked": OrderedDict(), "phase": OrderedDict()})
    hit = store["stacked"].get((phases, m))
    if hit is None:
        # read each entry once into a local dict: another thread (or this call) may evict it
        got = {f: store["phase"].get((f, m)) for f in phases}
        missing = tuple(f for f in phases if got[f] is None)
        if missing:
            parts = compute(missing)
            for i, f in enumerate(missing):
                got[f] = tuple(p[i] for p in parts)
                put_bounded(store["phase"], (f, m), got[f], _PHASE_ENTRIES)
        hit = tuple(np.stack(a) for a in zip(*(got[f] for f in phases)))
        for a in hit:
            a.setflags(write=False)
        put_bounded(store["stacked"], (phases, m), hit, _STACKED_ENTRIES)
    return hit


def score_component(y: np.ndarray, phases, mean_h: np.ndarray, inflate: float, chol: np.ndarray,
                    basis: GaussianBasis, noise_var: float):
    """:func:`score_phases` for one component and several sample sets: arrays of shape (B, J).

    Row ``b`` equals the component's column of :func:`score_phases` of ``y[b]``.
    :func:`score_phases` diagonalizes the shared covariance per phase once for all K
    components (one batched eigendecomposition, the cost of a recognition). A question about
    one component (the record of beginnings, asked at every update while the library is young)
    does not need the eigenbasis: with ``A_j = sigma^2 I + c L^T G_j L`` and
    ``C_j = sigma^2 I + c B_j`` (``B_j = V_g^T Sigma V_g`` of the fit statistic),

        d2_obs = (r^T r - c (L^T u)^T A_j^{-1} (L^T u)) / sigma^2
        logdet = log det A_j - h log sigma^2
        d2     = z^T C_j^{-1} z,   z = I_D (x) g^{-1/2} V^T H y - V_g^T mu

    one batched Cholesky factorization each, shared by the sample sets, several times
    cheaper than the eigendecompositions, and without a cache that every update empties.
    Where a factorization fails (a covariance that rounding leaves short of positive
    definite, as with fewer samples than basis functions), :func:`score_phases` answers.

    Parameters
    ----------
    y : array, shape (B, m, D)
        Sample sets of equal size (the beginnings of one motion, resampled alike).
    mean_h : array, shape (D N,)
        The component's human mean, as a row of ``means_h``.
    inflate : float
        Its ``c_k``.
    (the rest as :func:`score_phases`)
    """
    try:
        with np.errstate(divide="raise", over="raise", invalid="raise"):
            return _score_component(y, phases, mean_h, inflate, chol, basis, noise_var)
    except (np.linalg.LinAlgError, FloatingPointError):
        # a covariance that rounding leaves short of positive definite (or overflows): the
        # eigendecompositions of score_phases clip its eigenvalues at 0
        out = [score_phases(yb, phases, np.asarray(mean_h, float)[None], np.array([float(inflate)]), chol, basis,
                            noise_var) for yb in y]
        return tuple(np.stack([o[i][:, 0] for o in out]) for i in range(3))


def _score_component(y, phases, mean_h, inflate, chol, basis, noise_var):
    B, m, D = y.shape
    phases = tuple(float(f) for f in phases)
    Phi, PtP = _basis_terms(basis, phases, int(m))
    J, _, N = Phi.shape
    h = D * N
    c, s2 = float(inflate), float(noise_var)
    mu = np.asarray(mean_h, float).reshape(D, N)
    PhiT = Phi.transpose(0, 2, 1)[None]                                # (1, J, N, m)
    Hy = np.matmul(PhiT, y[:, None]).transpose(0, 1, 3, 2).reshape(B, J, h)    # H y, dimension-major
    Hm = np.matmul(PtP, mu.T[None]).transpose(0, 2, 1).reshape(J, h)          # H H^T mu = H (mean samples)
    u = Hy - Hm[None]                                                  # H r, r = y - Phi mu
    r = y[:, None] - np.matmul(Phi, mu.T[None])[None]                  # (B, J, m, D)
    rr = np.sum(r * r, axis=(2, 3))
    Ld = chol.reshape(D, N, -1)
    Gt = sum(np.matmul(Ld[d].T, np.matmul(PtP, Ld[d])) for d in range(D))       # L^T G_j L
    LA = np.linalg.cholesky(s2 * np.eye(h) + c * Gt)
    x = np.linalg.solve(LA[None], (u @ chol)[..., None])[..., 0]       # LA^-1 L^T u
    d2_obs = (rr - c * np.sum(x * x, axis=2)) / s2
    logdet = 2.0 * np.sum(np.log(np.diagonal(LA, axis1=1, axis2=2)), axis=1) - h * np.log(s2)
    loglik = -0.5 * (m * D * (_LOG_2PI + np.log(s2)) + logdet[None] + d2_obs)
    Vs, Vg = _seen_maps(basis, phases, int(m), D)                     # (J, h, w), zero columns as padding
    z = np.einsum("bjh,jhw->bjw", Hy, Vs) - np.einsum("h,jhw->jw", mu.reshape(h), Vg)[None]
    LV = np.matmul(chol.T[None], Vg)
    LC = np.linalg.cholesky(s2 * np.eye(Vg.shape[2]) + c * np.matmul(LV.transpose(0, 2, 1), LV))  # padding: z = 0
    zc = np.linalg.solve(LC[None], z[..., None])[..., 0]
    d2 = np.sum(zc * zc, axis=2)
    dof = np.broadcast_to(seen_dof(basis, phases, int(m), D)[None], d2.shape).copy()
    return loglik, d2, dof


@lru_cache(maxsize=256)
def _seen_maps(basis: GaussianBasis, phases: tuple, m: int, D: int):
    """``I_D (x) V g^{-1/2}`` and ``I_D (x) V g^{1/2}`` per phase, zero-padded to a common width: (J, h, w) each.

    The directions are :func:`_seen_directions` at each phase (settings only; cached, read-only).
    """
    N = basis.n_basis
    dirs = [_seen_directions(basis, f, m, interaction.SEEN_RCOND) for f in phases]
    n = max(g.size for _, g in dirs)
    Vs, Vg = np.zeros((len(phases), D * N, D * n)), np.zeros((len(phases), D * N, D * n))
    for j, (V, g) in enumerate(dirs):
        for d in range(D):
            Vs[j, d * N:(d + 1) * N, d * n:d * n + g.size] = V / np.sqrt(g)
            Vg[j, d * N:(d + 1) * N, d * n:d * n + g.size] = V * np.sqrt(g)
    for a in (Vs, Vg):
        a.setflags(write=False)
    return Vs, Vg


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


def band_of(guess: float) -> tuple:
    """The phases of :data:`PHASE_GRID` that :func:`phase_band` allows for one guess, in scalars (a tenth of its cost
    on one guess; tested equal to it)."""
    g = min(max(float(guess), PHASE_GRID[0]), 1.0)
    lo, hi = g / PHASE_BAND - 1e-12, min(g * PHASE_BAND, 1.0) + 1e-12
    n = len(PHASE_GRID)
    first = next((i for i in range(n) if PHASE_GRID[i] >= lo), n)
    last = next((i for i in range(n - 1, -1, -1) if PHASE_GRID[i] <= hi), -1)
    near = min(range(n), key=lambda i: abs(PHASE_GRID[i] - g))
    return PHASE_GRID[min(first, near):max(last, near) + 1]   # near lies in the band or next to it


def phase_band(guess) -> np.ndarray:
    """Which phases of :data:`PHASE_GRID` each component's band allows: a mask, shape (K, len(PHASE_GRID))."""
    grid = np.array(PHASE_GRID)
    g = np.clip(np.asarray(guess, float), grid[0], 1.0)
    lo, hi = g / PHASE_BAND, np.minimum(g * PHASE_BAND, 1.0)
    wanted = (grid[None, :] >= lo[:, None] - 1e-12) & (grid[None, :] <= hi[:, None] + 1e-12)
    wanted[np.arange(g.size), np.abs(grid[None, :] - g[:, None]).argmin(axis=1)] = True
    return wanted

