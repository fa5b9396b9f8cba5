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
        Coordinates whose terms are summed exactly.

    Returns
    -------
    bound, dof : arrays, shape (K, J)
        ``bound <= d2`` and the exact ``dof`` of :func:`~drake_skills.library.prefix.score_phases`.

    Notes
    -----
    ``d2 = sum_i v_i^2 / (sigma^2 + c gamma_i)`` over the coordinates of the least-squares
    weights in the directions the samples see well (:func:`~drake_skills.library.prefix.fit_statistic`).
    The ``n`` coordinates of largest prior variance ``gamma_i`` are summed exactly; each of
    the others has ``gamma_i`` at most the largest of them, ``gamma_rest``, so together they
    add at least ``(|v|^2 - sum_top v_i^2) / (sigma^2 + c gamma_rest)``, and ``|v|^2`` is the
    squared norm of the residual's part in the seen directions, a (K, D, N) product per
    phase. Neither needs the residuals of the samples: all pairs cost two products instead
    of the (J, K, m, D) residuals of the exact statistic.
    """
    m, D = ys.shape
    phases = tuple(float(f) for f in phases)
    Phi = _basis_terms(basis, phases, int(m))[0]
    W, M, gam, seen, Vs, Vg = fit_terms(basis, phases, int(m), chol, D, cache)
    J, _, N = Phi.shape
    K, h = means_h.shape[0], D * N
    n = min(int(n_directions), h)
    Pty = np.matmul(Phi.transpose(0, 2, 1), ys)                                # (J, N, D)
    Hy = Pty.transpose(0, 2, 1).reshape(J, h)
    v = np.einsum("jh,jhn->jn", Hy, W[:, :, h - n:])[:, None, :] - np.matmul(means_h, M[:, :, h - n:])
    c = np.asarray(inflate, float)[None, :, None]
    top = np.where(seen[:, None, h - n:], v * v, 0.0)
    bound = np.sum(top / (noise_var + c * gam[:, None, h - n:]), axis=2)          # (J, K)
    if n < h:
        b = np.matmul(Vs.transpose(0, 2, 1), Pty).transpose(0, 2, 1)            # (J, D, N): Vs^T Phi^T y_d
        Am = np.matmul(means_h.reshape(1, K * D, N), Vg).reshape(J, K, D, N)     # Vg^T mu_kd
        norm2 = np.sum((b[:, None] - Am) ** 2, axis=(2, 3))
        rest = np.maximum(norm2 - top.sum(axis=2), 0.0)
        bound += np.where(seen[:, None, h - n - 1], rest / (noise_var + c[..., 0] * gam[:, None, h - n - 1]), 0.0)
    dof = np.maximum(seen.sum(axis=1).astype(float), 1e-9)
    return bound.T, np.broadcast_to(dof[None, :], (K, J)).copy()


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
