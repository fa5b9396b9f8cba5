"""A cheap lower bound on the prefix fit statistic, to prune a large library before scoring it.

:func:`~drake_skills.library.prefix.score_phases` scores the observed beginning of a
motion against every component at every phase of its band: for a library of a
thousand components that is most of the cost of recognizing a prefix (the residuals of
all samples against every component's mean at every phase), and almost all of those
components cannot explain the samples at all. :func:`prefix_candidates` rules them out
with a lower bound on the fit statistic ``d2`` that needs no residuals of the samples (see
:func:`fit_lower_bounds`); only the others are scored. The recognition is the same as
scoring every component (``tests/library/test_scale.py`` checks both the bound against
the exact ``d2`` and the answers against scoring all components).
"""
from __future__ import annotations

import numpy as np

from drake_skills.library.novelty import chi2_ppf
from drake_skills.library.prefix import fit_terms, misfit_d2, seen_dof
from drake_skills.promp.basis import GaussianBasis

#: Directions per dimension the bound looks at: the ones the samples see best.
N_DIRECTIONS = 2
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
        As :func:`~drake_skills.library.prefix.score_phases` (``cache`` keeps this bound's
        decompositions beside the statistic's).
    n_directions : int
        Directions per dimension looked at (all the seen ones: the bound is ``d2``).

    Returns
    -------
    bound, dof : arrays, shape (K, J)
        ``bound <= d2`` and the exact ``dof`` of :func:`~drake_skills.library.prefix.score_phases`.

    Notes
    -----
    ``d2 = x^T C^{-1} x`` is the Mahalanobis distance of the coordinates ``x`` of the
    least-squares weights in the directions the samples see well, with covariance
    ``C = sigma^2 I + c V_g^T Sigma V_g`` (:func:`~drake_skills.promp.interaction.prefix_statistics`).
    The Mahalanobis distance of a sub-vector of ``x`` under its own block of ``C`` never
    exceeds that of the whole, so the ``n_directions`` best-seen directions of each
    dimension give a lower bound, and their block is ``D n_directions`` square: one small
    eigendecomposition per phase for all components, no residuals of the samples, and one
    (K, h) x (h, J D n) product for all pairs.
    """
    m, D = ys.shape
    phases = tuple(float(f) for f in phases)
    s = max(1, int(n_directions))
    W, M, gam = fit_terms(basis, phases, int(m), chol, D, cache, most=s)
    bound = misfit_d2(ys, phases, means_h, inflate, W, M, gam, basis, noise_var)   # (K, J)
    dof = seen_dof(basis, phases, int(m), D)
    return bound, np.broadcast_to(dof[None, :], bound.shape).copy()


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
    threshold = chi2_ppf(quantile, dof[:1])     # (1, J): dof depends on the phase only (fit_lower_bounds)
    fits = bound * (1.0 - ROUNDING) <= threshold * (1.0 + ROUNDING)
    return (fits & allowed[:, cols]).any(axis=1)
