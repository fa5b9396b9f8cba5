"""Prefix scoring (``library.prefix``) and its pruning bound (``library.prefix_bound``) against references.

The per-component reference of :func:`~drake_skills.library.prefix.score_phases` is
:func:`~drake_skills.promp.interaction.prefix_statistics` (itself checked against the
observation-space Gaussian in ``tests/promp``); :func:`score_prefix` is checked against
the band, argmax and average written out here; the bound against the exact ``d2`` of
every pair and the basis forms against :meth:`GaussianBasis.phi`. Small random
problems (a few components, D = 2-3, N = 4-7), so the cases the library rarely meets
are here: fewer samples than basis functions, a basis that is not normalized, wide
and narrow bases.
"""
import numpy as np
import pytest
from scipy.special import logsumexp

from drake_skills.library import prefix, prefix_bound
from drake_skills.library.prefix import PHASE_GRID, phase_band, score_at_phase, score_phases, score_prefix
from drake_skills.promp.basis import GaussianBasis
from drake_skills.promp.interaction import prefix_statistics

GRID = np.round(np.arange(1, 21) / 20.0, 6)


def _problem(seed, D=3, N=6, K=4, m=30, width=1.0, normalized=True, spread=0.5):
    """Random components near a random trajectory, a random SPD covariance: (y, means (K, D N), inflate, chol, basis)."""
    rng = np.random.default_rng(seed)
    basis = GaussianBasis(N, width, normalized)
    h = D * N
    A = rng.standard_normal((h, h))
    S = A @ A.T / h + 0.05 * np.eye(h)
    w = rng.normal(0.0, 2.0, h)
    f = rng.uniform(0.3, 1.0)
    y = basis.phi(np.linspace(0.0, f, m)) @ w.reshape(D, N).T + rng.normal(0, 0.05, (m, D))
    means = w[None] + spread * rng.standard_normal((K, h))
    inflate = 1.0 + 1.0 / rng.uniform(1.0, 6.0, K)
    return y, means, inflate, np.linalg.cholesky(S), basis, S


def _reference(y, phases, means, inflate, S, basis, noise):
    m = y.shape[0]
    out = np.empty((3, len(phases), means.shape[0]))
    for j, f in enumerate(phases):
        Phi = basis.phi(np.linspace(0.0, f, m))
        for k in range(means.shape[0]):
            out[:, j, k] = prefix_statistics(means[k], S * inflate[k], Phi, y, noise)
    return out


CASES = [dict(seed=0), dict(seed=1, D=2, N=4, m=12), dict(seed=2, N=7, m=5), dict(seed=3, normalized=False),
         dict(seed=4, width=0.4, m=50), dict(seed=5, width=2.5, K=1, m=8)]


@pytest.mark.parametrize("case", CASES, ids=[str(i) for i in range(len(CASES))])
@pytest.mark.parametrize("cached", [False, True])
def test_score_phases_equals_prefix_statistics_for_every_component_and_phase(case, cached):
    """Log-likelihood, fit statistic and its degrees of freedom, every (phase, component) pair: rtol 1e-9; with a
    cache, twice (computed, then taken from the cache), and a second phase set sharing phases with the first."""
    y, means, inflate, chol, basis, S = _problem(**case)
    noise = 0.03
    cache = {} if cached else None
    for phases in [(0.05, 0.3, 0.65, 1.0), (0.05, 0.3, 0.65, 1.0), (0.1, 0.3, 0.95)]:
        got = np.array(score_phases(y, phases, means, inflate, chol, basis, noise, cache))
        ref = _reference(y, phases, means, inflate, S, basis, noise)
        np.testing.assert_allclose(got[0], ref[0], rtol=1e-9, atol=1e-8)
        # d2 is a difference of two terms: 1e-5 for the ill-conditioned wide basis (width 2.5, 3e-6 seen)
        np.testing.assert_allclose(got[1], ref[1], rtol=1e-5, atol=1e-7)
        np.testing.assert_array_equal(got[2], ref[2])
    if cached:
        assert set(cache["stacked"]) == {((0.05, 0.3, 0.65, 1.0), y.shape[0]), ((0.1, 0.3, 0.95), y.shape[0])}
        assert {k for k in cache if k != "stacked"} == {(f, y.shape[0]) for f in (0.05, 0.3, 0.65, 1.0, 0.1, 0.95)}


def test_the_degrees_of_freedom_are_d_times_the_rank_of_the_observed_basis():
    """Five samples of a 7-function basis span 5 directions per dimension; a 5 % beginning even fewer."""
    y, means, inflate, chol, basis, _ = _problem(2, N=7, m=5)
    _, _, dof = score_phases(y, (0.05, 1.0), means, inflate, chol, basis, 0.03)
    ranks = [np.linalg.matrix_rank(basis.phi(np.linspace(0, f, 5)).T @ basis.phi(np.linspace(0, f, 5)),
                                   tol=1e-10 * np.linalg.norm(basis.phi(np.linspace(0, f, 5)), 2) ** 2)
             for f in (0.05, 1.0)]
    np.testing.assert_array_equal(dof[:, 0], [3 * r for r in ranks])
    assert dof[1, 0] == 15 and dof[0, 0] < 15


def test_score_at_phase_is_score_phases_at_that_phase():
    y, means, inflate, chol, basis, S = _problem(0)
    got = score_at_phase(y, 0.4, means, inflate, chol, basis, 0.03)
    ref = _reference(y, (0.4,), means, inflate, S, basis, 0.03)[:, 0]
    for a, b in zip(got, ref):
        assert a.shape == (4,)
        np.testing.assert_allclose(a, b, rtol=1e-7, atol=1e-7)


def _band_reference(guess):
    g = min(max(guess, GRID[0]), 1.0)
    band = {f for f in GRID if g / 1.5 - 1e-12 <= f <= min(g * 1.5, 1.0) + 1e-12}
    band.add(GRID[np.abs(GRID - g).argmin()])
    return np.isin(GRID, sorted(band))


@pytest.mark.parametrize("guess", [0.0, 0.01, 0.05, 0.06, 0.1, 0.2, 0.33, 0.5, 0.6667, 0.9, 1.0, 1.2, 3.0])
def test_phase_band_is_the_grid_within_a_factor_1_5_of_the_clipped_guess_and_its_nearest_phase(guess):
    np.testing.assert_array_equal(phase_band([guess])[0], _band_reference(guess))


def test_phase_band_edges():
    """0.2 allows 0.15 (= 0.2 / 1.5 rounded up to the grid) to 0.3 exactly; 0.01 allows only 0.05; 3 only 1."""
    assert GRID[phase_band([0.2])[0]].tolist() == [0.15, 0.2, 0.25, 0.3]
    assert GRID[phase_band([0.01])[0]].tolist() == [0.05]
    assert GRID[phase_band([3.0])[0]].tolist() == [0.7, 0.75, 0.8, 0.85, 0.9, 0.95, 1.0]
    assert GRID[phase_band([0.45])[0]].tolist() == [0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6, 0.65]
    assert phase_band([0.2, 0.5]).shape == (2, 20) and PHASE_GRID == tuple(GRID)


@pytest.mark.parametrize("given_band", [False, True])
def test_score_prefix_takes_the_most_likely_phase_of_each_band_and_averages_the_likelihood_over_it(given_band):
    """Per component: the phase of highest log-likelihood in its band, its d2 and dof, and as evidence
    logsumexp over the band minus log(band size)."""
    y, means, inflate, chol, basis, S = _problem(6, K=5, m=25)
    guess = np.array([0.05, 0.3, 0.62, 1.0, 2.0])
    noise = 0.03
    sc = score_prefix(y, guess, means, inflate, chol, basis, noise, {}, phase_band(guess) if given_band else None)
    ref = _reference(y, GRID, means, inflate, S, basis, noise)
    for k in range(5):
        band = np.flatnonzero(_band_reference(guess[k]))
        j = band[np.argmax(ref[0, band, k])]
        assert sc.phases[k] == GRID[j]
        np.testing.assert_allclose(sc.log_likelihoods[k], logsumexp(ref[0, band, k]) - np.log(band.size), rtol=1e-9)
        np.testing.assert_allclose(sc.mahalanobis_sq[k], ref[1, j, k], rtol=1e-7, atol=1e-7)
        assert sc.dof[k] == ref[2, j, k]
    assert len(set(sc.phases)) >= 3


# ------------------------------------------------------------------------------------------------ prefix_bound
@pytest.mark.parametrize("width, normalized", [(1.0, True), (0.3, True), (1.0, False), (0.212, True), (0.05, True)])
def test_basis_rows_and_columns_are_the_basis_at_those_phases(width, normalized):
    """Both forms equal GaussianBasis.phi (rtol 1e-12), the column form with the basis axis first. The narrow
    bases take the direct form where the recurrence would overflow: at width 0.212 (7 functions) rho^6 =
    exp(6^2 / 0.212^2) = exp(801) is past the largest double, (N - 1)^2 / w^2 = 801 > 600."""
    basis = GaussianBasis(7, width, normalized)
    z = np.linspace(0.0, 1.0, 24).reshape(4, 6)
    ref = basis.phi(z.ravel()).reshape(4, 6, 7)
    np.testing.assert_allclose(prefix_bound.basis_rows(basis, z), ref, rtol=1e-12, atol=1e-300)
    cols = prefix_bound._basis_columns(basis, z)
    assert cols.shape == (7, 4, 6)
    np.testing.assert_allclose(np.moveaxis(cols, 0, -1), ref, rtol=1e-10, atol=1e-300)


def test_fit_residual_is_the_squared_distance_of_the_samples_from_the_span_of_the_basis():
    rng = np.random.default_rng(8)
    basis = GaussianBasis(5, 1.0, True)
    y = rng.standard_normal((12, 2))
    phases = np.array([0.1, 0.5, 1.0])
    got = prefix_bound.fit_residual(y, phases, basis)
    for f, e in zip(phases, got):
        Phi = basis.phi(np.linspace(0.0, f, 12))    # the projection with d2's cut-off (1e-10 of the Gram matrix)
        P = Phi @ np.linalg.pinv(Phi.T @ Phi, rcond=1e-10, hermitian=True) @ Phi.T
        assert e == pytest.approx(float(np.sum((y - P @ y) ** 2)), rel=1e-7, abs=1e-9)
    # samples in the span leave nothing (clipped at 0, not a rounding below it)
    w = rng.standard_normal((2, 5))
    inside = basis.phi(np.linspace(0.0, 1.0, 12)) @ w.T
    r = prefix_bound.fit_residual(inside, np.array([1.0]), basis)
    assert r.shape == (1,) and 0.0 <= r[0] < 1e-9


@pytest.mark.parametrize("case", CASES, ids=[str(i) for i in range(len(CASES))])
def test_the_lower_bound_lies_below_the_exact_fit_statistic_and_is_not_vacuous(case):
    """Every component, every phase, 3 and 8 probes: bound <= d2 (up to 1e-6 relative); for components whose means
    are far from the samples the bound is positive and within a factor 50 of d2 at the true phase."""
    y, means, inflate, chol, basis, S = _problem(**case, spread=4.0)
    noise = 0.03
    sigma_max = float(np.linalg.eigvalsh(S)[-1])
    _, d2, _ = score_phases(y, GRID, means, inflate, chol, basis, noise)
    for q in (3, 8):
        bound = prefix_bound.fit_lower_bounds(means, inflate, GRID, y, sigma_max, basis, noise, n_probes=q)
        assert bound.shape == (means.shape[0], 20)
        assert (bound <= d2.T + 1e-6 * (1 + d2.T)).all(), np.max(bound - d2.T)
    E = prefix_bound.fit_residual(y, GRID, basis)
    np.testing.assert_array_equal(
        prefix_bound.fit_lower_bounds(means, inflate, GRID, y, sigma_max, basis, noise, residual=E),
        prefix_bound.fit_lower_bounds(means, inflate, GRID, y, sigma_max, basis, noise))


@pytest.mark.parametrize("normalized", [True, False])
def test_the_bound_is_exact_arithmetic_of_its_formula_at_one_probe_set(normalized):
    """|r_I|^2 / (sigma^2 + c lambda_max lambda_I) - (E + dropped) / sigma^2, written out for 8 probes; the
    basis not normalized too (its rows do not sum to 1, so lambda_I's row-sum factor counts)."""
    y, means, inflate, chol, basis, S = _problem(0, K=3, m=30, spread=3.0, normalized=normalized)
    noise, sigma_max = 0.03, float(np.linalg.eigvalsh(S)[-1])
    phases = np.array([0.25, 0.6, 1.0])
    got = prefix_bound.fit_lower_bounds(means, inflate, phases, y, sigma_max, basis, noise)
    m, D = y.shape
    N = basis.n_basis
    probes = np.unique(np.linspace(0, m - 1, 8).round().astype(int))
    E = prefix_bound.fit_residual(y, phases, basis)
    eps = N * 1e-10 * m * (1.0 if normalized else N)
    for j, f in enumerate(phases):
        Phi_I = basis.phi(np.linspace(0.0, f, m)[probes])
        lam = Phi_I.sum(axis=0).max() * Phi_I.sum(axis=1).max()
        for k in range(3):
            r = Phi_I @ means[k].reshape(D, N).T - y[probes]
            nm = np.linalg.norm(means[k])
            dropped = 2 * np.sqrt(eps) * nm * np.linalg.norm(y) + eps * nm ** 2
            expect = np.sum(r * r) / (noise + inflate[k] * sigma_max * lam) - (E[j] + dropped) / noise
            assert got[k, j] == pytest.approx(expect, rel=1e-9, abs=1e-9)


def test_prefix_candidates_keeps_every_component_that_fits_at_an_allowed_phase_and_rules_out_the_others():
    """Against the exact d2: a component is kept iff the bound allows it at one of its allowed phases (so every
    component with d2 <= threshold at an allowed phase is kept); a component allowed no phase is never kept."""
    y, means, inflate, chol, basis, S = _problem(9, K=6, m=30, spread=0.0)
    rng = np.random.default_rng(9)
    means = means + np.array([0.0, 0.05, 0.3, 3.0, 10.0, 30.0])[:, None] * rng.standard_normal(means.shape)
    noise, sigma_max = 0.03, float(np.linalg.eigvalsh(S)[-1])
    threshold = 40.0
    allowed = np.zeros((6, 20), bool)
    allowed[:, 8:16] = True
    allowed[2] = False                   # no phase allowed: never a candidate
    keep = prefix_bound.prefix_candidates(means, inflate, GRID, allowed, y, sigma_max, basis, noise, threshold)
    _, d2, _ = score_phases(y, GRID, means, inflate, chol, basis, noise)
    fits = ((d2.T <= threshold) & allowed).any(axis=1)
    assert keep[fits].all() and not keep[2]
    b3 = prefix_bound.fit_lower_bounds(means, inflate, GRID, y, sigma_max, basis, noise, n_probes=3)
    b8 = prefix_bound.fit_lower_bounds(means, inflate, GRID, y, sigma_max, basis, noise, n_probes=8)
    expect = ((b3 <= threshold) & allowed).any(axis=1) & ((b8 <= threshold) & allowed).any(axis=1)
    np.testing.assert_array_equal(keep, expect)
    assert keep[:2].all() and not keep[4:].any(), keep


def test_prefix_candidates_keeps_a_skill_whose_samples_hold_much_the_basis_cannot_span():
    """Samples of a skill plus a fast oscillation no basis function holds (fit residual E / sigma^2 in the
    hundreds): d2 leaves E out and the skill fits at every phase of its band, so the bound must subtract E at
    every allowed phase, not only at the first; the components far away are still ruled out."""
    y, means, inflate, _, basis, S = _problem(11, K=3, m=40, spread=0.0)
    S = 1e-4 * S                     # a tight skill: the bound's denominator is about sigma^2, so E must count
    chol = np.linalg.cholesky(S)
    t = np.linspace(0.0, 1.0, 40)
    wiggle = 0.8 * np.sin(2 * np.pi * 13 * t)[:, None] * np.array([1.0, -0.5, 0.8])
    y = y + wiggle
    means = means + np.array([0.0, 20.0, 40.0])[:, None]
    noise, sigma_max, threshold = 0.03, float(np.linalg.eigvalsh(S)[-1]), 60.0
    allowed = np.zeros((3, 20), bool)
    allowed[:, 5:] = True
    _, d2, _ = score_phases(y, GRID, means, inflate, chol, basis, noise)
    E = prefix_bound.fit_residual(y, GRID, basis)
    assert E[5:].min() / noise > 100.0
    fits = ((d2.T <= threshold) & allowed).any(axis=1)
    assert fits.tolist() == [True, False, False]
    keep = prefix_bound.prefix_candidates(means, inflate, GRID, allowed, y, sigma_max, basis, noise, threshold)
    assert keep.tolist() == [True, False, False]
