"""Merging (Eqs. 10-11) on libraries set up in an exact state through a hand-written library file.

Each test writes components with chosen means, covariances, supports and ages
(``library_files``), loads them with the public ``SkillLibrary.load`` and folds in
one demonstration, so the merge decision and its result can be checked against
numbers computed here, independently of the library's code.
"""
import numpy as np
import pytest
from scipy.stats import chi2, multivariate_normal

from drake_skills import LibraryConfig, SkillLibrary

import library_files as lf
from synthetic import synthetic_demo

#: A small representation (15 human + 35 robot weights) keeps the tests fast.
SMALL = dict(n_samples=30, n_basis_human=5, n_basis_robot=5, delete_min_age=1000)


def _unit(rng, n):
    u = rng.standard_normal(n)
    return u / np.linalg.norm(u)


def _spd(rng, d, scale):
    A = rng.standard_normal((d, d))
    return scale * (A @ A.T / d + 0.5 * np.eye(d))


def _pool(parts):
    """Moment-matched Gaussian of support-weighted Gaussians, from the second moments (not merge_moments)."""
    s = sum(p[0] for p in parts)
    mu = sum(p[0] * p[1] for p in parts) / s
    second = sum(p[0] * (p[2] + np.outer(p[1], p[1])) for p in parts) / s
    return s, mu, second - np.outer(mu, mu)


# --------------------------------------------------------------------- what a merge computes
@pytest.fixture
def absorbing_setup(tmp_path):
    """One old component A that is tight (cov ~1e-3, floor 0.01) and a demonstration whose weights lie
    sqrt(2) from A's mean: novel for A (d^2 ~ 180 > chi2_0.999(15) = 37.7), so it creates C with the wide
    Sigma_init (1.0 + floor), under which A's mean is close (d^2 ~ 2 < chi2_0.5(15) = 14.3): C merges
    with A in the same update."""
    cfg = LibraryConfig(**SMALL, sigma_init_human=1.0, sigma_init_robot=0.2, gating_floor=0.01, merge_min_age=0)
    rng = np.random.default_rng(0)
    demo = synthetic_demo(0, rng, T=30)
    w = lf.encode(cfg, demo)
    h, d = 15, w.shape[0]
    mean_a = w.copy()
    mean_a[:h] += np.sqrt(2.0) * _unit(rng, h)
    mean_a[h:] += 0.1 * rng.standard_normal(d - h)
    cov_a = _spd(rng, d, 1e-3)

    def load(support_a):
        a = lf.component(0, mean_a, cov_a, support=support_a, age=3, duration=2.0)
        path = lf.write_library(tmp_path / f"a{support_a}.npz", cfg, [a], dim_human=3, dim_robot=7, n_seen=7)
        return SkillLibrary.load(path)

    sigma_init = np.diag(np.r_[np.full(h, 1.0), np.full(d - h, 0.04)])
    return cfg, demo, w, mean_a, cov_a, sigma_init, load


def test_merge_pools_moments_supports_and_durations_of_both_components(absorbing_setup):
    cfg, demo, w, mean_a, cov_a, sigma_init, load = absorbing_setup
    lib = load(4.0)
    u = lib.partial_fit(demo)
    assert u.created == (1,) and u.merged == ((0, 1),) and u.recognized is None
    assert [c.id for c in lib.components] == [0]
    c = lib.components[0]
    s, mu, S = _pool([(4.0, mean_a, cov_a), (1.0, w, sigma_init)])
    assert c.support == pytest.approx(5.0, abs=1e-12)  # the absorbed support is added
    np.testing.assert_allclose(c.mean, mu, rtol=0, atol=1e-12)
    np.testing.assert_allclose(c.cov, S, rtol=0, atol=1e-12)
    assert c.duration == pytest.approx((4.0 * 2.0 + demo.duration) / 5.0, rel=1e-12)
    assert c.age == 4  # the older of the two: A aged by this demonstration
    assert lib.n_seen == 8
    assert lib.history[-2:] == ({"event": "created", "id": 1, "demo": 7},
                                {"event": "merged", "into": 0, "absorbed": 1, "demo": 7})


def test_merged_component_is_evaluated_with_its_new_covariance(absorbing_setup):
    """After the merge the gating uses the pooled covariance (plus the floor), not A's old factor."""
    cfg, demo, w, mean_a, cov_a, sigma_init, load = absorbing_setup
    lib = load(4.0)
    lib.partial_fit(demo)
    c = lib.components[0]
    h = lib.n_human
    rec = lib.recognize(demo.human)
    ref = multivariate_normal(c.mean[:h], c.cov[:h, :h] + cfg.gating_floor * np.eye(h)).logpdf(w[:h])
    assert rec.log_likelihoods[0] == pytest.approx(ref, rel=1e-9)
    assert rec.component == 0


def test_merge_keeps_the_component_with_the_larger_support(absorbing_setup):
    """With A's support 0.5 < 1 the new component survives and A is absorbed into it."""
    cfg, demo, w, mean_a, cov_a, sigma_init, load = absorbing_setup
    lib = load(0.5)
    u = lib.partial_fit(demo)
    assert u.merged == ((1, 0),)
    assert [c.id for c in lib.components] == [1]
    s, mu, S = _pool([(1.0, w, sigma_init), (0.5, mean_a, cov_a)])
    c = lib.components[0]
    assert c.support == pytest.approx(1.5, abs=1e-12)
    np.testing.assert_allclose(c.mean, mu, rtol=0, atol=1e-12)
    np.testing.assert_allclose(c.cov, S, rtol=0, atol=1e-12)
    assert c.age == 4
    assert lib.history[-1] == {"event": "merged", "into": 1, "absorbed": 0, "demo": 7}


def test_merge_on_equal_supports_keeps_the_component_the_other_was_tested_against(absorbing_setup):
    """A tie (support 1 each): A's mean was tested under the new component's Gaussian, so the new one is kept.
    (Pinned so that a change of the rule is a decision; see the report of issue 20.)"""
    cfg, demo, w, mean_a, cov_a, sigma_init, load = absorbing_setup
    lib = load(1.0)
    assert lib.partial_fit(demo).merged == ((1, 0),)


# --------------------------------------------------------------------- when a merge happens
def _two_close(tmp_path, *, support, consolidation, novelty_test, log_T_merge=-20.0, ages=10,
               cov_b_scale=1e-4, merge_min_age=5):
    """Components A (at the demonstration's weights) and B (1.0 away), human only, floor 0.25.

    The gating covariance is ~0.25 I for both, so d^2(mu_B | A) = d^2(mu_A | B) ~ 4 and
    log p(mu_B | A) = log N(1.0 | 0, 0.25 I_15) ~ -5.4 (logdet -20.8: far from 0, so it matters).
    The demonstration updates A (responsibility 0.88) and B (0.12), so both count as changed.
    """
    cfg = LibraryConfig(**SMALL, gating_floor=0.25, consolidation=consolidation, novelty_test=novelty_test,
                        log_T_merge=log_T_merge, merge_min_age=merge_min_age)
    rng = np.random.default_rng(1)
    demo = synthetic_demo(0, rng, T=30, robot=False)
    w = lf.encode(cfg, demo)
    h = w.shape[0]
    mean_b = w + 1.0 * _unit(rng, h)
    comps = [lf.component(0, w, 1e-4 * np.eye(h), support=support, age=ages),
             lf.component(1, mean_b, cov_b_scale * np.eye(h), support=support, age=ages)]
    lib = SkillLibrary.load(lf.write_library(tmp_path / "two.npz", cfg, comps, dim_human=3, dim_robot=0))
    log_p_pair = multivariate_normal(w, (1e-4 + 0.25) * np.eye(h)).logpdf(mean_b)
    return lib, demo, log_p_pair


def test_two_close_components_are_at_the_designed_distance(tmp_path):
    """The geometry the consolidation tests rely on (so that their margins are real)."""
    lib, demo, log_p_pair = _two_close(tmp_path, support=2.0, consolidation=0.5, novelty_test="chi2")
    c0, c1 = lib.components
    d2 = np.sum((c1.mean - c0.mean) ** 2) / 0.2501
    assert d2 == pytest.approx(4.0, rel=1e-3)
    assert log_p_pair == pytest.approx(-0.5 * (15 * np.log(2 * np.pi * 0.2501) + d2), rel=1e-9)
    assert lib.recognize(demo.human).component == 0


@pytest.mark.parametrize("support, consolidation, merges", [
    (2.0, 0.5, True),    # threshold chi2_0.5(15) / 2^0.5 = 10.1 > d^2 ~ 4
    (50.0, 0.5, False),  # threshold 14.3 / 50^0.5 = 2.0 < d^2 ~ 4: a consolidated component does not merge
    (50.0, 0.0, True),   # without consolidation support does not matter
])
def test_consolidation_makes_merging_harder_as_support_grows_chi2(tmp_path, support, consolidation, merges):
    lib, demo, _ = _two_close(tmp_path, support=support, consolidation=consolidation, novelty_test="chi2")
    assert bool(lib.partial_fit(demo).merged) == merges
    assert lib.n_components == (1 if merges else 2)


@pytest.mark.parametrize("support, consolidation, merges", [
    (2.0, 1.0, True),    # log T_merge + log 2 = log p - 1.6 < log p
    (50.0, 1.0, False),  # log T_merge + log 50 = log p + 1.6 > log p
    (50.0, 0.0, True),
])
def test_consolidation_makes_merging_harder_as_support_grows_loglik(tmp_path, support, consolidation, merges):
    """Eq. (10) in the log domain: merge when log p(mu_j | i) > log T_merge + beta log s_i."""
    _, _, log_p_pair = _two_close(tmp_path, support=support, consolidation=consolidation, novelty_test="chi2")
    log_T_merge = log_p_pair - 2.3  # between log 2 = 0.69 and log 50 = 3.9 below log p
    lib, demo, _ = _two_close(tmp_path, support=support, consolidation=consolidation, novelty_test="loglik",
                              log_T_merge=log_T_merge)
    assert bool(lib.partial_fit(demo).merged) == merges


@pytest.mark.parametrize("novelty_test", ["chi2", "loglik"])
def test_loglik_merge_threshold_counts_the_log_determinant(tmp_path, novelty_test):
    """log T_merge 3 above log p(mu_B | A) forbids the merge, 3 below allows it (support 1.5, beta 0.5)."""
    _, _, log_p_pair = _two_close(tmp_path, support=1.5, consolidation=0.5, novelty_test="chi2")
    for offset, merges in ((-3.0, True), (3.0, False)):
        lib, demo, _ = _two_close(tmp_path, support=1.5, consolidation=0.5, novelty_test="loglik",
                                  log_T_merge=log_p_pair + offset - 0.5 * np.log(1.5))
        assert bool(lib.partial_fit(demo).merged) == merges, offset


@pytest.mark.parametrize("age, merges", [(4, False), (5, True)])
def test_only_components_older_than_merge_min_age_are_checked(tmp_path, age, merges):
    """Ages in the file are before the update: the demonstration makes them age + 1; merge_min_age is 5."""
    lib, demo, _ = _two_close(tmp_path, support=2.0, consolidation=0.5, novelty_test="chi2", ages=age)
    assert bool(lib.partial_fit(demo).merged) == merges


def test_updated_component_checks_an_unchanged_one_under_its_own_covariance(tmp_path):
    """A (wide, updated by the demonstration) and B (tight, responsibility ~1e-7, so not updated):
    mu_B is close under A's Gaussian (d^2 ~ 0.8 / 0.2 after the update, threshold 14.3 / 2 = 7.2), mu_A far
    under B's (d^2 ~ 0.8 / 0.0101 = 79): the merge is found from A, the component the demonstration changed."""
    cfg = LibraryConfig(**SMALL, gating_floor=0.01)
    rng = np.random.default_rng(2)
    demo = synthetic_demo(0, rng, T=30, robot=False)
    w = lf.encode(cfg, demo)
    h = w.shape[0]
    comps = [lf.component(0, w, 0.25 * np.eye(h), support=3.0, age=10),
             lf.component(1, w + np.sqrt(0.8) * _unit(rng, h), 1e-4 * np.eye(h), support=2.0, age=10)]
    lib = SkillLibrary.load(lf.write_library(tmp_path / "ab.npz", cfg, comps, dim_human=3, dim_robot=0))
    u = lib.partial_fit(demo)
    assert u.updated == (0,) and u.responsibilities[1] < 1e-5
    assert u.merged == ((0, 1),)


def test_unchanged_pair_is_not_rechecked(tmp_path):
    """Two close old components that the demonstration leaves alone (it creates a far third one):
    only pairs with a changed component are checked, as Algorithm 1 checks after an update."""
    cfg = LibraryConfig(**SMALL, gating_floor=0.25)
    rng = np.random.default_rng(3)
    far = synthetic_demo(2, rng, T=30, robot=False)
    w = lf.encode(cfg, synthetic_demo(0, rng, T=30, robot=False))
    h = w.shape[0]
    comps = [lf.component(0, w, 1e-4 * np.eye(h), support=2.0, age=10),
             lf.component(1, w + 1.0 * _unit(rng, h), 1e-4 * np.eye(h), support=2.0, age=10)]
    lib = SkillLibrary.load(lf.write_library(tmp_path / "ab.npz", cfg, comps, dim_human=3, dim_robot=0))
    u = lib.partial_fit(far)
    assert u.created == (2,) and u.merged == ()
    assert [c.age for c in lib.components] == [11, 11, 1]


def test_best_pair_merges_first_then_the_merged_component_is_checked_again(tmp_path):
    """A (wide, updated) has B at d^2 ~ 1 and C at d^2 ~ 3 under its Gaussian, both below the threshold
    chi2_0.5(15) / 5^0.5 = 6.4. B and C are tight (cov 1e-5, floor 1e-3), so the demonstration at A's mean
    is far from them (d^2 > 180) and only A changes. B is absorbed first (the better pair); then the merged
    component, changed, absorbs C (d^2 ~ 3.6 < 14.3 / 6^0.5 = 5.9)."""
    cfg = LibraryConfig(**SMALL, gating_floor=1e-3)
    rng = np.random.default_rng(4)
    demo = synthetic_demo(0, rng, T=30, robot=False)
    w = lf.encode(cfg, demo)
    h = w.shape[0]
    tight = 1e-5 * np.eye(h)
    comps = [lf.component(0, w, 0.25 * np.eye(h), support=4.0, age=10),
             lf.component(1, w + np.sqrt(0.2) * _unit(rng, h), tight, support=1.0, age=10),
             lf.component(2, w + np.sqrt(0.6) * _unit(rng, h), tight, support=1.0, age=10)]
    lib = SkillLibrary.load(lf.write_library(tmp_path / "abc.npz", cfg, comps, dim_human=3, dim_robot=0))
    u = lib.partial_fit(demo)
    assert u.updated == (0,)
    assert u.merged == ((0, 1), (0, 2))
    assert [e["event"] for e in lib.history[-2:]] == ["merged", "merged"]
    # supports 4 + 1 + 1 plus the demonstration's responsibilities, which sum to 1
    assert lib.n_components == 1 and lib.components[0].support == pytest.approx(7.0, abs=1e-12)


def test_best_pair_merges_first_in_the_log_domain_however_deep_inside_the_threshold(tmp_path):
    """novelty_test="loglik" with log T_merge = -100: both candidates lie ~95 nats inside the threshold.
    The nearer one (B, d^2 ~ 1, listed after C, d^2 ~ 3) is still absorbed first."""
    cfg = LibraryConfig(**SMALL, gating_floor=1e-3, novelty_test="loglik", log_T_merge=-100.0)
    rng = np.random.default_rng(4)
    demo = synthetic_demo(0, rng, T=30, robot=False)
    w = lf.encode(cfg, demo)
    h = w.shape[0]
    tight = 1e-5 * np.eye(h)
    comps = [lf.component(0, w, 0.25 * np.eye(h), support=4.0, age=10),
             lf.component(1, w + np.sqrt(0.6) * _unit(rng, h), tight, support=1.0, age=10),   # C, farther
             lf.component(2, w + np.sqrt(0.2) * _unit(rng, h), tight, support=1.0, age=10)]   # B, nearer
    lib = SkillLibrary.load(lf.write_library(tmp_path / "acb.npz", cfg, comps, dim_human=3, dim_robot=0))
    u = lib.partial_fit(demo)
    assert u.updated == (0,)
    assert u.merged == ((0, 2), (0, 1))


def test_a_young_component_does_not_stop_the_merge_check_of_the_others(tmp_path):
    """A component no older than merge_min_age, listed first, is skipped; the pair after it still merges."""
    lib, demo, _ = _two_close(tmp_path, support=2.0, consolidation=0.5, novelty_test="chi2")
    cfg = lib.config
    comps = [lf.component(7, lib.components[0].mean + 50.0, 1e-4 * np.eye(15), support=1.0, age=1)]
    comps += [lf.component(c.id, c.mean, c.cov, support=c.support, age=c.age) for c in lib.components]
    young_first = SkillLibrary.load(lf.write_library(tmp_path / "young.npz", cfg, comps, dim_human=3, dim_robot=0,
                                                     next_id=8))
    assert young_first.partial_fit(demo).merged == ((0, 1),)


def _wide_unchanged_tight_changed(tmp_path, with_c):
    """A wide (cov 0.25, support 4) and unchanged; B tight (1e-4) at d^2 ~ 3 under A's Gaussian, and the
    demonstration sits on B (responsibility of A ~1e-11). Optionally C, tight, near A (d^2 ~ 2 under A)
    but far from the demonstration (not updated). Floor 0.01."""
    cfg = LibraryConfig(**SMALL, gating_floor=0.01)
    rng = np.random.default_rng(5)
    demo = synthetic_demo(0, rng, T=30, robot=False)
    w = lf.encode(cfg, demo)
    h = w.shape[0]
    mean_a = w + np.sqrt(0.8) * _unit(rng, h)
    comps = [lf.component(0, mean_a, 0.25 * np.eye(h), support=4.0, age=10),
             lf.component(1, w, 1e-4 * np.eye(h), support=2.0, age=10)]
    if with_c:
        comps.append(lf.component(2, mean_a + np.sqrt(0.5) * _unit(rng, h), 1e-4 * np.eye(h), support=1.0,
                                  age=10))
    return SkillLibrary.load(lf.write_library(tmp_path / f"abc{with_c}.npz", cfg, comps, dim_human=3,
                                              dim_robot=0)), demo


def test_unchanged_component_checks_the_changed_one_under_its_own_covariance(tmp_path):
    """Only A's Gaussian is wide enough for the pair: the merge is found from the unchanged component."""
    lib, demo = _wide_unchanged_tight_changed(tmp_path, with_c=False)
    u = lib.partial_fit(demo)
    assert u.updated == (1,) and u.responsibilities[0] < 1e-6
    assert u.merged == ((0, 1),)


def test_component_changed_by_a_merge_is_checked_against_all_others(tmp_path):
    """After absorbing B, A has changed: it is checked against C too, which the demonstration left alone."""
    lib, demo = _wide_unchanged_tight_changed(tmp_path, with_c=True)
    u = lib.partial_fit(demo)
    assert u.updated == (1,) and u.responsibilities[2] < 1e-6
    assert u.merged == ((0, 1), (0, 2))
    assert [c.id for c in lib.components] == [0]


def test_best_pair_is_compared_across_the_checking_components(tmp_path):
    """A (tight, updated) and C (tight, at d^2 ~ 1.4 from A) find each other at ~0.1-0.2 of their
    thresholds; B (wide, unchanged, listed last) finds A at ~0.4: the better pair, found first, is kept."""
    cfg = LibraryConfig(**SMALL, gating_floor=0.01)
    rng = np.random.default_rng(6)
    demo = synthetic_demo(0, rng, T=30, robot=False)
    w = lf.encode(cfg, demo)
    h = w.shape[0]
    comps = [lf.component(0, w, 1e-4 * np.eye(h), support=3.0, age=10),                                     # A
             lf.component(1, w + np.sqrt(1.4 * 0.0101) * _unit(rng, h), 1e-4 * np.eye(h), support=1.0, age=10),  # C
             lf.component(2, w + np.sqrt(4 * 0.26) * _unit(rng, h), 0.25 * np.eye(h), support=2.0, age=10)]  # B
    lib = SkillLibrary.load(lf.write_library(tmp_path / "acb.npz", cfg, comps, dim_human=3, dim_robot=0))
    u = lib.partial_fit(demo)
    assert u.responsibilities[2] < 1e-6
    assert u.merged[0] == (0, 1)
