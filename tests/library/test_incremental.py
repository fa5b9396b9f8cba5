"""SkillLibrary: Algorithm 1 (Eqs. 5-12) on synthetic coupled demonstrations."""

import numpy as np
import pytest

from drake_skills import Demonstration, LibraryConfig, SkillLibrary
from drake_skills.library import algorithm
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


def test_covariances_stay_symmetric_positive_definite_over_5000_updates():
    rng = np.random.default_rng(9)
    # a tight Sigma_init and floor make duplicates (and so merges) common
    cfg = LibraryConfig(n_samples=30, n_basis_human=6, n_basis_robot=6, sigma_init_human=0.3, gating_floor=0.05,
                        merge_min_age=3, delete_min_age=40)
    lib = SkillLibrary(cfg)
    worst = np.inf
    for i in range(5000):
        r = rng.random()
        if r < 0.1:  # outlier: a random wiggly motion
            T = 30
            human = np.cumsum(rng.normal(0, 1.0, (T, 3)), axis=0)
            d = Demonstration(t=np.linspace(0, 1, T), human=human, robot=rng.normal(0, 0.5, (T, 7)))
        else:
            d = synthetic_demo(int(rng.integers(4)), rng, T=30, noise=rng.choice([0.1, 0.8]))
        lib.partial_fit(d)
        if i % 250 == 0 or i == 4999:
            for c in lib.components:
                assert np.array_equal(c.cov, c.cov.T)
                worst = min(worst, np.linalg.eigvalsh(c.cov).min())
                assert worst > 0, f"component {c.id} lost definiteness at update {i}"
    events = {e["event"] for e in lib.history}
    assert {"created", "merged", "deleted"} <= events, events


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
    monkeypatch.setattr(algorithm, "incremental_update", boom)
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


def test_human_only_library_shares_gating_and_expert():
    rng = np.random.default_rng(11)
    lib = SkillLibrary()
    for i in range(10):
        lib.partial_fit(synthetic_demo(i % 2, rng, robot=False))
    c = lib.components[0]
    assert c.mean.shape == (lib.n_human,)
    np.testing.assert_array_equal(c.mean_gating, c.mean)
    with pytest.raises(ValueError, match="human-only"):
        lib.predict_robot(synthetic_demo(0, rng, robot=False).human)


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


def test_state_snapshot_rebuilds_a_library_that_answers_and_learns_identically():
    lib = _taught_library(tasks=(0, 1, 2), merge_min_age=2)
    state = lib.state()
    copy = SkillLibrary.from_state(state)
    assert copy.state().next_id == state.next_id and copy.history == lib.history
    rng = np.random.default_rng(12)
    for task in (0, 1, 2, 3):
        h = synthetic_demo(task, rng).human
        a, b = lib.recognize(h), copy.recognize(h)
        assert a.component == b.component
        np.testing.assert_array_equal(a.log_likelihoods, b.log_likelihoods)
    demo = synthetic_demo(1, rng)
    assert lib.partial_fit(demo) == copy.partial_fit(demo)
    for c, d in zip(lib.components, copy.components):
        np.testing.assert_array_equal(c.cov, d.cov)


def test_state_is_a_read_only_snapshot_that_later_learning_does_not_change():
    lib = _taught_library(tasks=(0, 1))
    state = lib.state()
    means = [np.array(c.mean) for c in state.components]
    with pytest.raises(ValueError):
        state.components[0].mean[0] = 1.0
    lib.partial_fit(synthetic_demo(0, np.random.default_rng(13)))
    assert state.n_seen == lib.n_seen - 1
    for c, m in zip(state.components, means):
        np.testing.assert_array_equal(c.mean, m)


def test_library_state_rejects_inconsistent_components():
    from dataclasses import replace

    state = _taught_library(tasks=(0, 1)).state()
    c0, c1 = state.components[:2]
    with pytest.raises(ValueError, match="duplicated"):
        replace(state, components=(c0, replace(c1, id=c0.id)))
    with pytest.raises(ValueError, match="shapes"):
        replace(state, components=(replace(c0, mean=c0.mean[:-1]),))
    with pytest.raises(ValueError, match="positive definite"):
        replace(state, components=(replace(c0, cov=-np.eye(state.n_weights)),))


def test_encode_gives_the_gating_weights_first_then_the_robot_weights():
    lib = _taught_library(tasks=(0,))
    demo = synthetic_demo(0, np.random.default_rng(14))
    w = lib.encode(demo)
    cfg = lib.config
    assert w.shape == (3 * cfg.n_basis_human + 7 * cfg.n_basis_robot,)
    from drake_skills.promp.basis import ridge_weights

    np.testing.assert_array_equal(w[:lib.n_human], ridge_weights(lib.human_samples(demo.human), cfg.basis_human,
                                                                 cfg.ridge))
    with pytest.raises(ValueError, match="Demonstration"):
        lib.encode(demo.human)


def test_normalized_samples_are_only_resampled():
    from drake_skills.data.workspace import Workspace

    ws = Workspace(np.array([-8.0, -8.0, -8.0]), np.array([8.0, 8.0, 8.0]))
    rng = np.random.default_rng(15)
    lib = SkillLibrary()
    for i in range(9):
        lib.partial_fit(synthetic_demo(i % 3, rng), workspace=ws)
    h = synthetic_demo(2, rng).human
    y = ws.normalize(h, subtract_start=True)
    a, b = lib.recognize(h, workspace=ws), lib.recognize(y, normalized=True)
    assert a.component == b.component
    np.testing.assert_array_equal(a.log_likelihoods, b.log_likelihoods)
    np.testing.assert_array_equal(lib.predict_robot(h, workspace=ws)[0], lib.predict_robot(y, normalized=True)[0])
    half = y[: len(y) // 2]
    np.testing.assert_array_equal(lib.recognize(h[: len(h) // 2], observed_fraction=0.5, workspace=ws).mahalanobis_sq,
                                  lib.recognize(half, observed_fraction=0.5, normalized=True).mahalanobis_sq)
    with pytest.raises(ValueError, match="no workspace"):
        lib.recognize(y, normalized=True, workspace=ws)


def test_the_novelty_rule_is_chosen_in_one_place_and_can_be_swapped():
    from drake_skills.library.algorithm import ComponentModel, fold_in
    from drake_skills.library.novelty import Chi2Rule, LogLikRule, novelty_rule

    assert isinstance(novelty_rule(LibraryConfig()), Chi2Rule)
    assert isinstance(novelty_rule(LibraryConfig(novelty_test="loglik")), LogLikRule)

    class EverythingIsNovel:
        def novel(self, log_likelihoods, mahalanobis_sq, dof):
            return np.ones(len(mahalanobis_sq), bool)

        def merge_scores(self, mahalanobis_sq, support, chol):
            return np.full(len(mahalanobis_sq), np.inf)

    lib = _taught_library(tasks=(0,))
    comps = [ComponentModel.of(c, lib.n_human, lib.config.gating_floor) for c in lib.state().components]
    w = lib.encode(synthetic_demo(0, np.random.default_rng(16)))
    kw = dict(n_human=lib.n_human, config=lib.config, next_id=lib.state().next_id, demo_index=lib.n_seen)
    assert fold_in(comps, w, 1.0, **kw).created == ()  # the default rule: the same skill again
    step = fold_in(comps, w, 1.0, rule=EverythingIsNovel(), **kw)
    assert step.created == (kw["next_id"],) and len(step.components) == len(comps) + 1
