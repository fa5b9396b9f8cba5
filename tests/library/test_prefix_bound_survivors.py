"""The pruning bound where ``make mutate`` found it untested: with the ridge undone, and wide bases of many functions.

Recognition compares a beginning with the least-squares weights its samples see,
``S^-1 mu`` (``RecognitionMixin._prefix_model``), and hands the bound ``mu`` with
``unshrink = S^-1``. The bound is checked here against the exact fit statistic ``d2``
of that model (:func:`~drake_skills.library.prefix.score_phases` on ``S^-1 mu`` and
``S^-1 Sigma S^-T``, itself checked against ``prefix_statistics`` in
``test_prefix_mutants.py``), on samples built so that the bound is nearly tight: on a
component's mean, along the direction the stretched basis sees most, along a direction
the pseudo-inverse's cut-off drops. ``S^-1 = I + beta (Phi^T Phi)^-1`` is written in
closed form (not as the library computes it).
"""
import numpy as np
import pytest

from drake_skills.library import prefix_bound
from drake_skills.library.novelty import chi2_ppf
from drake_skills.library.prefix import _basis_at, phase_band, score_phases
from drake_skills.promp.basis import GaussianBasis

GRID = np.round(np.arange(1, 21) / 20.0, 6)


def _unshrink(basis, n_samples, ridge):
    """``S^-1 = I + beta G^-1`` with ``G`` the Gram matrix of the basis over ``n_samples`` phases of [0, 1]."""
    Phi = basis.phi(np.linspace(0.0, 1.0, n_samples))
    return np.eye(basis.n_basis) + ridge * np.linalg.inv(Phi.T @ Phi)


def _exact_d2(y, means, inflate, S, basis, noise, Sinv):
    """d2 (K, 20) of every component at every grid phase, for the model the samples see (S^-1 mu, S^-1 Sigma S^-T)."""
    D = y.shape[1]
    U = np.kron(np.eye(D), Sinv)
    _, d2, _ = score_phases(y, GRID, means @ U.T, inflate, np.linalg.cholesky(U @ S @ U.T), basis, noise)
    return d2.T


def _on_the_mean():
    """Six samples exactly on component 0's mean trajectory at phase 0.6 (default basis and ridge): d2 there is 0,
    so each probe must be compared with the mean at its own phase (sample 4 at 0.48, not 0.6)."""
    basis, D, m, f = GaussianBasis(7, 1.0, True), 2, 6, 0.6
    Sinv = _unshrink(basis, 100, 1e-2)
    rng = np.random.default_rng(0)
    mu0 = np.concatenate([np.linspace(0.0, 6.0, 7), 3.0 * np.sin(np.linspace(0.0, np.pi, 7))])
    means = np.stack([mu0, mu0 + 0.3 * rng.standard_normal(14), mu0 + 30.0])
    y = basis.phi(np.linspace(0.0, f, m)) @ (np.kron(np.eye(D), Sinv) @ mu0).reshape(D, 7).T
    return dict(y=y, means=means, S=1e-3 * np.eye(14), noise=1e-2, basis=basis, Sinv=Sinv, f=f, zero=True)


def _along_the_most_seen_direction():
    """A strong ridge (1, 30 samples) stretches the basis into rows of both signs: eight samples off component 0's
    mean along the top singular vector of Phi S^-1 (sigma_1^2 = 164), isotropic Sigma. d2 is about |delta|^2 / (c s);
    the bound must take lambda_I from the absolute row and column sums (290), not the signed ones (11)."""
    basis, m, f = GaussianBasis(7, 1.0, True), 8, 1.0
    Sinv = _unshrink(basis, 30, 1.0)
    H = basis.phi(np.linspace(0.0, f, m)) @ Sinv
    v = np.linalg.svd(H)[2][0]
    mu0 = np.linspace(0.0, 6.0, 7)
    means = np.stack([mu0, mu0 + 30.0])
    s = 1e-2
    delta = 3.0 * np.sqrt(1.1 * s) * v                   # d2 about 9 at c = 1.1
    y = (H @ (mu0 + delta))[:, None]
    return dict(y=y, means=means, S=s * np.eye(7), noise=1e-2, basis=basis, Sinv=Sinv, f=f, zero=False)


def _along_a_dropped_direction():
    """Samples at 0 and component 0's seen mean ``S^-1 mu`` of norm 1e4 along the eigenvector of the Gram matrix of
    phase 0.1 (6 samples, 10 narrow functions) just below the pseudo-inverse's cut-off: d2 leaves that direction out
    (d2 = 0), and the bound must subtract what it can add, counted on S^-1 mu (ridge 100: |mu| is 0.06 of it)."""
    basis, m, f = GaussianBasis(10, 0.5, True), 6, 0.1
    Sinv = _unshrink(basis, 100, 100.0)
    _, PtP, _ = _basis_at(basis, f, m)
    lam, V = np.linalg.eigh(PtP)
    j = np.flatnonzero(lam < 1e-10 * lam[-1])[-1]
    seen = 1e4 * V[:, j]
    means = np.stack([np.linalg.solve(Sinv, seen), np.full(10, 30.0)])
    return dict(y=np.zeros((m, 1)), means=means, S=1e-8 * np.eye(10), noise=1e-4, basis=basis, Sinv=Sinv, f=f,
                zero=True)


CASES = {"on_the_mean": _on_the_mean, "most_seen_direction": _along_the_most_seen_direction,
         "dropped_direction": _along_a_dropped_direction}


@pytest.mark.parametrize("case", list(CASES))
def test_with_the_ridge_undone_the_bound_lies_below_the_exact_fit_statistic_of_the_model_the_samples_see(case):
    """Every component, every phase, 3 and 8 probes: bound <= d2 (1e-6 relative); the bound is not vacuous: at the
    samples' phase the far component's bound is above the novelty threshold at h = D N degrees of freedom."""
    c = CASES[case]()
    y, means, S, noise, basis, Sinv = c["y"], c["means"], c["S"], c["noise"], c["basis"], c["Sinv"]
    K = means.shape[0]
    inflate = np.full(K, 1.1)
    sigma_max = float(np.linalg.eigvalsh(S)[-1])
    d2 = _exact_d2(y, means, inflate, S, basis, noise, Sinv)
    k = int(np.flatnonzero(GRID == c["f"])[0])
    if c["zero"]:
        assert d2[0, k] == pytest.approx(0.0, abs=1e-6)
    else:
        assert 5.0 < d2[0, k] < 12.0
    for q in (3, 8):
        bound = prefix_bound.fit_lower_bounds(means, inflate, GRID, y, sigma_max, basis, noise, n_probes=q,
                                              unshrink=Sinv)
        assert bound.shape == (K, 20)
        assert (bound <= d2 + 1e-6 * (1.0 + np.abs(d2))).all(), np.max(bound - d2)
        assert bound[-1, k] > chi2_ppf(0.999, means.shape[1]), bound[-1, k]


def test_prefix_candidates_with_the_ridge_undone_keeps_the_skill_the_samples_lie_on():
    """A strong ridge (10): 60 samples on component 0's seen mean S^-1 mu over phase 0.6 fit it (d2 = 0 <= 46.8,
    the 0.999 quantile at 21 degrees of freedom) and are kept; the component 30 units away in every weight is ruled
    out. (Compared with Phi mu instead, the samples would be ruled out of their own skill.)"""
    basis, D, m, f = GaussianBasis(7, 1.0, True), 3, 60, 0.6
    Sinv = _unshrink(basis, 100, 10.0)
    z = np.linspace(0.0, 1.0, 7)
    mu0 = np.concatenate([6.0 * z, 3.0 * np.sin(np.pi * z), 2.0 * z ** 2])
    means = np.stack([mu0, mu0 + 30.0])
    y = basis.phi(np.linspace(0.0, f, m)) @ (np.kron(np.eye(D), Sinv) @ mu0).reshape(D, 7).T
    S, noise, inflate = 1e-2 * np.eye(21), 0.05, np.full(2, 1.1)
    threshold = chi2_ppf(0.999, 21)
    allowed = phase_band(np.array([f, f]))
    d2 = _exact_d2(y, means, inflate, S, basis, noise, Sinv)
    assert ((d2 <= threshold) & allowed).any(axis=1).tolist() == [True, False]
    keep = prefix_bound.prefix_candidates(means, inflate, GRID, allowed, y, 1e-2, basis, noise, threshold,
                                          unshrink=Sinv)
    assert keep.tolist() == [True, False]


def test_a_wide_basis_of_many_functions_takes_the_direct_form_where_the_recurrence_would_overflow():
    """43 functions of width 1.5: rho^42 = exp(42^2 / 1.5^2 z) = exp(784 z) passes the largest double (exp(709))
    above z = 0.9, so the column form must be the direct one there: equal to GaussianBasis.phi (rtol 1e-10), and the
    bound on a beginning ending at phase 1 finite and below d2."""
    basis = GaussianBasis(43, 1.5, True)
    z = np.linspace(0.0, 1.0, 12).reshape(3, 4)
    cols = prefix_bound._basis_columns(basis, z)
    np.testing.assert_allclose(np.moveaxis(cols, 0, -1), basis.phi(z.ravel()).reshape(3, 4, 43), rtol=1e-10,
                               atol=1e-300)
    rng = np.random.default_rng(3)
    w = np.sin(np.linspace(0.0, 3.0, 43)) * 4.0
    y = basis.phi(np.linspace(0.0, 1.0, 30)) @ w[:, None] + rng.normal(0.0, 0.05, (30, 1))
    means = np.stack([w, w + 2.0])
    S = 0.1 * np.eye(43)
    inflate = np.full(2, 1.5)
    _, d2, _ = score_phases(y, GRID, means, inflate, np.linalg.cholesky(S), basis, 0.01)
    bound = prefix_bound.fit_lower_bounds(means, inflate, GRID, y, 0.1, basis, 0.01)
    assert np.isfinite(bound).all()
    assert (bound <= d2.T + 1e-6 * (1.0 + d2.T)).all()
