"""The novelty, merge and split tests at their thresholds: which side the boundary falls on.

Both rules of ``library.novelty`` say a motion *fits* a component when its statistic reaches
the threshold exactly, and a component *splits* only beyond it (the chi-square rule: ``d2 >
quantile`` is novel; the log-likelihood rule: ``log p < log_T_nov`` is novel). A value exactly
at a threshold is rare with real data, but a library compared across versions or machines must
give the same answers there.
"""
import numpy as np

from drake_skills.library.novelty import Chi2Rule, LogLikRule, chi2_ppf

H = 21


def test_a_log_likelihood_exactly_at_the_novelty_threshold_fits():
    rule = LogLikRule(-60.0, -20.0, 0.9999, consolidation=0.0)
    ll = np.array([-60.0, np.nextafter(-60.0, -np.inf), -59.0])
    np.testing.assert_array_equal(rule.novel(ll, np.zeros(3), H), [False, True, False])


def test_a_chi_square_statistic_exactly_at_the_novelty_threshold_fits():
    rule = Chi2Rule(0.999, 0.999, 0.9999, consolidation=0.0)
    q = chi2_ppf(0.999, H)
    d2 = np.array([q, np.nextafter(q, np.inf)])
    np.testing.assert_array_equal(rule.novel(np.zeros(2), d2, H), [False, True])


def test_sub_clusters_exactly_at_the_split_quantile_stay_together_under_both_rules():
    q = chi2_ppf(0.9999, H)
    d2 = np.array([q, np.nextafter(q, np.inf)])
    for rule in (Chi2Rule(0.999, 0.999, 0.9999, consolidation=0.0), LogLikRule(-60.0, -20.0, 0.9999, consolidation=0.0)):
        np.testing.assert_array_equal(rule.splits(d2, H), [False, True])


def test_loglik_merge_threshold_grows_with_the_log_of_integer_supports_too():
    """Supports passed as integers give the thresholds of the same supports as floats (Eq. 10)."""
    rule = LogLikRule(-60.0, -20.0, 0.9999, consolidation=0.5)
    d2 = np.array([3.0, 3.0])
    a = rule.merge_scores(d2, np.array([1, 4]), np.array([2.0, 0.5]), 1.5, H)
    b = rule.merge_scores(d2, np.array([1.0, 4.0]), np.array([2.0, 0.5]), 1.5, H)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
    # the threshold of support 4 is 0.5 log 4 above that of support 1, for the same log p
    same = rule.merge_scores(np.array([3.0, 3.0]), np.array([1.0, 4.0]), np.array([2.0, 2.0]), 1.5, H)
    assert abs((same[1] - same[0]) - 0.5 * np.log(4.0)) < 1e-12  # score = threshold - log p: support makes a merge harder


def test_chi2_ppf_of_an_array_equals_scipy_elementwise_for_integer_and_fractional_dof():
    """The table lookup for integer dof (a prefix test's (K, J) array) gives scipy's quantiles, shape kept."""
    from scipy.stats import chi2

    dof = np.array([[3, 6, 21, 6], [1, 3, 3, 12]])
    np.testing.assert_allclose(chi2_ppf(0.9995, dof), chi2.ppf(0.9995, dof), rtol=1e-12)
    assert chi2_ppf(0.9995, dof).shape == (2, 4)
    wide = np.broadcast_to(np.array([3.0, 9.0, 5000.0]), (50, 3))      # a range too wide for one table
    from drake_skills.library import novelty
    assert 5000 - 3 >= novelty._TABLE_SPAN
    np.testing.assert_allclose(chi2_ppf(0.99, wide), chi2.ppf(0.99, wide), rtol=1e-12)
    mixed = np.array([2.5, 3.0, 7.0])
    np.testing.assert_allclose(chi2_ppf(0.99, mixed), chi2.ppf(0.99, mixed), rtol=1e-12)
    assert chi2_ppf(0.99, np.zeros((0, 4))).shape == (0, 4)
