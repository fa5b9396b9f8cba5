"""Recognition and novelty (Eqs. 5, 9, 12) at their thresholds, on libraries set up by hand.

A component is placed at a chosen squared Mahalanobis distance from the weights of a
demonstration under the predictive covariance ``Sigma (1 + 1/s_k)`` of the shared
scale, so the tests know d^2 and log p(w_h | k) exactly and can put the motion just
inside or just outside the novelty test (chi-square quantile or log T_nov).
"""
import json

import numpy as np
import pytest
from scipy.special import softmax
from scipy.stats import chi2, multivariate_normal

from drake_skills import LibraryConfig
from drake_skills.library.incremental import UnknownSkillError

import library_states as ls
from synthetic import synthetic_demo

SMALL = dict(n_samples=30, n_basis_human=5, n_basis_robot=5, delete_min_age=1000)
H = 15  # 3-D human, 5 basis functions
Q = LibraryConfig().novelty_quantile  # the default novelty quantile
THR = chi2.ppf(Q, H)  # 39.7 at 0.9995


def _at_distance(d2s, *, supports=None, robot=False, var=1.0, **cfg_kw):
    """A library whose components lie at predictive squared distances ``d2s`` from the weights of one
    demonstration; returns (lib, demo, w, Sigma)."""
    cfg = LibraryConfig(**{**SMALL, **cfg_kw})
    rng = np.random.default_rng(len(d2s))
    demo = synthetic_demo(0, rng, T=30, robot=robot)
    w = ls.encode(cfg, demo)
    dims = dict(dim_human=3, dim_robot=7 if robot else 0)
    G = ls.library(cfg, [], var=var, **dims).shared_covariance()
    g = G[0, 0]
    np.testing.assert_allclose(G, g * np.eye(H), rtol=0, atol=1e-9 * g)  # isotropic: distances are exact
    supports = [1.0] * len(d2s) if supports is None else supports
    comps = []
    for k, (d2, s) in enumerate(zip(d2s, supports)):
        mean = w.copy()
        mean[:H] += np.sqrt(d2 * g * (1.0 + 1.0 / s)) * ls.unit(rng, H)
        comps.append(ls.component(k, mean, support=s, age=3))
    return ls.library(cfg, comps, var=var, n_seen=6, **dims), demo, w, G


@pytest.mark.parametrize("factor, unknown", [(0.99, False), (1.01, True)])
def test_motion_is_unknown_just_beyond_the_chi2_quantile(factor, unknown):
    lib, demo, _, _ = _at_distance([factor * THR], supports=[2.0])
    rec = lib.recognize(demo.human, observed_fraction=1.0)
    assert rec.mahalanobis_sq[0] == pytest.approx(factor * THR, rel=1e-9)
    assert rec.status == ("unknown" if unknown else "skill") and rec.component == (None if unknown else 0)
    assert rec.dof == H
    assert rec.posterior.shape == (1,) and rec.posterior.dtype == float
    np.testing.assert_array_equal(rec.posterior, [0.0 if unknown else 1.0])


@pytest.mark.parametrize("quantile", [0.9, 0.99999])
def test_novelty_quantile_sets_the_threshold(quantile):
    thr = chi2.ppf(quantile, H)
    for factor, unknown in ((0.98, False), (1.02, True)):
        lib, demo, _, _ = _at_distance([factor * thr], novelty_quantile=quantile, split_quantile=0.999999)
        assert (lib.recognize(demo.human, observed_fraction=1.0).status == "unknown") is unknown, (quantile, factor)


@pytest.mark.parametrize("factor, created", [(0.99, False), (1.01, True)])
def test_demonstration_is_novel_just_beyond_the_chi2_quantile(factor, created):
    # merge_quantile 0.5: the new component is not merged back at once
    lib, demo, _, _ = _at_distance([factor * THR], supports=[3.0], merge_quantile=0.5)
    u = lib.partial_fit(demo)
    assert bool(u.created) is created
    assert u.recognized == (None if created else 0)
    assert lib.n_components == (2 if created else 1)


@pytest.mark.parametrize("offset, unknown", [(0.05, True), (-0.05, False)])
def test_loglik_novelty_compares_log_p_with_log_T_nov(offset, unknown):
    """novelty_test="loglik": unknown when log p(w_h | k) < log T_nov for every k, log p under Sigma (1 + 1/s)."""
    lib0, demo, w, G = _at_distance([20.0], supports=[4.0], var=0.5)  # log det Sigma = -10: it counts
    c = lib0.components[0]
    log_p = multivariate_normal(c.mean[:H], G * 1.25).logpdf(w[:H])
    lib, demo, _, _ = _at_distance([20.0], supports=[4.0], novelty_test="loglik", log_T_nov=log_p + offset,
                                   log_T_merge=1e3, var=0.5)
    rec = lib.recognize(demo.human, observed_fraction=1.0)
    assert rec.log_likelihoods[0] == pytest.approx(log_p, rel=1e-12)
    assert (rec.status == "unknown") is unknown
    assert bool(lib.partial_fit(demo).created) is unknown


def test_recognition_reports_log_densities_distances_and_responsibilities():
    lib, demo, w, G = _at_distance([2.0, 8.0, 60.0], supports=[3.0, 1.0, 4.0], var=0.7)
    rec = lib.recognize(demo.human, observed_fraction=1.0)
    assert rec.ids == (0, 1, 2)
    comps = lib.components
    logp = [multivariate_normal(c.mean[:H], G * (1 + 1 / c.support)).logpdf(w[:H]) for c in comps]
    np.testing.assert_allclose(rec.log_likelihoods, logp, rtol=1e-10)
    np.testing.assert_allclose(rec.mahalanobis_sq, [2.0, 8.0, 60.0], rtol=1e-9)
    resp = softmax(np.array(logp) + np.log(np.array([3.0, 1.0, 4.0]) / 8.0))  # Eq. (5)
    np.testing.assert_allclose(rec.responsibilities, resp, rtol=1e-10)
    # the posterior is Eq. (5) over the components that explain the motion (not the 60 one)
    post = softmax(np.array(logp[:2]) + np.log(np.array([3.0, 1.0]) / 4.0))
    np.testing.assert_allclose(rec.posterior, np.r_[post, 0.0], rtol=1e-10, atol=1e-300)
    np.testing.assert_allclose(rec.phases, 1.0)
    # each component's gating covariance in the view is the one judged with
    np.testing.assert_allclose(comps[1].cov_gating, G * 2.0, rtol=1e-12)


def test_component_is_the_most_responsible_among_those_the_motion_is_not_novel_for():
    """A heavy component 0 takes most of the responsibility although the motion is novel for it (d^2 = 40 >
    39.7); component 1 explains it (d^2 = 1): the answer is 1, not unknown and not 0."""
    lib, demo, _, _ = _at_distance([40.0, 1.0], supports=[1e9, 1.0])
    rec = lib.recognize(demo.human, observed_fraction=1.0)
    assert rec.responsibilities[0] > 0.99
    assert rec.status == "skill" and rec.component == 1
    assert rec.posterior.tolist() == [0.0, 1.0]


def test_responsibilities_of_a_demonstration_update_every_component_with_its_share():
    """partial_fit updates each component that explains the motion with its posterior share (Eqs. 5-8)."""
    lib, demo, w, _ = _at_distance([2.0, 5.0, 45.0], supports=[2.0, 1.0, 1.0], merge_quantile=0.001)
    rec = lib.recognize(demo.human, observed_fraction=1.0)
    before = lib.components
    u = lib.partial_fit(demo)
    lam = rec.posterior
    assert dict(u.responsibilities) == pytest.approx({0: lam[0], 1: lam[1], 2: 0.0}, rel=1e-6, abs=1e-12)
    assert u.updated == (0, 1) and u.recognized == 0 and u.created == () and u.merged == ()
    for b, a, l in zip(before, lib.components, lam):
        assert a.support == pytest.approx(b.support + l, rel=1e-6)
        assert a.age == b.age + 1
        np.testing.assert_allclose(a.mean, b.mean + l / (b.support + l) * (w - b.mean), rtol=0, atol=1e-6)
    np.testing.assert_array_equal(lib.components[2].mean, before[2].mean)  # not explained: unchanged
    # each updated component's demonstration went to a sub-cluster with the same share
    for c in lib.state().components[:2]:
        assert c.subclusters[1].support == pytest.approx(u.responsibilities[c.id], rel=1e-12)
    # ids are ints (they are written to JSON)
    assert all(type(k) is int for k in u.responsibilities) and type(u.recognized) is int
    u2 = lib.partial_fit(demo)
    assert all(type(k) is int for k in u2.responsibilities) and '"0":' in json.dumps(dict(u2.responsibilities))


def test_update_reports_the_most_responsible_component():
    lib, demo, _, _ = _at_distance([6.0, 1.0, 4.0])
    u = lib.partial_fit(demo)
    assert u.recognized == 1 and max(u.responsibilities, key=u.responsibilities.get) == 1


def test_unknown_motion_cannot_be_predicted():
    lib, demo, _, _ = _at_distance([2 * THR], robot=True)
    with pytest.raises(UnknownSkillError, match="^the motion matches no skill in the library: ask for a demonstration$"):
        lib.predict_robot(demo.human, observed_fraction=1.0)
    lib, demo, _, _ = _at_distance([0.5 * THR], robot=True)
    mean, cov = lib.predict_robot(demo.human, observed_fraction=1.0)
    assert mean.shape == (30, 7) and cov.shape == (30, 7, 7)


def test_library_with_no_components_answers_unknown():
    lib = ls.library(LibraryConfig(**SMALL), [], dim_human=3, dim_robot=7, next_id=2, n_seen=5)
    human = synthetic_demo(0, np.random.default_rng(0), T=30).human
    for rec in (lib.recognize(human, observed_fraction=1.0), lib.recognize(human),
                lib.recognize(human[:10], observed_fraction=0.3)):
        assert rec.status == "unknown" and rec.component is None and rec.ids == () and rec.dof == H
        assert rec.responsibilities.shape == rec.log_likelihoods.shape == rec.mahalanobis_sq.shape == (0,)
    with pytest.raises(UnknownSkillError):
        lib.predict_robot(human)
    assert lib.partial_fit(synthetic_demo(0, np.random.default_rng(1), T=30)).created == (2,)


def test_responsibilities_read_like_the_dict_they_stand_for():
    """A ``Responsibilities`` is a read-only mapping id -> value that prints as the dict it stands for."""
    from drake_skills.library.views import Responsibilities

    r = Responsibilities(np.array([4, 9]), np.array([0.25, 0.75]))
    assert dict(r) == {4: 0.25, 9: 0.75} and len(r) == 2 and r[9] == 0.75 and list(r) == [4, 9]
    assert repr(r) == "{4: 0.25, 9: 0.75}"
    with pytest.raises(KeyError):
        r[5]
