"""Merging (Eqs. 10-11) on the shared scale, on libraries set up by hand in an exact state.

Components are placed at chosen positions in the whitened gating space of an isotropic
shared covariance ``Sigma = g I`` (``library_states``), so every two-sample distance
``|mu_i - mu_j|^2_Sigma / (1/s_i + 1/s_j)`` is known here. A demonstration is then
folded in and the merge decision and its result are checked against numbers computed
in the test: the pooled moments of both components (support, mean, scatter, duration,
path length, age), which one is kept, the shared scale's between term.

The issue's "consolidation makes a merge harder as support grows" is, in this design,
the two-sample distance itself (the same mean difference is farther apart when both
means are better known) plus the optional ``s^beta`` of Eq. (10); both are tested.
"""
import numpy as np
import pytest
from scipy.stats import chi2, multivariate_normal

from drake_skills import LibraryConfig

import library_states as ls
from synthetic import synthetic_demo

H = 15
#: A small human-only representation; novelty at the median (so that near motions are new), merge at 0.999.
BASE = dict(n_samples=30, n_basis_human=5, n_basis_robot=5, delete_min_age=1000, novelty_quantile=0.5,
            merge_quantile=0.999, split_quantile=0.9999)
THR_MERGE = chi2.ppf(0.999, H)  # 37.7
THR_NOV = chi2.ppf(0.5, H)  # 14.3


def _setup(specs, seed=0, var=1.0, **cfg_kw):
    """Components ``(id, z, support, age)`` at whitened offsets ``z`` (H,) from a demonstration's weights.

    Returns (lib, demo, w, g) with the gating covariance g I.
    """
    cfg = LibraryConfig(**{**BASE, **cfg_kw})
    demo = synthetic_demo(0, np.random.default_rng(seed), T=30, robot=False)
    w = ls.encode(cfg, demo)
    g = ls.library(cfg, [], dim_human=3, dim_robot=0, var=var).shared_covariance()[0, 0]
    rng = np.random.default_rng(seed + 1)
    comps = [ls.component(cid, w + np.sqrt(g) * z, support=s, age=age, duration=2.0 + cid, path_length=3.0 + cid,
                          factor=0.1 * rng.standard_normal((H, 2)))
             for cid, z, s, age in specs]
    lib = ls.library(cfg, comps, dim_human=3, dim_robot=0, n_seen=10, var=var)
    return lib, demo, w, g


def _offset(d2_two_sample, s_a, s_b=1.0, seed=0):
    """A whitened offset at two-sample distance ``d2_two_sample`` between supports s_a and s_b."""
    return np.sqrt(d2_two_sample * (1.0 / s_a + 1.0 / s_b)) * ls.unit(np.random.default_rng(100 + seed), H)


# ------------------------------------------------------------------ what a merge computes
def test_a_new_component_within_the_merge_threshold_is_pooled_with_the_old_one():
    """A (support 4) at two-sample distance 0.9 * chi2_0.999(15) from a novel demonstration: the new component
    merges into A, holding the pooled moments of both (the corrected Eq. 11), and the shared scale gains the
    between-component scatter."""
    lib, demo, w, g = _setup([(0, _offset(0.9 * THR_MERGE, 4.0), 4.0, 3)])
    before = lib.state()
    a = before.components[0].cluster
    path = lib.path_length(demo.human)
    u = lib.partial_fit(demo)
    assert u.created == (1,) and u.merged == ((0, 1),) and u.recognized is None and u.updated == ()
    (c,) = lib.components
    st = lib.state()
    (cs,) = st.components
    dm = a.mean - w
    assert c.id == 0 and c.support == pytest.approx(5.0, abs=1e-12)  # the absorbed support is added
    np.testing.assert_allclose(c.mean, (4.0 * a.mean + w) / 5.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(cs.cluster.scatter, a.scatter + (4.0 / 5.0) * np.outer(dm, dm), rtol=1e-12,
                               atol=1e-12)
    assert c.duration == pytest.approx((4.0 * 2.0 + demo.duration) / 5.0, rel=1e-12)
    assert c.path_length == pytest.approx((4.0 * 3.0 + path) / 5.0, rel=1e-12)
    assert c.age == 4  # the older of the two, aged by this demonstration
    # it remembers the two it came from, as its sub-clusters
    first, second = cs.subclusters
    np.testing.assert_array_equal(first.mean, a.mean)
    assert first.support == 4.0 and second.support == 1.0
    np.testing.assert_array_equal(second.mean, w)
    assert lib.n_seen == 11
    assert lib.history[-2:] == ({"event": "created", "id": 1, "demo": 10},
                                {"event": "merged", "into": 0, "absorbed": 1, "demo": 10})
    np.testing.assert_allclose(st.scale.pooled - before.scale.pooled, (4.0 / 5.0) * np.outer(dm, dm), rtol=1e-9,
                               atol=1e-6)
    assert st.scale.dof == pytest.approx(before.scale.dof + 1.0, abs=1e-9)


@pytest.mark.parametrize("factor, merges", [(0.97, True), (1.03, False)])
def test_the_merge_threshold_is_the_chi2_quantile_of_the_two_sample_distance(factor, merges):
    """Two-sample distance |dz|^2 / (1/s_a + 1/s_new) just inside or outside chi2_0.999(15)."""
    lib, demo, _, _ = _setup([(0, _offset(factor * THR_MERGE, 2.5), 2.5, 3)])
    u = lib.partial_fit(demo)
    assert u.created == (1,)
    assert u.merged == (((0, 1),) if merges else ())
    assert lib.n_components == (1 if merges else 2)


@pytest.mark.parametrize("quantile", [0.9, 0.99999])
def test_merge_quantile_sets_the_threshold(quantile):
    thr = chi2.ppf(quantile, H)
    for factor, merges in ((0.97, True), (1.03, False)):
        lib, demo, _, _ = _setup([(0, _offset(factor * thr, 2.0), 2.0, 3)], merge_quantile=quantile,
                                 split_quantile=0.999999)
        assert bool(lib.partial_fit(demo).merged) is merges, (quantile, factor)


def test_the_component_with_the_larger_support_is_kept():
    """A (support 0.5) against the new component (1): the new one is kept and A is absorbed into it."""
    lib, demo, w, _ = _setup([(0, _offset(0.5 * THR_MERGE, 0.5), 0.5, 3)])
    a = lib.state().components[0].cluster
    u = lib.partial_fit(demo)
    assert u.merged == ((1, 0),)
    (c,) = lib.components
    assert c.id == 1 and c.support == pytest.approx(1.5, abs=1e-12) and c.age == 4
    np.testing.assert_allclose(c.mean, (0.5 * a.mean + w) / 1.5, rtol=0, atol=1e-12)
    assert lib.history[-1] == {"event": "merged", "into": 1, "absorbed": 0, "demo": 10}
    first, second = lib.state().components[0].subclusters
    assert (first.support, second.support) == (1.0, 0.5)  # the kept component's own half first


def test_on_equal_supports_the_lower_id_is_kept():
    lib, demo, _, _ = _setup([(0, _offset(0.5 * THR_MERGE, 1.0), 1.0, 3)])
    assert lib.partial_fit(demo).merged == ((0, 1),)
    # the changed component has the lower id: A (support 1, updated to 2) and B (support 2, novel for the demo)
    lib, demo, _, _ = _setup([(0, np.zeros(H), 1.0, 3), (1, np.sqrt(30.0) * ls.unit(np.random.default_rng(9), H),
                                                          2.0, 3)])
    u = lib.partial_fit(demo)
    assert u.updated == (0,) and u.merged == ((0, 1),)


# ------------------------------------------------------------------ when a merge happens
@pytest.mark.parametrize("support, merges", [(1.0, True), (50.0, False)])
def test_a_merge_gets_harder_as_support_grows(support, merges):
    """The same mean difference (|dz|^2 = 1.6 chi2_0.999): at support 1 the two-sample distance is |dz|^2 / 2
    (merges), at support 50 |dz|^2 / 1.02 (does not): better known means must be closer to merge."""
    z = np.sqrt(1.6 * THR_MERGE) * ls.unit(np.random.default_rng(7), H)
    lib, demo, _, _ = _setup([(0, z, support, 3)])
    u = lib.partial_fit(demo)
    assert u.created == (1,) and bool(u.merged) is merges


@pytest.mark.parametrize("beta, merges", [(0.0, True), (0.5, False)])
def test_consolidation_divides_the_merge_threshold_by_the_larger_support_to_the_beta(beta, merges):
    """Eq. (10): threshold chi2_0.999 / s^beta with s = 4: a pair at 0.6 of the threshold merges with beta 0 and
    not with beta 0.5 (threshold halved)."""
    lib, demo, _, _ = _setup([(0, _offset(0.6 * THR_MERGE, 4.0), 4.0, 3)], consolidation=beta)
    assert bool(lib.partial_fit(demo).merged) is merges


@pytest.mark.parametrize("beta", [0.0, 1.0])
@pytest.mark.parametrize("offset, merges", [(-0.05, True), (0.05, False)])
def test_loglik_merges_when_the_mean_difference_is_likelier_than_T_merge_s_beta(beta, offset, merges):
    """novelty_test="loglik": merge when log N(mu_i - mu_j | 0, Sigma (1/s_i + 1/s_j)) > log T_merge + beta log s
    (the log-determinant of Sigma counts: Sigma = 0.3 I, log det = -18), checked against scipy."""
    s_a = 3.0
    z = _offset(0.5 * THR_MERGE, s_a)
    lib0, demo, w, g = _setup([(0, z, s_a, 3)], var=0.3)
    mu_a = lib0.components[0].mean
    G = lib0.shared_covariance()
    log_p = multivariate_normal(np.zeros(H), G * (1.0 / s_a + 1.0)).logpdf(mu_a - w)
    log_T_merge = log_p - beta * np.log(s_a) + offset
    lib, demo, _, _ = _setup([(0, z, s_a, 3)], novelty_test="loglik", log_T_nov=1e3, log_T_merge=log_T_merge,
                             consolidation=beta, var=0.3)
    u = lib.partial_fit(demo)
    assert u.created == (1,) and bool(u.merged) is merges


@pytest.mark.parametrize("merge_min_age, merges", [(4, True), (5, False)])
def test_a_pair_is_checked_once_the_older_component_is_past_merge_min_age(merge_min_age, merges):
    """A is aged 4 before the demonstration, 5 after it: merge_min_age 4 allows the merge, 5 does not."""
    lib, demo, _, _ = _setup([(0, _offset(0.5 * THR_MERGE, 2.0), 2.0, 4)], merge_min_age=merge_min_age)
    assert bool(lib.partial_fit(demo).merged) is merges


def test_a_young_component_does_not_stop_the_merge_check_of_the_others():
    """merge_min_age 5: Y (age 1, listed first, nearest) is skipped; the old A still merges."""
    lib, demo, _, _ = _setup([(7, _offset(0.45 * THR_MERGE, 1.0, seed=1), 1.0, 1),
                              (0, _offset(0.6 * THR_MERGE, 2.0, seed=2), 2.0, 9)], merge_min_age=5)
    u = lib.partial_fit(demo)
    assert u.created == (8,) and u.merged[0] == (0, 8)


def test_an_unchanged_pair_within_the_threshold_merges():
    """A and B are within the merge threshold of each other and the demonstration leaves both alone (it creates
    a far third component): every pair is checked, as Algorithm 1 checks every component past its merge age,
    because the learned scale moves under components that did not change (a skill shown in a row fragments
    while the scale is its prior, and its fragments never change again)."""
    e = ls.unit(np.random.default_rng(3), H)
    far = 30.0 * e
    lib, demo, _, _ = _setup([(0, far, 2.0, 9), (1, far + np.sqrt(0.3 * THR_MERGE) * ls.unit(
        np.random.default_rng(4), H), 2.0, 9)])
    u = lib.partial_fit(demo)
    assert u.created == (2,) and u.merged == ((0, 1),)
    assert [c.id for c in lib.components] == [0, 2] and [c.age for c in lib.components] == [10, 1]


def test_an_unchanged_pair_beyond_the_threshold_stays_apart():
    """The same, with A and B at 1.05 of the merge threshold: both stay."""
    e = ls.unit(np.random.default_rng(3), H)
    far = 30.0 * e
    lib, demo, _, _ = _setup([(0, far, 2.0, 9), (1, far + np.sqrt(1.05 * THR_MERGE) * ls.unit(
        np.random.default_rng(4), H), 2.0, 9)])
    u = lib.partial_fit(demo)
    assert u.created == (2,) and u.merged == ()
    assert [c.age for c in lib.components] == [10, 10, 1]


def test_a_component_updated_by_the_demonstration_is_checked_against_the_others():
    """The demonstration lies on A (support 3) and updates it; B (support 1) is novel for it (d^2 20 > 14.3)
    but within the merge threshold of A (|dz|^2 / (1/4 + 1) = 32 < 37.7): found from A, which changed."""
    z_b = np.sqrt(40.0) * ls.unit(np.random.default_rng(5), H)
    lib, demo, _, _ = _setup([(0, np.zeros(H), 3.0, 9), (1, z_b, 1.0, 9)])
    u = lib.partial_fit(demo)
    assert u.updated == (0,) and u.responsibilities[1] == 0.0 and u.created == ()
    assert u.merged == ((0, 1),)
    assert lib.components[0].support == pytest.approx(5.0, abs=1e-12)


def test_the_merged_component_is_checked_again():
    """The closest pair merges first (A and B: |dz|^2 / (1/4 + 1) = 12.8, against A and the new component at half
    the threshold); the merged A has changed and is checked against the new component, which it then absorbs
    too."""
    e1, e2 = np.eye(H)[0], np.eye(H)[1]
    lib, demo, _, _ = _setup([(0, np.sqrt(0.5 * THR_MERGE * 1.25) * e1, 4.0, 9),
                              (1, np.sqrt(0.5 * THR_MERGE * 1.25) * e1 + 4.0 * e2, 1.0, 9)])
    u = lib.partial_fit(demo)
    assert u.created == (2,)
    assert u.merged == ((0, 1), (0, 2))
    assert [c.id for c in lib.components] == [0]
    assert lib.components[0].support == pytest.approx(6.0, abs=1e-12)


@pytest.mark.parametrize("novelty_test", ["chi2", "loglik"])
def test_the_best_pair_merges_first_however_deep_inside_the_threshold(novelty_test):
    """The new component has A (listed first, 0.9 of the threshold) and B (0.45) as candidates; B, the nearer,
    is absorbed first. With loglik and log T_merge = -1000 both lie hundreds of nats inside the threshold
    (a score clipped at exp(-50) made them tie and the first listed merge)."""
    kw = dict(novelty_test="loglik", log_T_nov=1e3, log_T_merge=-1000.0) if novelty_test == "loglik" else {}
    lib, demo, _, _ = _setup([(0, _offset(0.9 * THR_MERGE, 2.0, seed=1), 2.0, 9),
                              (1, _offset(0.45 * THR_MERGE, 2.0, seed=2), 2.0, 9)], **kw)
    u = lib.partial_fit(demo)
    assert u.created == (2,) and u.merged[0] == (1, 2)


def test_the_best_pair_is_compared_across_the_changed_components():
    """The demonstration updates A (id 0) and C (id 2), supports 30 (too sure of themselves to merge with each
    other). A's candidate B lies at 0.77 of the threshold, C's candidate D at 0.92: A's pair, found first, is
    the better one and merges first; then C absorbs D."""
    e1, e3 = np.eye(H)[0], np.eye(H)[2]
    lib, demo, _, _ = _setup([(0, np.zeros(H), 30.0, 9), (1, -np.sqrt(30.0) * e1, 1.0, 9),
                              (2, 3.0 * e1, 30.0, 9), (3, 3.0 * e1 + 6.0 * e3, 1.0, 9)])
    u = lib.partial_fit(demo)
    assert u.updated == (0, 2) and u.created == ()
    assert u.merged == ((0, 1), (2, 3))


@pytest.mark.parametrize("offset, merges", [(-0.05, True), (0.05, False)])
def test_loglik_merge_of_an_updated_component_uses_both_supports(offset, merges):
    """A (support 3, on the demonstration) is updated to support 4; B (support 1) is novel for the demonstration.
    The pair merges when log N(mu_B - mu_A | 0, Sigma (1/4 + 1/1)) > log T_merge."""
    z_b = np.sqrt(40.0) * ls.unit(np.random.default_rng(5), H)
    lib0, demo, w, g = _setup([(0, np.zeros(H), 3.0, 9), (1, z_b, 1.0, 9)], var=0.3)
    delta = lib0.components[1].mean - w
    log_p = multivariate_normal(np.zeros(H), lib0.shared_covariance() * 1.25).logpdf(delta)
    rec = lib0.recognize(demo.human, observed_fraction=1.0)
    log_T_nov = 0.5 * (rec.log_likelihoods[0] + rec.log_likelihoods[1])  # A explains it, B does not
    lib, demo, _, _ = _setup([(0, np.zeros(H), 3.0, 9), (1, z_b, 1.0, 9)], var=0.3, novelty_test="loglik",
                             log_T_nov=log_T_nov, log_T_merge=log_p + offset)
    u = lib.partial_fit(demo)
    assert u.updated == (0,) and u.responsibilities[1] == 0.0
    assert bool(u.merged) is merges


def test_distance_shrink_bounds_how_far_any_squared_distance_can_shrink():
    """For random pairs of covariances (near and far apart) and random vectors: |x|^2_new >= f |x|^2_old, and f is
    within a factor h of the exact smallest generalized eigenvalue (tight, 1 +- 1e-12, when the metric is the
    same); no old metric gives 0."""
    from drake_skills.library.algorithm import Metric, distance_shrink

    rng = np.random.default_rng(0)
    h = 7
    assert distance_shrink(None, Metric.of(np.eye(h))) == 0.0
    for step in (1e-3, 0.1, 1.0):
        for _ in range(20):
            A = rng.normal(size=(h, h))
            old = A @ A.T + h * np.eye(h)
            B = rng.normal(size=(h, h)) * step
            new = old + B @ B.T - step * np.diag(rng.uniform(0, 1, h))
            new = 0.5 * (new + new.T) + 1e-3 * np.eye(h)
            m_old, m_new = Metric.of(old), Metric.of(new)
            f = distance_shrink(m_old.inv_chol, m_new)
            X = rng.normal(size=(200, h))
            d_old = np.einsum("ij,ij->i", m_old.whiten(X), m_old.whiten(X))
            d_new = np.einsum("ij,ij->i", m_new.whiten(X), m_new.whiten(X))
            assert np.all(d_new >= f * d_old)
            exact = np.linalg.eigvalsh(np.linalg.solve(m_new.chol, m_old.chol) @ np.linalg.solve(
                m_new.chol, m_old.chol).T).min()
            assert exact / h <= f <= exact * (1 + 1e-12)
    m = Metric.of(old)
    assert distance_shrink(m.inv_chol, m) == pytest.approx(1.0, abs=2e-9)


def test_a_young_unchanged_pair_merges_once_past_merge_min_age_in_a_later_step():
    """A and B (age 1) lie at half the merge threshold; merge_min_age 3 holds them apart for two updates that only
    touch a far component C; on the third they merge though neither changed (their bounds were carried, not
    recomputed; a cold review's test)."""
    far = 30.0 * ls.unit(np.random.default_rng(3), H)
    lib, demo, _, _ = _setup([(0, far, 1.0, 1), (1, far + _offset(0.5 * THR_MERGE, 1.0, 1.0), 1.0, 1),
                              (2, np.zeros(H), 4.0, 9)], merge_min_age=3)
    merged = [lib.partial_fit(demo).merged for _ in range(3)]
    assert merged == [(), (), ((0, 1),)], merged


def test_with_consolidation_a_pair_of_small_supports_is_not_ruled_out_by_the_largest_supports_threshold():
    """beta 0.5: A and B (support 1, threshold q) at half of q; C has support 16 (its threshold q/4). merge_min_age
    keeps A and B apart for two updates of C; on the third they merge: the merge limit is the smallest support's
    threshold, not the largest's (a cold review's test)."""
    far = 30.0 * ls.unit(np.random.default_rng(3), H)
    lib, demo, _, _ = _setup([(0, far, 1.0, 1), (1, far + _offset(0.5 * THR_MERGE, 1.0, 1.0), 1.0, 1),
                              (2, np.zeros(H), 16.0, 9)], merge_min_age=3, consolidation=0.5)
    merged = [lib.partial_fit(demo).merged for _ in range(3)]
    assert merged == [(), (), ((0, 1),)], merged


@pytest.mark.parametrize("beta", [0.0, 0.5])
@pytest.mark.parametrize("novelty_test", ["chi2", "loglik"])
def test_the_merge_limit_is_a_distance_no_pair_of_these_supports_merges_at(novelty_test, beta):
    """Random supports (some below 1, as soft responsibilities leave them) and log-determinants: no pair of the
    supports merges at the limit (sound), and it is tight: at 0.999 of it the pair it is computed for merges (chi2:
    the smallest support; loglik: the smallest support's threshold with the largest support's inflation)."""
    from drake_skills.library.novelty import novelty_rule

    kw = dict(novelty_test="loglik", log_T_nov=1e3, log_T_merge=-40.0) if novelty_test == "loglik" else {}
    rule = novelty_rule(LibraryConfig(consolidation=beta, **kw))
    rng = np.random.default_rng(0)
    for _ in range(50):
        s = rng.uniform(0.3, 20.0, size=6)
        logdet = float(rng.normal(0.0, 10.0))
        limit = rule.merge_limit(s, logdet, H)
        pairs = [(a, b) for a in range(6) for b in range(6) if a != b]
        larger = np.array([max(s[a], s[b]) for a, b in pairs])
        inflate = np.array([1 / s[a] + 1 / s[b] for a, b in pairs])
        assert np.all(rule.merge_scores(np.full(len(pairs), limit), larger, inflate, logdet, H) >= -1e-9)
        near = rule.merge_scores(np.array([0.999 * limit]), np.array([s.min()]), np.array([2.0 / s.max()]), logdet, H)
        assert near[0] < 0.0


def test_of_equal_merge_scores_the_pair_of_lowest_ids_merges_whichever_row_finds_it():
    """A stale bound can leave a pair to be found only from its other component's row (here component 0's partner
    is a split half, new in this update). Two pairs at distance 0 tie: the library merges the one of lowest ids, as
    the reference that scores every pair, and a copy made by from_state after the first update (its bounds
    rebuilt) goes on alike (a cold review's construction)."""
    from brute_force import Reference
    from drake_skills import SkillLibrary
    from drake_skills.library.novelty import novelty_rule
    from drake_skills.library.scale import Cluster
    from drake_skills.library.state import ComponentState

    cfg = LibraryConfig(**{**BASE, "merge_min_age": 2})
    demo = synthetic_demo(0, np.random.default_rng(0), T=30, robot=False)
    w = ls.encode(cfg, demo)
    g = ls.library(cfg, [], dim_human=3, dim_robot=0).shared_covariance()[0, 0]
    u = [ls.unit(np.random.default_rng(k), H) for k in range(10, 14)]
    far_a = w + np.sqrt(g) * 40.0 * u[0]
    s1 = Cluster(1.0, far_a - np.sqrt(g) * 20.0 * u[1], np.zeros((H, 0)), 2.0, 3.0)  # X's first half
    s2 = Cluster(1.0, far_a, np.zeros((H, 0)), 2.0, 3.0)  # X's second half, exactly at A
    X, _ = s1.pool(s2)
    cd = w + np.sqrt(g) * 40.0 * u[2]
    comps = [ls.component(0, far_a, age=9),  # A
             ls.component(1, cd, age=1), ls.component(2, cd.copy(), age=1),  # C, D: identical, young
             ComponentState(3, 9, X, (s1, s2)),  # X: splits in the first update
             ls.component(4, w, support=4.0, age=9)]  # E: the demonstration updates it
    lib = ls.library(cfg, comps, dim_human=3, dim_robot=0, n_seen=10)
    ref = Reference(lib.config, novelty_rule(lib.config), H)
    ref.items, ref.scale, ref.next_id, ref.n_seen = list(lib._components.items), lib._scale, 5, 10
    path, y = lib.path_length(demo.human), lib.human_samples(demo.human)
    fit = lib.config.basis_human.phi_uniform(y.shape[0]) @ w[:H].reshape(3, -1).T
    res = float(np.mean((y - fit) ** 2))
    merged = []
    for step in range(2):
        expect = ref.partial_fit(w, demo.duration, path, res, demo.task)
        got = lib.partial_fit(demo)
        assert got.merged == expect["merged"] and got.split == expect["split"], step
        merged.append(got.merged)
        if step == 0:
            copy = SkillLibrary.from_state(lib.state())
        else:
            assert copy.partial_fit(demo).merged == got.merged
    assert merged == [(), ((0, 5), (1, 2))]  # the tie happened, with the split half (id 5) first
