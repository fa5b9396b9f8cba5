"""Recognition's decision (skill / undecided / unknown) on hand-set libraries with a robot part.

Two components explain a motion equally (posterior 1/2 each). Executing either is only
wrong if they answer differently: their robot means more than the ``novelty_quantile``
of the predictive within-skill spread ``Sigma_rr (1 + 1/s)`` apart. So the answer is
"skill" when the responses are alike and "undecided" when they are not.
"""
import numpy as np
import pytest
from scipy.stats import chi2

from drake_skills import LibraryConfig
from drake_skills.library.incremental import UnknownSkillError

import library_states as ls
from synthetic import synthetic_demo

H, R = 15, 35
SMALL = dict(n_samples=30, n_basis_human=5, n_basis_robot=5, delete_min_age=1000)


def _two_equal(response_d2, *, d2_human=4.0, supports=(2.0, 2.0), risk=0.01, var=0.8):
    cfg = LibraryConfig(**SMALL, decision_risk=risk)
    rng = np.random.default_rng(0)
    demo = synthetic_demo(0, rng, T=30)
    w = ls.encode(cfg, demo)
    S = ls.library(cfg, [], dim_human=3, dim_robot=7, var=var).shared_covariance("expert")
    gh, gr = S[0, 0], S[H, H]
    np.testing.assert_allclose(S[H:, H:], gr * np.eye(R), rtol=0, atol=1e-9 * gr)
    e1, e2 = np.eye(H)[0], np.eye(H)[1]
    comps = []
    for k, (e, s) in enumerate(zip((e1, e2), supports)):
        m = w.copy()
        m[:H] += np.sqrt(d2_human * gh * (1 + 1 / s)) * e
        comps.append(m)
    # response of component 1 at predictive distance response_d2 from component 0's
    comps[1][H:] = comps[0][H:] + np.sqrt(response_d2 * gr * (1 + 1 / supports[0])) * ls.unit(rng, R)
    lib = ls.library(cfg, [ls.component(k, m, support=s, age=3) for k, (m, s) in enumerate(zip(comps, supports))],
                     dim_human=3, dim_robot=7, n_seen=6, var=var)
    return lib, demo


def test_two_equally_likely_skills_that_answer_alike_are_one_decision():
    lib, demo = _two_equal(0.97 * chi2.ppf(LibraryConfig().novelty_quantile, R))
    rec = lib.recognize(demo.human, observed_fraction=1.0)
    np.testing.assert_allclose(rec.posterior, [0.5, 0.5], rtol=1e-9)
    assert rec.status == "skill" and rec.component == 0


def test_two_equally_likely_skills_that_answer_differently_are_undecided():
    lib, demo = _two_equal(1.03 * chi2.ppf(LibraryConfig().novelty_quantile, R))
    rec = lib.recognize(demo.human, observed_fraction=1.0)
    np.testing.assert_allclose(rec.posterior, [0.5, 0.5], rtol=1e-9)
    assert rec.status == "undecided" and rec.component is None
    with pytest.raises(UnknownSkillError, match=r"^the motion fits more than one skill and none clearly "
                                                r"\(([01]) \(0\.50\), (?!\1)[01] \(0\.50\)\): observe more, or ask$"):
        lib.predict_robot(demo.human, observed_fraction=1.0)


@pytest.mark.parametrize("factor, status", [(1.02, "skill"), (0.98, "undecided")])
def test_one_skill_is_decided_when_its_posterior_reaches_one_minus_the_decision_risk(factor, status):
    """Supports 3 and 1 at equal predictive distance: the posterior of 0 is p ~ 0.98 (prior 3:1, and 1 has the
    wider predictive Gaussian); a decision risk just above 1 - p accepts it, just below does not (responses far
    apart, so they do not count together)."""
    lib, demo = _two_equal(4 * chi2.ppf(LibraryConfig().novelty_quantile, R), supports=(3.0, 1.0))
    p = lib.recognize(demo.human, observed_fraction=1.0).posterior[0]
    assert 0.9 < p < 0.999
    lib, demo = _two_equal(4 * chi2.ppf(LibraryConfig().novelty_quantile, R), supports=(3.0, 1.0), risk=factor * (1 - p))
    rec = lib.recognize(demo.human, observed_fraction=1.0)
    assert rec.status == status and rec.component == (0 if status == "skill" else None)
