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
from drake_skills.promp.interaction import SEEN_RCOND, prefix_statistics

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
        np.testing.assert_allclose(got[1], ref[1], rtol=1e-9, atol=1e-9)      # 2e-13 seen
        np.testing.assert_array_equal(got[2], ref[2])
    if cached:
        assert set(cache) == {"gram", "fit"}
        for kind in ("gram", "fit"):
            assert set(cache[kind]["stacked"]) == {((0.05, 0.3, 0.65, 1.0), y.shape[0]), ((0.1, 0.3, 0.95), y.shape[0])}
            assert set(cache[kind]["phase"]) == {(f, y.shape[0]) for f in (0.05, 0.3, 0.65, 1.0, 0.1, 0.95)}


@pytest.mark.parametrize("case", CASES, ids=[str(i) for i in range(len(CASES))])
def test_score_component_equals_prefix_statistics_for_each_sample_set_and_phase(case):
    """One component, two sample sets at once (the record of beginnings): log-likelihood and fit statistic rtol 1e-9
    against the reference, the degrees of freedom exactly; the phases see different numbers of directions."""
    y, means, inflate, chol, basis, S = _problem(**case)
    rng = np.random.default_rng(case["seed"] + 100)
    ys = np.stack([y, y + rng.normal(0.0, 0.1, y.shape)])
    phases = (0.05, 0.3, 0.65, 1.0)
    for k in range(means.shape[0]):
        got = prefix.score_component(ys, phases, means[k], inflate[k], chol, basis, 0.03)
        for b in range(2):
            ref = _reference(ys[b], phases, means[[k]], inflate[[k]], S, basis, 0.03)[:, :, 0]
            np.testing.assert_allclose(got[0][b], ref[0], rtol=1e-9, atol=1e-8)
            np.testing.assert_allclose(got[1][b], ref[1], rtol=1e-9, atol=1e-9)
            np.testing.assert_array_equal(got[2][b], ref[2])


def test_score_component_falls_back_to_score_phases_where_a_factorization_fails():
    """A covariance 1e6 times too large against a noise of 1e-12 (three samples, seven basis functions): rounding
    leaves the matrices short of positive definite; the answer is score_phases' column (eigenvalues clipped at 0),
    not an error."""
    y, means, inflate, chol, basis, S = _problem(2, N=7, m=3)
    chol, phases = 1e3 * chol, (0.05, 0.3)
    with pytest.raises(np.linalg.LinAlgError):          # the direct route cannot take this case
        prefix._score_component(y[None], phases, means[0], inflate[0], chol, basis, 1e-12)
    got = prefix.score_component(y[None], phases, means[0], inflate[0], chol, basis, 1e-12)
    ref = score_phases(y, phases, means[[0]], inflate[[0]], chol, basis, 1e-12)
    for a, b in zip(got, ref):
        np.testing.assert_array_equal(a, b[:, 0][None])


def test_the_degrees_of_freedom_are_d_times_the_directions_the_samples_see_well():
    """Five samples of a 7-function basis: per dimension, the eigenvalues of Phi^T Phi at least SEEN_RCOND of the
    largest; the same for every component (the prior does not choose them); a 5 % beginning sees two directions."""
    y, means, inflate, chol, basis, _ = _problem(2, N=7, m=5)
    _, _, dof = score_phases(y, (0.05, 1.0), means, inflate, chol, basis, 0.03)
    for j, f in enumerate((0.05, 1.0)):
        g = np.linalg.eigvalsh(basis.phi(np.linspace(0, f, 5)).T @ basis.phi(np.linspace(0, f, 5)))
        assert dof[j].tolist() == [3.0 * np.sum(g >= SEEN_RCOND * g[-1])] * 4
    assert dof[0, 0] == 6 and 6 < dof[1, 0] <= 15


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
def _terms(y, f, mean, chol, basis, rcond=SEEN_RCOND):
    """The fit statistic's coordinates with explicit matrices: prior variances gamma (ascending, per unit c) and
    v = R^T (I (x) g^-1/2 V^T) H r for the seen eigenvectors V of Phi^T Phi, B = Vg^T Sigma Vg = R diag(gamma) R^T."""
    m, D = y.shape
    Phi = basis.phi(np.linspace(0.0, f, m))
    g, V = np.linalg.eigh(Phi.T @ Phi)
    keep = g >= rcond * g[-1]
    g, V = g[keep], V[:, keep]
    HT = np.kron(np.eye(D), Phi)
    r = y.T.reshape(-1) - HT @ mean
    x = np.kron(np.eye(D), V / np.sqrt(g)).T @ HT.T @ r
    Vg = np.kron(np.eye(D), V * np.sqrt(g))
    gam, R = np.linalg.eigh(Vg.T @ chol @ chol.T @ Vg)
    return gam, R.T @ x


@pytest.mark.parametrize("case", CASES, ids=[str(i) for i in range(len(CASES))])
def test_the_lower_bound_lies_below_the_exact_fit_statistic_and_equals_it_over_all_directions(case):
    """Every component, every phase: bound <= d2 (up to 1e-6 relative) with 4 coordinates, bound == d2 (rtol 1e-6)
    with all h of them, and the dof are score_phases' exactly; the 4-coordinate bound rules out, at some phase, most
    components (spread 4 around the samples' weights) whose exact d2 exceeds twice its threshold there."""
    from drake_skills.library.novelty import chi2_ppf

    y, means, inflate, chol, basis, S = _problem(**case, spread=4.0)
    noise = 0.03
    _, d2, dof = score_phases(y, GRID, means, inflate, chol, basis, noise)
    bound, bdof = prefix_bound.fit_lower_bounds(y, GRID, means, inflate, chol, basis, noise)
    assert bound.shape == bdof.shape == (means.shape[0], 20)
    assert (bound <= d2.T + 1e-6 * (1 + d2.T)).all(), np.max(bound - d2.T)
    np.testing.assert_array_equal(bdof, dof.T)
    full, _ = prefix_bound.fit_lower_bounds(y, GRID, means, inflate, chol, basis, noise, n_directions=chol.shape[0])
    np.testing.assert_allclose(full, d2.T, rtol=1e-6, atol=1e-6 * (1 + d2.max()))
    thr = chi2_ppf(0.999, dof.T)
    far = (d2.T > 2 * thr).any(axis=1)
    assert far.sum() >= 1 and (bound > thr).any(axis=1)[far].mean() >= 0.75, (far, (bound > thr).any(axis=1))


@pytest.mark.parametrize("cached", [False, True])
def test_the_bound_is_the_mahalanobis_distance_of_the_best_seen_directions(cached):
    """x_S^T (sigma^2 I + c Vg_S^T Sigma Vg_S)^-1 x_S over the n best-seen eigenvectors V_S of Phi^T Phi per dimension,
    x_S = (I (x) g_S^-1/2 V_S^T) H r, written out with explicit matrices (n = 1, 2; with 7, all the seen ones: d2)."""
    y, means, inflate, chol, basis, S = _problem(0, K=3, m=30, spread=3.0)
    phases = (0.1, 0.6, 1.0)
    cache = {} if cached else None
    noise = 0.03
    m, D = y.shape
    for n in (1, 2, 7):
        got, _ = prefix_bound.fit_lower_bounds(y, phases, means, inflate, chol, basis, noise, cache, n_directions=n)
        for j, f in enumerate(phases):
            Phi = basis.phi(np.linspace(0.0, f, m))
            g, V = np.linalg.eigh(Phi.T @ Phi)
            keep = np.flatnonzero(g >= SEEN_RCOND * g[-1])[-n:]
            HT = np.kron(np.eye(D), Phi)
            Vs = np.kron(np.eye(D), V[:, keep] / np.sqrt(g[keep]))
            Vg = np.kron(np.eye(D), V[:, keep] * np.sqrt(g[keep]))
            for k in range(3):
                x = Vs.T @ HT.T @ (y.T.reshape(-1) - HT @ means[k])
                C = noise * np.eye(x.size) + inflate[k] * Vg.T @ S @ Vg
                assert got[k, j] == pytest.approx(float(x @ np.linalg.solve(C, x)), rel=1e-8, abs=1e-9)
    _, d2, _ = score_phases(y, phases, means, inflate, chol, basis, noise)
    np.testing.assert_allclose(got, d2.T, rtol=1e-8, atol=1e-9)                        # n = 7: every seen direction
    counts = [np.sum(np.linalg.eigvalsh(basis.phi(np.linspace(0, f, m)).T @ basis.phi(np.linspace(0, f, m)))
                     >= SEEN_RCOND * np.linalg.eigvalsh(basis.phi(np.linspace(0, f, m)).T @ basis.phi(
                         np.linspace(0, f, m)))[-1]) for f in phases]
    assert min(counts) <= 2 < max(counts)                                               # fewer and more than n


def test_prefix_candidates_keeps_every_component_that_fits_at_an_allowed_phase_and_rules_out_the_others():
    """Against the exact d2: a component is kept iff the bound allows it (bound <= the chi-square quantile at its
    dof) at one of its allowed phases, so every component with d2 within the quantile at an allowed phase is
    kept; a component allowed no phase is never kept; the ones far away are ruled out."""
    from drake_skills.library.novelty import chi2_ppf

    y, means, inflate, chol, basis, S = _problem(9, K=6, m=30, spread=0.0)
    rng = np.random.default_rng(9)
    means = means + np.array([0.0, 0.05, 0.3, 3.0, 10.0, 30.0])[:, None] * rng.standard_normal(means.shape)
    noise = 0.03
    allowed = np.zeros((6, 20), bool)
    allowed[:, 8:16] = True
    allowed[2] = False                   # no phase allowed: never a candidate
    keep = prefix_bound.prefix_candidates(y, GRID, allowed, means, inflate, chol, basis, noise, 0.999)
    _, d2, dof = score_phases(y, GRID, means, inflate, chol, basis, noise)
    fits = ((d2.T <= chi2_ppf(0.999, dof.T)) & allowed).any(axis=1)
    assert keep[fits].all() and not keep[2]
    bound, bdof = prefix_bound.fit_lower_bounds(y, GRID[8:16], means, inflate, chol, basis, noise)
    expect = ((bound <= chi2_ppf(0.999, bdof)) & allowed[:, 8:16]).any(axis=1)
    np.testing.assert_array_equal(keep, expect)
    assert keep[:2].all() and not keep[4:].any(), keep
    none = prefix_bound.prefix_candidates(y, GRID, np.zeros((6, 20), bool), means, inflate, chol, basis, noise, 0.999)
    assert none.dtype == bool and none.shape == (6,) and not none.any()


def test_the_bound_and_the_scores_share_the_callers_cache():
    """prefix_candidates, fit_lower_bounds, score_prefix and score_at_phase keep their decompositions in the cache
    passed (the library's, emptied when it learns; the bound's beside the statistic's): the per-phase maps once,
    the stacked set reused as is."""
    y, means, inflate, chol, basis, S = _problem(9, K=3, m=30)
    allowed = np.zeros((3, 20), bool)
    allowed[:, 8:12] = True
    cache: dict = {}
    prefix_bound.prefix_candidates(y, GRID, allowed, means, inflate, chol, basis, 0.03, 0.999, cache)
    assert set(cache["fit2"]["phase"]) == {(f, 30) for f in GRID[8:12]}
    score_phases(y, tuple(GRID[8:12]), means, inflate, chol, basis, 0.03, cache)
    first = prefix.fit_terms(basis, tuple(GRID[8:12]), 30, chol, 3, cache)
    again = prefix.fit_terms(basis, tuple(GRID[8:12]), 30, chol, 3, cache)
    assert all(a is b for a, b in zip(first, again))             # the stacked entry, not a new stack
    cache2: dict = {}
    prefix_bound.fit_lower_bounds(y, (0.4,), means, inflate, chol, basis, 0.03, cache2)
    assert set(cache2["fit2"]["phase"]) == {(0.4, 30)}
    cache3: dict = {}
    score_prefix(y, np.array([0.5, 0.5, 0.5]), means, inflate, chol, basis, 0.03, cache3)
    score_at_phase(y, 0.95, means, inflate, chol, basis, 0.03, cache3)
    assert (0.95, 30) in cache3["gram"]["phase"] and (0.5, 30) in cache3["fit"]["phase"]


@pytest.mark.parametrize("excess, kept", [(1e-9, True), (1e-3, False)])
def test_prefix_candidates_allows_for_rounding_at_the_threshold(excess, kept):
    """One dimension at phase 0.2 sees 2 directions, so the bound (2 per dimension) is the exact statistic: samples
    moved along the coordinate of largest prior variance until d2 is the threshold times (1 + excess): kept at 1e-9 above
    it (the bound, computed by other products, may round above d2 by far less than 1e-6 relative), ruled out at
    1e-3 above."""
    from drake_skills.library.novelty import chi2_ppf

    y, means, inflate, chol, basis, S = _problem(3, D=1, N=6, K=1, m=20, spread=0.0)
    y = basis.phi(np.linspace(0.0, 0.2, 20)) @ means[0][:, None]     # on the mean: every coordinate 0
    noise = 0.03
    allowed = np.zeros((1, 20), bool)
    allowed[0, 3] = True                 # phase 0.2
    _, _, dof = score_phases(y, (0.2,), means, inflate, chol, basis, noise)
    assert dof[0, 0] == prefix_bound.N_DIRECTIONS == 2
    thr = chi2_ppf(0.999, dof[0, 0])
    gam, v = _terms(y, 0.2, means[0], chol, basis)
    rest = np.sum(v[:-1] ** 2 / (noise + inflate[0] * gam[:-1]))
    assert np.abs(v).max() < 1e-9
    # the gradient of the top coordinate with respect to the samples (linear in them; orthogonal to the others')
    dy = np.array([_terms(y + e[:, None], 0.2, means[0], chol, basis)[1][-1] - v[-1] for e in np.eye(20)])
    target = thr * (1 + excess)
    t = np.sqrt((target - rest) * (noise + inflate[0] * gam[-1])) - v[-1]
    y2 = y + (t * dy / (dy @ dy))[:, None]
    _, d2, _ = score_phases(y2, (0.2,), means, inflate, chol, basis, noise)
    assert d2[0, 0] == pytest.approx(target, rel=1e-10)
    assert prefix_bound.prefix_candidates(y2, GRID, allowed, means, inflate, chol, basis, noise, 0.999).tolist() \
        == [kept]


def test_prefix_candidates_keeps_a_tight_skill_whose_samples_hold_much_the_basis_cannot_span():
    """Samples of a skill far tighter than the noise (Sigma 1e-4 of the problem's) plus a fast oscillation no basis
    function holds: the statistic leaves the oscillation out and the skill fits, so the bound keeps it; the
    components 20 and 40 away are ruled out (a statistic over the directions where the prior's variance exceeds the
    noise's would test nothing here and keep all three)."""
    from drake_skills.library.novelty import chi2_ppf

    y, means, inflate, _, basis, S = _problem(11, K=3, m=40, spread=0.0)
    S = 1e-4 * S
    chol = np.linalg.cholesky(S)
    t = np.linspace(0.0, 1.0, 40)
    y = y + 0.8 * np.sin(2 * np.pi * 13 * t)[:, None] * np.array([1.0, -0.5, 0.8])
    means = means + np.array([0.0, 20.0, 40.0])[:, None]
    noise = 0.03
    allowed = np.zeros((3, 20), bool)
    allowed[:, 5:] = True
    _, d2, dof = score_phases(y, GRID, means, inflate, chol, basis, noise)
    fits = ((d2.T <= chi2_ppf(0.999, dof.T)) & allowed).any(axis=1)
    assert fits.tolist() == [True, False, False]
    keep = prefix_bound.prefix_candidates(y, GRID, allowed, means, inflate, chol, basis, noise, 0.999)
    assert keep.tolist() == [True, False, False]


def test_the_per_phase_cache_computes_each_phase_once_and_hands_out_read_only_arrays():
    """A second phase set sharing phases with the first asks only for the new ones; what the cache hands out cannot
    be written (a caller's in-place change would corrupt every later recognition)."""
    y, means, inflate, chol, basis, S = _problem(9, K=2, m=20)
    asked = []

    def compute(fs):
        asked.append(fs)
        return prefix._fit_terms(basis, fs, 20, chol, 3)

    cache: dict = {}
    first = prefix._per_phase(cache, "fit", (0.2, 0.4), 20, compute)
    prefix._per_phase(cache, "fit", (0.4, 0.6), 20, compute)
    assert asked == [(0.2, 0.4), (0.6,)]
    for a in first + prefix._fit_terms(basis, (0.3,), 20, chol, 3):
        assert not a.flags.writeable
