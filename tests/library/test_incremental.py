"""SkillLibrary: Algorithm 1 (Eqs. 5-12) on synthetic coupled demonstrations."""

import numpy as np
import pytest

from drake_skills import Demonstration, LibraryConfig, SkillLibrary
from drake_skills.library import incremental
from drake_skills.library.incremental import UnknownSkillError, incremental_update
from drake_skills.promp.gaussian import merge_moments

from synthetic import synthetic_demo


def _taught_library(n_per_task=6, tasks=(0, 1, 2), seed=0, **cfg):
    rng = np.random.default_rng(seed)
    lib = SkillLibrary(LibraryConfig(**cfg))
    order = [t for _ in range(n_per_task) for t in tasks]
    for i in rng.permutation(len(order)):
        lib.partial_fit(synthetic_demo(order[i], rng))
    return lib


def test_incremental_update_equals_exact_weighted_moments():
    """Without fast forgetting, the update is the running weighted (biased) covariance,
    the initial component counting as one pseudo-sample with covariance Sigma_init."""
    rng = np.random.default_rng(0)
    d = 4
    W = rng.standard_normal((30, d)) @ rng.standard_normal((d, d))
    lam = rng.uniform(0.05, 1.0, 30)
    lam[0] = 1.0
    Sigma_init = 0.3 * np.eye(d)
    mean, cov, s = W[0].copy(), Sigma_init.copy(), 1.0
    for w, l in zip(W[1:], lam[1:]):
        mean, cov, s, _ = incremental_update(mean, cov, s, w, float(l), fast_forgetting=False)
    mu_ref = np.average(W, axis=0, weights=lam)
    diff = W - mu_ref
    cov_ref = (Sigma_init + (lam[:, None] * diff).T @ diff) / lam.sum()
    np.testing.assert_allclose(s, lam.sum(), rtol=1e-12)
    np.testing.assert_allclose(mean, mu_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(cov, cov_ref, rtol=1e-10, atol=1e-12)


def test_fast_forgetting_moves_covariance_away_from_initialization_faster():
    rng = np.random.default_rng(1)
    W = 0.1 * rng.standard_normal((5, 3))
    out = {}
    for ff in (False, True):
        mean, cov, s = W[0], np.eye(3), 1.0
        for w in W[1:]:
            mean, cov, s, _ = incremental_update(mean, cov, s, w, 1.0, fast_forgetting=ff)
        out[ff] = np.trace(cov)
    assert out[True] < out[False]  # less of Sigma_init = I left


def test_merge_moments_match_pooled_samples():
    rng = np.random.default_rng(2)
    A, B = rng.normal(0, 1, (40, 3)), rng.normal(2, 0.5, (15, 3))
    mu, S = merge_moments(40, A.mean(0), np.cov(A.T, bias=True), 15, B.mean(0), np.cov(B.T, bias=True))
    P = np.vstack([A, B])
    np.testing.assert_allclose(mu, P.mean(0), atol=1e-12)
    np.testing.assert_allclose(S, np.cov(P.T, bias=True), atol=1e-12)


def test_partial_fit_creates_component_for_novel_demo():
    rng = np.random.default_rng(3)
    lib = SkillLibrary()
    u0 = lib.partial_fit(synthetic_demo(0, rng))
    assert u0.created == (0,) and u0.recognized is None
    u1 = lib.partial_fit(synthetic_demo(0, rng))
    assert u1.created == () and u1.recognized == 0 and u1.updated == (0,)
    u2 = lib.partial_fit(synthetic_demo(2, rng))
    assert u2.created == (1,)
    assert lib.n_components == 2
    assert [e["event"] for e in lib.history] == ["created", "created"]


def test_library_finds_one_component_per_skill_and_recognizes_them():
    lib = _taught_library(n_per_task=8, tasks=(0, 1, 2, 3))
    assert lib.n_components == 4
    rng = np.random.default_rng(99)
    owners = {}
    for task in range(4):
        for _ in range(5):
            rec = lib.recognize(synthetic_demo(task, rng).human)
            assert rec.component is not None
            owners.setdefault(task, set()).add(rec.component)
            assert rec.responsibilities.sum() == pytest.approx(1.0, abs=1e-12)
    assert all(len(v) == 1 for v in owners.values())
    assert len(set.union(*owners.values())) == 4


def test_recognize_answers_unknown_for_a_motion_never_shown():
    lib = _taught_library(tasks=(0, 1))
    rng = np.random.default_rng(4)
    rec = lib.recognize(synthetic_demo(3, rng).human)
    assert rec.component is None and rec.unknown
    with pytest.raises(UnknownSkillError):
        lib.predict_robot(synthetic_demo(3, rng).human)


def test_predict_robot_follows_the_observed_human():
    lib = _taught_library(n_per_task=20, tasks=(0, 1, 2))
    rng = np.random.default_rng(5)
    errs, prior_errs = [], []
    for task in (0, 1, 2) * 3:
        d = synthetic_demo(task, rng, noise=0.4)
        mean, cov = lib.predict_robot(d.human)
        assert mean.shape == (100, 7) and cov.shape == (100, 7, 7)
        k = lib.recognize(d.human).component
        prior = lib.component(k).mean[lib.n_human:].reshape(7, -1)
        prior_end = lib.config.basis_robot.phi_uniform(100)[-1] @ prior.T
        errs.append(np.abs(mean[-1] - d.robot[-1]).max())
        prior_errs.append(np.abs(prior_end - d.robot[-1]).max())
    # the robot's end pose depends on the human's goal (goal noise 0.4 -> about 0.05 rad);
    # conditioning on the human recovers most of it from 20 demonstrations per skill
    assert max(errs) < 0.04, errs
    assert np.mean(errs) < 0.5 * np.mean(prior_errs), (np.mean(errs), np.mean(prior_errs))


def test_prefix_recognition_and_prediction():
    lib = _taught_library(n_per_task=8, tasks=(0, 1, 2))
    rng = np.random.default_rng(6)
    d = synthetic_demo(1, rng)
    full = lib.recognize(d.human).component
    # cut at half the path length
    step = np.linalg.norm(np.diff(d.human, axis=0), axis=1)
    cut = int(np.searchsorted(np.cumsum(step), 0.5 * step.sum()))
    rec = lib.recognize(d.human[:cut + 1], observed_fraction=0.5)
    assert rec.component == full
    mean, _ = lib.predict_robot(d.human[:cut + 1], observed_fraction=0.5)
    assert np.abs(mean[-1] - d.robot[-1]).max() < 0.1


def test_outlier_component_is_deleted_after_its_deletion_age():
    rng = np.random.default_rng(7)
    cfg = LibraryConfig(delete_min_age=10, delete_min_support=1.5)
    lib = SkillLibrary(cfg)
    lib.partial_fit(synthetic_demo(0, rng))
    outlier = lib.partial_fit(synthetic_demo(3, rng)).created[0]
    deleted_at = None
    for i in range(15):
        u = lib.partial_fit(synthetic_demo(0, rng))
        if outlier in u.deleted:
            deleted_at = i
    assert deleted_at is not None
    assert outlier not in [c.id for c in lib.components]
    events = [e for e in lib.history if e["event"] == "deleted"]
    assert events and events[0]["id"] == outlier and events[0]["age"] == cfg.delete_min_age + 1


def test_duplicate_components_of_one_skill_are_merged():
    """Tight Sigma_init makes the first few demos of a skill novel (duplicates); once the
    components have grown to the skill's spread and are older than v_min, they merge."""
    rng = np.random.default_rng(8)
    cfg = LibraryConfig(sigma_init_human=0.05, gating_floor=0.01, merge_min_age=3, delete_min_age=1000)
    lib = SkillLibrary(cfg)
    merged = []
    for _ in range(40):
        merged += lib.partial_fit(synthetic_demo(0, rng, noise=0.6)).merged
    assert merged, "expected at least one merge"
    assert lib.n_components < 1 + len([e for e in lib.history if e["event"] == "created"]) - 1
    assert [e for e in lib.history if e["event"] == "merged"]


def test_failed_update_leaves_library_exactly_as_it_was(tmp_path, monkeypatch):
    lib = _taught_library(tasks=(0, 1))
    before = tmp_path / "before.npz"
    lib.save(before)
    rng = np.random.default_rng(10)
    good = synthetic_demo(2, rng)
    bad_inputs = [
        Demonstration(t=good.t, human=good.human[:, :2], robot=good.robot),        # wrong D_h
        Demonstration(t=good.t, human=good.human),                                  # robot missing
        Demonstration(t=good.t, human=np.zeros_like(good.human), robot=good.robot),  # does not move
    ]
    for demo in bad_inputs:
        with pytest.raises(ValueError):
            lib.partial_fit(demo)
    # a numerical failure in the middle of an update (after the weights were computed)
    def boom(*a, **k):
        raise np.linalg.LinAlgError("injected failure")
    monkeypatch.setattr(incremental, "incremental_update", boom)
    with pytest.raises(np.linalg.LinAlgError):
        lib.partial_fit(synthetic_demo(0, rng))
    after = tmp_path / "after.npz"
    lib.save(after)
    assert before.read_bytes() == after.read_bytes()


def test_recognize_and_predict_reject_bad_input():
    lib = _taught_library(tasks=(0, 1))
    with pytest.raises(ValueError, match="NaN"):
        lib.recognize(np.full((20, 3), np.nan))
    with pytest.raises(ValueError, match="columns"):
        lib.recognize(np.random.rand(20, 2))
    with pytest.raises(ValueError, match="too short"):
        lib.recognize(np.zeros((1, 3)))
    with pytest.raises(ValueError, match="observed_fraction"):
        lib.recognize(np.random.rand(20, 3), observed_fraction=1.5)
    with pytest.raises(ValueError, match="not fitted"):
        SkillLibrary().recognize(np.random.rand(20, 3))
    with pytest.raises(ValueError, match="Demonstration"):
        lib.partial_fit(np.random.rand(20, 3))


def test_human_only_library_equals_the_human_block_of_the_library_with_robot():
    """The gating model is the human block of the experts (Sec. 4.1): the same human motions, with or
    without robot trajectories, give the same components, whose human blocks are identical."""
    rng = np.random.default_rng(11)
    demos = [synthetic_demo(i % 3, rng, noise=0.4) for i in range(12)]
    cfg = LibraryConfig(sigma_init_human=0.3, merge_min_age=2)
    with_robot, human_only = SkillLibrary(cfg), SkillLibrary(cfg)
    for d in demos:
        u = with_robot.partial_fit(d)
        v = human_only.partial_fit(Demonstration(t=d.t, human=d.human))
        assert (u.created, u.updated, u.merged, u.deleted) == (v.created, v.updated, v.merged, v.deleted)
    h = human_only.n_human
    assert h == with_robot.n_human == 30
    for a, b in zip(with_robot.components, human_only.components):
        assert b.mean.shape == (h,) and a.mean.shape == (h + 140,)
        np.testing.assert_allclose(b.mean, a.mean_gating, rtol=0, atol=1e-12)
        np.testing.assert_allclose(b.cov, a.cov_gating, rtol=0, atol=1e-12)
        assert (a.id, a.age, a.support) == (b.id, b.age, pytest.approx(b.support, abs=1e-12))
    with pytest.raises(ValueError, match="human-only"):
        human_only.predict_robot(demos[0].human)


def test_components_view_is_read_only():
    lib = _taught_library(tasks=(0,))
    c = lib.components[0]
    with pytest.raises(ValueError):
        c.mean[0] = 1.0
    assert sum(c.weight for c in lib.components) == pytest.approx(1.0)


def test_config_rejects_bad_values_and_round_trips():
    with pytest.raises(ValueError, match="novelty_test"):
        LibraryConfig(novelty_test="magic")
    with pytest.raises(ValueError, match="gating_floor"):
        LibraryConfig(gating_floor=0.0)
    with pytest.raises(ValueError, match="novelty_quantile"):
        LibraryConfig(novelty_quantile=1.0)
    cfg = LibraryConfig(n_basis_human=12)
    assert LibraryConfig.from_dict(cfg.dict()) == cfg


def test_loglik_novelty_test_also_separates_skills():
    lib = _taught_library(n_per_task=6, tasks=(0, 1, 2), novelty_test="loglik")
    assert lib.n_components == 3


def test_incremental_update_forgets_fast_by_default_and_caps_gamma_tilde_at_1():
    rng = np.random.default_rng(12)
    mean, cov, w = rng.standard_normal(3), np.eye(3), rng.standard_normal(3)
    default = incremental_update(mean, cov, 2.0, w, 0.5)
    fast = incremental_update(mean, cov, 2.0, w, 0.5, fast_forgetting=True)
    for a, b in zip(default, fast):
        np.testing.assert_array_equal(a, b)
    s, gamma = 2.5, 0.5 / 2.5
    gamma_t = gamma + np.exp(-s) * 0.5
    e = w - mean
    np.testing.assert_allclose(fast[1], (1 - gamma_t) * cov + gamma_t * (1 - gamma) * np.outer(e, e), rtol=1e-12)
    # support 0.1 and lambda 1: gamma + exp(-1.1) = 0.91 + 0.33 > 1, capped: Sigma_init is forgotten entirely
    m2, c2, s2, g2 = incremental_update(mean, cov, 0.1, w, 1.0)
    assert s2 == pytest.approx(1.1) and g2 == pytest.approx(1.0 / 1.1)
    np.testing.assert_allclose(c2, (1 - g2) * np.outer(e, e), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(m2, mean + g2 * e, rtol=1e-12)
