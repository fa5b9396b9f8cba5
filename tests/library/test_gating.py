"""Recognition and novelty (Eqs. 5, 9, 12) at their thresholds, on libraries written by hand.

A component is placed at a chosen squared Mahalanobis distance from the weights of a
demonstration, so the tests know d^2 and log p(w_h | k) exactly and can put the
motion just inside or just outside the novelty test (chi-square quantile or log T_nov).
"""
import numpy as np
import pytest
from scipy.special import softmax
from scipy.stats import chi2, multivariate_normal

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.library.incremental import UnknownSkillError

import library_files as lf
from synthetic import synthetic_demo

SMALL = dict(n_samples=30, n_basis_human=5, n_basis_robot=5, delete_min_age=1000)
H = 15  # 3-D human, 5 basis functions
THR = chi2.ppf(0.999, H)  # 37.7, the default novelty quantile


def _unit(rng, n):
    u = rng.standard_normal(n)
    return u / np.linalg.norm(u)


def _at_distance(tmp_path, d2s, *, cov=0.5, supports=None, robot=False, name="lib.npz", **cfg_kw):
    """A library whose components lie at squared Mahalanobis distances ``d2s`` (floored gating
    covariance (cov + floor) I) from the weights of one demonstration; returns (lib, demo, w)."""
    cfg = LibraryConfig(**{**SMALL, **cfg_kw})
    rng = np.random.default_rng(len(d2s))
    demo = synthetic_demo(0, rng, T=30, robot=robot)
    w = lf.encode(cfg, demo)
    d = w.shape[0]
    covs = np.broadcast_to(cov, (len(d2s),))
    comps = []
    for k, (d2, c) in enumerate(zip(d2s, covs)):
        mean = w.copy()
        mean[:H] += np.sqrt(d2 * (c + cfg.gating_floor)) * _unit(rng, H)
        S = c * np.eye(d)
        comps.append(lf.component(k, mean, S, support=1.0 if supports is None else supports[k], age=3))
    path = lf.write_library(tmp_path / name, cfg, comps, dim_human=3, dim_robot=7 if robot else 0)
    return SkillLibrary.load(path), demo, w


@pytest.mark.parametrize("factor, unknown", [(0.99, False), (1.01, True)])
def test_motion_is_unknown_just_beyond_the_chi2_quantile(tmp_path, factor, unknown):
    lib, demo, _ = _at_distance(tmp_path, [factor * THR])
    rec = lib.recognize(demo.human)
    assert rec.mahalanobis_sq[0] == pytest.approx(factor * THR, rel=1e-9)
    assert rec.unknown is unknown and rec.component == (None if unknown else 0)
    assert rec.dof == H


@pytest.mark.parametrize("quantile", [0.9, 0.99999])
def test_novelty_quantile_sets_the_threshold(tmp_path, quantile):
    thr = chi2.ppf(quantile, H)
    for factor, unknown in ((0.98, False), (1.02, True)):
        lib, demo, _ = _at_distance(tmp_path, [factor * thr], novelty_quantile=quantile)
        assert lib.recognize(demo.human).unknown is unknown, (quantile, factor)


@pytest.mark.parametrize("factor, created", [(0.99, False), (1.01, True)])
def test_demonstration_is_novel_just_beyond_the_chi2_quantile(tmp_path, factor, created):
    lib, demo, _ = _at_distance(tmp_path, [factor * THR])
    u = lib.partial_fit(demo)
    assert bool(u.created) is created
    assert u.recognized == (None if created else 0)
    assert lib.n_components == (2 if created else 1)


@pytest.mark.parametrize("offset, unknown", [(0.05, True), (-0.05, False)])
def test_loglik_novelty_compares_log_p_with_log_T_nov(tmp_path, offset, unknown):
    """novelty_test="loglik": unknown when log p(w_h | k) < log T_nov for every k."""
    lib0, demo, w = _at_distance(tmp_path, [20.0])
    c = lib0.components[0]
    log_p = multivariate_normal(c.mean[:H], (0.5 + 1.0) * np.eye(H)).logpdf(w[:H])
    lib, demo, _ = _at_distance(tmp_path, [20.0], novelty_test="loglik", log_T_nov=log_p + offset)
    rec = lib.recognize(demo.human)
    assert rec.log_likelihoods[0] == pytest.approx(log_p, rel=1e-12)
    assert rec.unknown is unknown
    assert bool(lib.partial_fit(demo).created) is unknown


def test_recognition_reports_floored_log_densities_distances_and_responsibilities(tmp_path):
    lib, demo, w = _at_distance(tmp_path, [2.0, 8.0, 60.0], cov=[0.5, 2.0, 0.1], supports=[3.0, 1.0, 4.0])
    rec = lib.recognize(demo.human)
    assert rec.ids == (0, 1, 2)
    comps = lib.components
    floor = lib.config.gating_floor
    logp = [multivariate_normal(c.mean[:H], c.cov[:H, :H] + floor * np.eye(H)).logpdf(w[:H]) for c in comps]
    np.testing.assert_allclose(rec.log_likelihoods, logp, rtol=1e-10)
    np.testing.assert_allclose(rec.mahalanobis_sq, [2.0, 8.0, 60.0], rtol=1e-9)
    resp = softmax(np.array(logp) + np.log(np.array([3.0, 1.0, 4.0]) / 8.0))  # Eq. (5)
    np.testing.assert_allclose(rec.responsibilities, resp, rtol=1e-10)
    assert rec.component == int(np.argmax(resp))


def test_component_is_the_most_responsible_among_those_the_motion_is_not_novel_for(tmp_path):
    """A tight, heavy component 0 takes nearly all the responsibility although the motion is novel for it
    (d^2 = 40 > 37.7); component 1 explains it (d^2 = 1): the answer is 1, not unknown and not 0."""
    lib, demo, _ = _at_distance(tmp_path, [40.0, 1.0], cov=[1e-4, 3.0], supports=[1000.0, 1.0], gating_floor=0.01)
    rec = lib.recognize(demo.human)
    assert rec.responsibilities[0] > 0.999
    assert rec.component == 1


def test_responsibilities_of_a_demonstration_update_every_component(tmp_path):
    """partial_fit reports the responsibilities of Eq. (5) and updates each component with its own share."""
    lib, demo, w = _at_distance(tmp_path, [2.0, 5.0], supports=[2.0, 1.0])
    rec = lib.recognize(demo.human)
    before = lib.components
    u = lib.partial_fit(demo)
    assert u.responsibilities == pytest.approx({0: rec.responsibilities[0], 1: rec.responsibilities[1]}, rel=1e-12)
    assert u.updated == (0, 1) and u.recognized == 0 and u.created == () and u.merged == ()
    for b, a, lam in zip(before, lib.components, rec.responsibilities):
        assert a.support == pytest.approx(b.support + lam, rel=1e-12)
        assert a.age == b.age + 1
        gamma = lam / a.support
        np.testing.assert_allclose(a.mean, b.mean + gamma * (w - b.mean), rtol=0, atol=1e-12)


def test_update_reports_the_most_responsible_component(tmp_path):
    lib, demo, _ = _at_distance(tmp_path, [6.0, 1.0, 4.0])
    u = lib.partial_fit(demo)
    assert u.recognized == 1 and max(u.responsibilities, key=u.responsibilities.get) == 1


def test_unknown_motion_cannot_be_predicted(tmp_path):
    lib, demo, _ = _at_distance(tmp_path, [2 * THR], robot=True)
    with pytest.raises(UnknownSkillError, match="^the motion matches no skill in the library: ask for a demonstration$"):
        lib.predict_robot(demo.human)
    lib, demo, _ = _at_distance(tmp_path, [0.5 * THR], robot=True, name="near.npz")
    mean, cov = lib.predict_robot(demo.human)
    assert mean.shape == (30, 7) and cov.shape == (30, 7, 7)


def test_library_with_no_components_answers_unknown(tmp_path):
    cfg = LibraryConfig(**SMALL)
    meta = lf.metadata(cfg, [], dim_human=3, dim_robot=7, next_id=2, n_seen=5)
    lib = SkillLibrary.load(lf.write(tmp_path / "none.npz", meta, np.zeros((0, 50)), np.zeros((0, 50, 50))))
    human = synthetic_demo(0, np.random.default_rng(0), T=30).human
    rec = lib.recognize(human)
    assert rec.component is None and rec.ids == () and rec.dof == H
    assert rec.responsibilities.shape == rec.log_likelihoods.shape == rec.mahalanobis_sq.shape == (0,)
    assert lib.recognize(human[:10], observed_fraction=0.3).component is None
    with pytest.raises(UnknownSkillError):
        lib.predict_robot(human)
