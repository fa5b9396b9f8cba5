"""A cheap lower bound on the prefix fit statistic, to prune a large library before scoring it.

:func:`~drake_skills.library.prefix.score_phases` scores the observed beginning of a
motion against every component at every phase of its band: for a library of a
thousand components that is most of the cost of recognizing a prefix (the residuals of
all samples against every component's mean at every phase), and almost all of those
components cannot explain the samples at all. :func:`prefix_candidates` rules them out
with a lower bound on the fit statistic ``d2`` that skips the samples altogether (see
:func:`fit_lower_bounds`); only the others are scored. The recognition is the same as
scoring every component (``tests/library/test_scale.py`` checks both the bound against
the exact ``d2`` and the answers against scoring all components).
"""
from __future__ import annotations

import numpy as np

from drake_skills.library.novelty import chi2_ppf
from drake_skills.library.prefix import _basis_terms, fit_terms
from drake_skills.promp.basis import GaussianBasis

#: Coordinates per phase whose terms the bound sums exactly: those of largest prior variance.
N_DIRECTIONS = 4
#: Relative allowance for rounding when a bound is compared with a threshold (the bound and
#: the exact statistic compute the same misfit coordinates by different products).
ROUNDING = 1e-6


def fit_lower_bounds(ys: np.ndarray, phases, means_h: np.ndarray, inflate: np.ndarray, chol: np.ndarray,
                     basis: GaussianBasis, noise_var: float, cache: dict | None = None, *,
                     n_directions: int = N_DIRECTIONS):
    """Lower bounds of the fit statistic ``d2`` of every component at every phase, and its degrees of freedom.

    Parameters
    ----------
    ys : array, shape (m, D)
        The observed samples, evenly spaced over ``[0, phase]``.
    phases : sequence of float, length J
    means_h, inflate, chol, basis, noise_var, cache
        As :func:`~drake_skills.library.prefix.score_phases` (``cache`` shares its
        decompositions).
    n_directions : int
        Coordinates summed per phase.

    Returns
    -------
    bound, dof : arrays, shape (K, J)
        ``bound <= d2`` and the exact ``dof`` of :func:`~drake_skills.library.prefix.score_phases`.

    Notes
    -----
    ``d2 = sum_i v_i^2 / (sigma^2 + c gamma_i)`` over the coordinates of the least-squares
    weights in the directions the samples see well (:func:`~drake_skills.library.prefix.fit_statistic`),
    a sum of non-negative terms, so the same sum over the ``n_directions`` coordinates of
    largest prior variance ``gamma_i`` is a lower bound. (The others weigh more per unit
    of misfit, but a skill's components differ most where the skills vary most.) Their
    coordinates need no residual of the samples, ``v = a_j - mu_k^T M_j``: all pairs cost
    one (K, h) x (h, J n) product instead of the (J, K, m, D) residuals of the exact statistic.
    """
    m, D = ys.shape
    phases = tuple(float(f) for f in phases)
    Phi = _basis_terms(basis, phases, int(m))[0]
    W, M, gam, seen = fit_terms(basis, phases, int(m), chol, D, cache)
    J, h = gam.shape
    K = means_h.shape[0]
    n = min(int(n_directions), h)
    Hy = np.matmul(Phi.transpose(0, 2, 1), ys).transpose(0, 2, 1).reshape(J, h)   # H y, dimension-major
    a = np.einsum("jh,jhn->jn", Hy, W[:, :, h - n:])                              # (J, n)
    Mt = M[:, :, h - n:].transpose(1, 0, 2).reshape(h, J * n)                      # one product for every phase
    v = a.reshape(1, J * n) - means_h @ Mt                                         # (K, J n)
    var = noise_var + np.outer(np.asarray(inflate, float), gam[:, h - n:].reshape(-1))
    terms = np.where(seen[:, h - n:].reshape(1, -1), v * v / var, 0.0)
    dof = seen.sum(axis=1).astype(float)
    return terms.reshape(K, J, n).sum(axis=2), np.broadcast_to(dof[None, :], (K, J)).copy()


def prefix_candidates(ys: np.ndarray, phases, allowed: np.ndarray, means_h: np.ndarray, inflate: np.ndarray,
                      chol: np.ndarray, basis: GaussianBasis, noise_var: float, quantile: float,
                      cache: dict | None = None) -> np.ndarray:
    """Which components may explain the observed beginning ``ys``: a mask, shape (K,).

    ``allowed`` (K, J) says at which of ``phases`` each component will be scored;
    ``quantile`` is the novelty quantile of the prefix test (``d2`` against the chi-square
    quantile at its ``dof``). A component is ruled out where the lower bound of
    :func:`fit_lower_bounds` exceeds that threshold at every phase it allows: its test
    fails wherever its phase is chosen.
    """
    allowed = np.asarray(allowed, bool)
    phases = np.asarray(phases, float)
    cols = np.flatnonzero(allowed.any(axis=0))
    keep = np.zeros(allowed.shape[0], bool)
    if not cols.size:
        return keep
    bound, dof = fit_lower_bounds(ys, tuple(phases[cols]), means_h, inflate, chol, basis, noise_var, cache)
    threshold = chi2_ppf(quantile, dof)
    fits = bound * (1.0 - ROUNDING) <= threshold * (1.0 + ROUNDING)
    return (fits & allowed[:, cols]).any(axis=1)
