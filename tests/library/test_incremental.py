"""SkillLibrary: Algorithm 1 (Eqs. 5-12) on the learned shared scale, on synthetic coupled demonstrations."""

from dataclasses import replace

import numpy as np
import pytest

from drake_skills import Demonstration, LibraryConfig, SkillLibrary
from drake_skills.library import algorithm, scale as scale_mod
from drake_skills.library.algorithm import ComponentModel, Components, Metric, fold_in, within_share
from drake_skills.library.incremental import UnknownSkillError
from drake_skills.library.novelty import Chi2Rule, LogLikRule, chi2_ppf, novelty_rule
from drake_skills.library.scale import Cluster, SharedScale, gating_covariance, shared_covariance

from synthetic import synthetic_demo


def _taught_library(n_per_task=6, tasks=(0, 1, 2), seed=0, **cfg):
    rng = np.random.default_rng(seed)
    lib = SkillLibrary(LibraryConfig(**cfg))
    order = [t for _ in range(n_per_task) for t in tasks]
    for i in rng.permutation(len(order)):
        lib.partial_fit(synthetic_demo(order[i], rng))
    return lib


# ---------------------------------------------------------------- moments and the scale
def test_cluster_add_equals_exact_weighted_moments():
    """Adding samples one by one (weights lam) gives the weighted mean and scatter of all of them."""
    rng = np.random.default_rng(0)
    d = 4
    W = rng.standard_normal((30, d)) @ rng.standard_normal((d, d))
    lam = rng.uniform(0.05, 1.0, 30)
    lam[0] = 1.0
    cl = Cluster.of_sample(W[0], 2.0, 5.0)
    scatter = np.zeros((d, d))
    for w, l in zip(W[1:], lam[1:]):
        cl, g = cl.add(w, float(l), 2.0, 5.0)
        scatter += np.outer(g, g)
    mu_ref = np.average(W, axis=0, weights=lam)
    diff = W - mu_ref
    S_ref = (lam[:, None] * diff).T @ diff
    assert cl.support == pytest.approx(lam.sum(), rel=1e-12)
    np.testing.assert_allclose(cl.mean, mu_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(cl.scatter, S_ref, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(scatter, S_ref, rtol=1e-9, atol=1e-10)  # the increments sum to the scatter
    assert cl.factor.shape[1] <= d  # compressed, not one column per sample


@pytest.mark.parametrize("case", ["triangular", "triangular, rank-deficient", "square, not triangular", "wide"])
def test_a_compressed_factor_keeps_the_scatter_and_is_lower_triangular(case):
    """``scale._compress``: a full lower-triangular factor plus one column (the Givens path every update takes
    once a cluster has more members than dimensions) and any other factor (the QR path) give a d-column lower-
    triangular factor of the same scatter F F^T."""
    rng = np.random.default_rng(3)
    d = 6
    if case.startswith("triangular"):
        L = np.tril(rng.standard_normal((d, d)))
        if "deficient" in case:
            L[:, 2] = 0.0
        F = np.column_stack([L, rng.standard_normal(d)])
    elif case == "square, not triangular":
        F = np.column_stack([rng.standard_normal((d, d)), rng.standard_normal(d)])
    else:
        F = rng.standard_normal((d, 3 * d))
    C = scale_mod._compress(F)
    assert C.shape == (d, d) and not np.triu(C, 1).any()
    np.testing.assert_allclose(C @ C.T, F @ F.T, rtol=1e-12, atol=1e-12)


def test_cluster_pool_equals_moments_of_the_union():
    """The corrected Eq. (11): pooling two clusters gives the support, mean and scatter of all their samples."""
    rng = np.random.default_rng(2)
    A, B = rng.normal(0, 1, (40, 3)), rng.normal(2, 0.5, (15, 3))

    def cluster(X, dur):
        c = Cluster.of_sample(X[0], dur, 2 * dur)
        for x in X[1:]:
            c = c.add(x, 1.0, dur, 2 * dur)[0]
        return c

    a, b = cluster(A, 1.0), cluster(B, 3.0)
    p, g = a.pool(b)
    P = np.vstack([A, B])
    assert p.support == 55.0
    np.testing.assert_allclose(p.mean, P.mean(0), atol=1e-12)
    np.testing.assert_allclose(p.scatter, (P - P.mean(0)).T @ (P - P.mean(0)), rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(a.scatter + b.scatter + np.outer(g, g), p.scatter, rtol=1e-10, atol=1e-10)
    assert p.duration == pytest.approx((40 * 1.0 + 15 * 3.0) / 55) and p.path_length == pytest.approx(2 * p.duration)


def test_shared_covariance_is_the_scale_free_prior_until_scatter_is_pooled():
    """No pooled scatter: Sigma = rho^2 x (mean variance of all demos) per block, shrunk; then the pool takes over."""
    rng = np.random.default_rng(3)
    h, d = 4, 6
    sc = SharedScale.empty(d)
    X = rng.normal(0, 3.0, (50, d)) * np.array([1, 1, 1, 1, 10, 10])
    for x in X:
        sc = sc.count(x)
    var = X.var(axis=0)
    np.testing.assert_allclose(sc.total_m2 / sc.n, var, rtol=1e-10)
    kw = dict(prior_scale=0.5, prior_strength=2.0, shrinkage=0.3)
    S = shared_covariance(sc, h, **kw)
    np.testing.assert_allclose(np.diag(S)[:h], 0.25 * var[:h].mean(), rtol=1e-6)
    np.testing.assert_allclose(np.diag(S)[h:], 0.25 * var[h:].mean(), rtol=1e-6)
    np.testing.assert_allclose(gating_covariance(sc, h, **kw), S[:h, :h], rtol=1e-12)
    # a lot of pooled within-skill scatter, prior_strength 2: the pool dominates
    R = rng.normal(0, 0.1, (2000, d))
    sc2 = sc.with_scatter(R.T, +1.0, 2000.0)
    S2 = shared_covariance(sc2, h, prior_scale=0.5, prior_strength=2.0, shrinkage=0.0)
    np.testing.assert_allclose(S2, (R.T @ R + 2.0 * np.diag(np.r_[[0.25 * var[:h].mean()] * h,
                                                                   [0.25 * var[h:].mean()] * 2])) / 2002,
                               rtol=1e-6, atol=1e-9)
    assert np.linalg.eigvalsh(S2).min() > 0


def test_shrinkage_keeps_the_shared_covariance_positive_definite_from_one_pooled_deviation():
    sc = SharedScale.empty(30).count(np.zeros(30)).count(np.ones(30))
    sc = sc.with_scatter(np.arange(30.0), +1.0, 1.0)  # rank one
    S = shared_covariance(sc, 21, prior_scale=0.3, prior_strength=2.0, shrinkage=0.3)
    assert np.linalg.eigvalsh(S).min() > 0 and np.allclose(S, S.T)


# ---------------------------------------------------------------- learning
def test_partial_fit_creates_component_for_novel_demo():
    rng = np.random.default_rng(3)
    lib = SkillLibrary()
    u0 = lib.partial_fit(synthetic_demo(0, rng))
    assert u0.created == (0,) and u0.recognized is None
    u1 = lib.partial_fit(synthetic_demo(0, rng))
    u2 = lib.partial_fit(synthetic_demo(0, rng))
    assert u2.created == () and u2.recognized is not None and u2.updated
    u3 = lib.partial_fit(synthetic_demo(2, rng))
    assert u3.created and u3.recognized is None
    assert [e["event"] for e in lib.history].count("created") == len(u0.created + u1.created + u2.created +
                                                                      u3.created)


def test_library_finds_one_component_per_skill_and_recognizes_them():
    lib = _taught_library(n_per_task=8, tasks=(0, 1, 2, 3))
    assert lib.n_components == 4
    rng = np.random.default_rng(99)
    owners = {}
    for task in range(4):
        for _ in range(5):
            rec = lib.recognize(synthetic_demo(task, rng).human, observed_fraction=1.0)
            assert rec.status == "skill" and rec.component is not None
            owners.setdefault(task, set()).add(rec.component)
            assert rec.responsibilities.sum() == pytest.approx(1.0, abs=1e-12)
            assert rec.posterior.max() >= 1 - lib.config.decision_risk
    assert all(len(v) == 1 for v in owners.values())
    assert len(set.union(*owners.values())) == 4


def test_recognize_answers_unknown_for_a_motion_never_shown():
    lib = _taught_library(tasks=(0, 1))
    rng = np.random.default_rng(4)
    for fraction in (1.0, None):
        rec = lib.recognize(synthetic_demo(3, rng).human, observed_fraction=fraction)
        assert rec.component is None and rec.unknown and rec.status == "unknown"
        assert np.isnan(rec.phase) and rec.confidence == 0.0
    with pytest.raises(UnknownSkillError, match="no skill"):
        lib.predict_robot(synthetic_demo(3, rng).human)


def test_novelty_is_the_chi2_quantile_of_the_predictive_distance():
    """A motion is unknown exactly when its distance under Sigma (1 + 1/s) exceeds chi2(q, h) for every component."""
    lib = _taught_library(tasks=(0, 1))
    rng = np.random.default_rng(40)
    h = lib.n_human
    thr = chi2_ppf(lib.config.novelty_quantile, h)
    S = lib.shared_covariance()
    for c in lib.components:
        np.testing.assert_allclose(c.cov_gating, S * (1 + 1 / c.support), rtol=1e-12)
    for task in (0, 1, 3):
        human = synthetic_demo(task, rng).human
        rec = lib.recognize(human, observed_fraction=1.0)
        w = lib.encode(Demonstration(t=np.linspace(0, 1, len(human)), human=human))[:h]
        for c, d2 in zip(lib.components, rec.mahalanobis_sq):
            e = w - c.mean_gating
            assert d2 == pytest.approx(e @ np.linalg.solve(c.cov_gating, e), rel=1e-9)
        assert rec.unknown == bool((rec.mahalanobis_sq > thr).all())
        assert rec.unknown == (task == 3)


def test_predict_robot_follows_the_observed_human():
    lib = _taught_library(n_per_task=20, tasks=(0, 1, 2))
    rng = np.random.default_rng(5)
    errs, prior_errs = [], []
    for task in (0, 1, 2) * 3:
        d = synthetic_demo(task, rng, noise=0.4)
        mean, cov = lib.predict_robot(d.human, 1.0)
        assert mean.shape == (100, 7) and cov.shape == (100, 7, 7)
        k = lib.recognize(d.human, observed_fraction=1.0).component
        prior = lib.component(k).mean[lib.n_human:].reshape(7, -1)
        prior_end = lib.config.basis_robot.phi_uniform(100)[-1] @ prior.T
        errs.append(np.abs(mean[-1] - d.robot[-1]).max())
        prior_errs.append(np.abs(prior_end - d.robot[-1]).max())
    # the robot's end pose depends on the human's goal (goal noise 0.4 -> about 0.05 rad);
    # conditioning on the human recovers most of it from 20 demonstrations per skill
    assert max(errs) < 0.04, errs
    assert np.mean(errs) < 0.5 * np.mean(prior_errs), (np.mean(errs), np.mean(prior_errs))


def _cut(human, fraction):
    step = np.linalg.norm(np.diff(human, axis=0), axis=1)
    return human[:int(np.searchsorted(np.cumsum(step), fraction * step.sum())) + 1]


def test_prefix_recognition_and_prediction_with_a_given_fraction():
    lib = _taught_library(n_per_task=8, tasks=(0, 1, 2))
    rng = np.random.default_rng(6)
    d = synthetic_demo(1, rng)
    full = lib.recognize(d.human, observed_fraction=1.0).component
    rec = lib.recognize(_cut(d.human, 0.5), observed_fraction=0.5)
    assert rec.component == full
    mean, _ = lib.predict_robot(_cut(d.human, 0.5), observed_fraction=0.5)
    assert np.abs(mean[-1] - d.robot[-1]).max() < 0.1


def test_phase_is_estimated_from_a_prefix_within_0_1():
    """Without observed_fraction the library estimates how much of the skill's path the prefix covers."""
    lib = _taught_library(n_per_task=8, tasks=(0, 1, 2))
    rng = np.random.default_rng(60)
    for task in (0, 1, 2):
        d = synthetic_demo(task, rng)
        for f in (0.3, 0.6, 1.0):
            rec = lib.recognize(_cut(d.human, f))
            assert rec.status == "skill", (task, f, rec.status)
            assert rec.component == lib.recognize(d.human, observed_fraction=1.0).component
            assert abs(rec.phase - f) < 0.1, (task, f, rec.phase)
        mean, _ = lib.predict_robot(_cut(d.human, 0.6))
        assert np.abs(mean[-1] - d.robot[-1]).max() < 0.1


def _twins(robot_shift: float):
    """A library of one skill and a twin of it: human mean moved 0.6 sigma per weight, robot mean moved ``robot_shift``."""
    lib = _taught_library(n_per_task=4, tasks=(0,))
    st = lib.state()
    c = st.components[0]
    h = lib.n_human
    shift = np.zeros(st.n_weights)
    shift[:h] = 0.6 * np.sqrt(np.diag(lib.shared_covariance()))
    shift[h:] = robot_shift
    twin_cl = replace(c.cluster, mean=c.cluster.mean + shift)
    twin = replace(c, id=st.next_id, cluster=twin_cl, subclusters=(twin_cl, None))
    lib2 = SkillLibrary.from_state(replace(st, components=(c, twin), next_id=st.next_id + 1))
    probe = lib2.components[0].mean[:h] + 0.5 * shift[:h]  # half-way between the two
    y = lib2.config.basis_human.phi_uniform(100) @ probe.reshape(3, -1).T
    return lib2, y


def test_a_motion_between_two_skills_that_answer_differently_is_undecided_not_guessed():
    """Half-way between two components, neither is 99 % probable: "undecided", no component, no prediction."""
    lib, y = _twins(robot_shift=0.5)
    rec = lib.recognize(y, observed_fraction=1.0, normalized=True)
    assert rec.status == "undecided" and rec.component is None and rec.best is not None
    assert rec.posterior.max() < 1 - lib.config.decision_risk
    assert rec.posterior.sum() == pytest.approx(1.0)
    with pytest.raises(UnknownSkillError, match="more than one"):
        lib.predict_robot(y, 1.0, normalized=True)


def test_components_that_answer_alike_count_together_in_the_decision():
    """The same two components, but with the same robot response: executing the best one is safe."""
    lib, y = _twins(robot_shift=0.0)
    rec = lib.recognize(y, observed_fraction=1.0, normalized=True)
    assert rec.posterior.max() < 1 - lib.config.decision_risk  # split between the two ...
    assert rec.status == "skill" and rec.component == rec.best  # ... but they answer alike


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


def test_deletion_age_grows_with_the_number_of_components():
    """With K > 5 components the age limit is delete_min_age K / 5 (here 5 x 10 / 5 = 10), not delete_min_age."""
    cfg = LibraryConfig(delete_min_age=5)
    comps, scale = _crafted(10, spread=100.0)
    rule = novelty_rule(cfg)
    w = comps.items[0].cluster.mean.copy()
    kw = dict(n_human=3, config=cfg, rule=rule, next_id=10)
    young = fold_in(comps, scale, w, 1.0, 1.0, demo_index=7, **kw)  # ages 8: past 5, not past 10
    assert young.deleted == () and len(young.components) == 10
    old = fold_in(comps, scale, w, 1.0, 1.0, demo_index=10, **kw)  # ages 11
    assert set(old.deleted) == set(range(1, 10))  # component 0 got the demonstration: support 2 survives
    assert [c.id for c in old.components.items] == [0]


def _crafted(K, spread=100.0, d=3, support=1.0, seed=0):
    """K singleton components far apart (``spread``), with a shared scale of unit within-skill scatter."""
    rng = np.random.default_rng(seed)
    means = rng.normal(0, spread, (K, d))
    items = []
    for k in range(K):
        cl = Cluster(support, means[k], np.zeros((d, 0)), 1.0, 1.0)
        items.append(ComponentModel(k, 0, cl, (cl, None)))
    sc = SharedScale.empty(d)
    for m in means:
        sc = sc.count(m)
    sc = sc.with_scatter(np.sqrt(1000.0) * np.eye(d), +1.0, 1000.0)  # within-skill variance ~1 per weight
    return Components.of(items, d), sc


def test_merge_pools_the_moments_and_supports_of_both_components():
    """Two components of one skill whose means come within the merge threshold are pooled exactly (Eq. 11)."""
    cfg = LibraryConfig(prior_strength=1e-6, shrinkage=0.0)
    d = 3
    a = Cluster(3.0, np.array([0.0, 0.0, 0.0]), np.diag([1.0, 2.0, 0.5]), 2.0, 4.0)
    b = Cluster(2.0, np.array([0.9, -0.6, 0.3]), np.diag([0.7, 0.2, 1.0]), 3.0, 6.0)
    items = [ComponentModel(0, 0, a, (a, None)), ComponentModel(1, 1, b, (b, None))]
    sc = SharedScale.empty(d).count(np.zeros(d)).count(np.ones(d))
    sc = sc.with_scatter(np.sqrt(500.0) * np.eye(d), +1.0, 500.0)
    w = a.mean.copy()  # a demonstration at a's mean updates a (and b), then the pair merges
    step = fold_in(Components.of(items, d), sc, w, 2.0, 4.0, n_human=d, config=cfg, rule=novelty_rule(cfg),
                   next_id=2, demo_index=5)
    assert step.merged and step.merged[0][0] == 0
    (c,) = step.components.items
    # the pooled moments of everything both absorbed: a, b and the new demonstration
    lam = step.responsibilities
    parts = [a.add(w, lam[0], 2.0, 4.0)[0], b.add(w, lam[1], 2.0, 4.0)[0]] if lam[1] >= 1e-3 else \
        [a.add(w, lam[0], 2.0, 4.0)[0], b]
    ref = parts[0].pool(parts[1])[0]
    assert c.support == pytest.approx(ref.support, rel=1e-12)
    assert c.support == pytest.approx(3.0 + 2.0 + sum(v for v in lam.values() if v >= 1e-3), rel=1e-12)
    np.testing.assert_allclose(c.cluster.mean, ref.mean, atol=1e-12)
    np.testing.assert_allclose(c.cluster.scatter, ref.scatter, rtol=1e-10, atol=1e-10)
    # it remembers the two it came from, and the pooled scatter gained the between term
    assert c.subclusters[1] is not None
    assert step.scale.dof == pytest.approx(sc.dof + sum(v for v in lam.values() if v >= 1e-3) + 1.0)


def _cluster_of(points: np.ndarray) -> Cluster:
    """The exact moments of ``points`` (n, d) as a Cluster (scatter factor: its Cholesky factor)."""
    mean = points.mean(axis=0)
    scatter = (points - mean).T @ (points - mean)
    return Cluster(float(len(points)), mean, np.linalg.cholesky(scatter), 1.0, 1.0)


def test_within_share_tells_two_skills_from_one_cut_in_half():
    """``within_share``: a Gaussian cut at its mean keeps 1 - 2/pi of its spread along the cut's normal
    within the halves, two equal Gaussians D standard deviations apart 1 / (1 + D^2 / 4), both in any
    metric's whitened units; one demonstration per half 0, identical means 1."""
    rng = np.random.default_rng(0)
    d, n = 4, 40000
    A = rng.normal(size=(d, d)) + 2 * np.eye(d)
    cov = A @ A.T
    metric = Metric.of(cov)
    x = rng.multivariate_normal(np.zeros(d), cov, n)
    z = metric.whiten(x)
    side = z[:, 0] > 0   # cut at the mean, normal to a whitened axis
    share = within_share(_cluster_of(x[side]), _cluster_of(x[~side]), metric, d)
    assert share == pytest.approx(1 - 2 / np.pi, abs=0.01)
    # two skills 4 standard deviations apart along a whitened direction (the default's bound, 0.2)
    for D, expected in ((4.0, 0.2), (8.0, 1 / 17)):
        shift = metric.chol @ np.array([D, 0.0, 0.0, 0.0])
        half = rng.multivariate_normal(np.zeros(d), cov, (2, n // 2))
        share = within_share(_cluster_of(half[0]), _cluster_of(half[1] + shift), metric, d)
        assert share == pytest.approx(expected, rel=0.03)
    one, other = Cluster.of_sample(np.zeros(d), 1.0, 1.0), Cluster.of_sample(np.ones(d), 1.0, 1.0)
    assert within_share(one, other, metric, d) == 0.0
    assert within_share(one, Cluster.of_sample(np.zeros(d), 1.0, 1.0), metric, d) == 1.0


def test_a_skill_shown_150_times_is_not_split_in_two():
    """Each demonstration joins the nearer of its component's two sub-clusters, so the halves' two-sample
    distance grows with the support even when the skill is one Gaussian: without the within-share test
    two synthetic skills shown 150 times each split into 4-6 components, with it they stay 2."""
    from drake_skills.benchmarks.library import _demo, _skill_bank

    def components(share):
        rng = np.random.default_rng(1)
        bank = _skill_bank(2, rng)
        lib = SkillLibrary(LibraryConfig(n_basis_human=7, n_basis_robot=5, split_within_share=share))
        for n in range(300):
            lib.partial_fit(_demo(bank, n % 2, rng))
        return lib.n_components, [e["within"] for e in lib.history if e["event"] == "split"]

    n_old, shares = components(1.0)   # the distance test alone
    assert n_old >= 4 and len(shares) >= 2 and min(shares) > 0.25   # halves of one skill, not two skills
    assert components(0.2) == (2, [])


def test_consolidation_makes_a_merge_harder_as_support_grows():
    rule = Chi2Rule(0.999, 0.999, 0.9999, consolidation=0.5)
    d2 = np.array([10.0])
    assert rule.merge_scores(d2, np.array([4.0]), np.array([1.0]), 0.0, 3)[0] > \
        rule.merge_scores(d2, np.array([1.0]), np.array([1.0]), 0.0, 3)[0]
    ll = LogLikRule(-60.0, -20.0, 0.9999, consolidation=0.5)
    assert ll.merge_scores(d2, np.array([4.0]), np.array([1.0]), 0.0, 3)[0] > \
        ll.merge_scores(d2, np.array([1.0]), np.array([1.0]), 0.0, 3)[0]
    # and a closer pair always scores lower
    assert rule.merge_scores(np.array([1.0]), np.array([1.0]), np.array([1.0]), 0.0, 3)[0] < \
        rule.merge_scores(d2, np.array([1.0]), np.array([1.0]), 0.0, 3)[0]


def test_a_component_whose_halves_drift_apart_splits_into_them():
    """A merge made on a too-wide scale is undone once the scale is small: the halves become components again."""
    cfg = LibraryConfig()
    d = 3
    a = Cluster(4.0, np.array([0.0, 0.0, 0.0]), 0.1 * np.eye(d), 1.0, 2.0)
    b = Cluster(3.0, np.array([30.0, 0.0, 0.0]), 0.1 * np.eye(d), 3.0, 6.0)
    merged = a.pool(b)[0]
    items = [ComponentModel(0, 0, merged, (a, b))]
    sc = SharedScale.empty(d).count(np.zeros(d)).count(np.array([30.0, 0.0, 0.0]))
    sc = sc.with_scatter(merged.factor, +1.0, merged.support - 1.0)
    sc = sc.with_scatter(np.sqrt(200.0) * np.eye(d), +1.0, 200.0)  # elsewhere: a small within-skill scatter
    w = merged.mean.copy()  # updates the merged component; it joins the nearer half, a
    step = fold_in(Components.of(items, d), sc, w, 1.0, 2.0, n_human=d, config=cfg, rule=novelty_rule(cfg),
                   next_id=1, demo_index=10)
    assert step.updated == (0,) and step.subcluster == {0: 0}
    assert step.split == ((0, 1),)
    kept, new = step.components.items
    assert kept.id == 0 and new.id == 1 and kept.support + new.support == pytest.approx(8.0)
    np.testing.assert_allclose(new.cluster.mean, b.mean)
    ref = a.add(w, 1.0, 1.0, 2.0)[0]
    np.testing.assert_allclose(kept.cluster.mean, ref.mean)
    np.testing.assert_allclose(kept.cluster.scatter, ref.scatter, atol=1e-12)
    assert new.cluster.duration == 3.0 and new.subclusters == (new.cluster, None)
    (event,) = [e for e in step.history if e["event"] == "split"]
    # the halves, 30 apart against a scatter of 0.01 per axis, lie apart as two skills do
    assert {k: event[k] for k in ("id", "new", "demo")} == {"id": 0, "new": 1, "demo": 10}
    assert 0.0 < event["within"] <= cfg.split_within_share
    assert step.scale.dof == pytest.approx(sc.dof + 1.0 - 1.0)  # +1 the update, -1 the split


def test_covariances_stay_symmetric_positive_definite_over_500_updates():
    rng = np.random.default_rng(9)
    cfg = LibraryConfig(n_samples=30, n_basis_human=6, n_basis_robot=6, delete_min_age=10)
    lib = SkillLibrary(cfg)
    for i in range(500):
        r = rng.random()
        if r < 0.1:  # outlier: a random wiggly motion
            T = 30
            human = np.cumsum(rng.normal(0, 1.0, (T, 3)), axis=0)
            d = Demonstration(t=np.linspace(0, 1, T), human=human, robot=rng.normal(0, 0.5, (T, 7)))
        else:
            d = synthetic_demo(int(rng.integers(4)), rng, T=30, noise=rng.choice([0.1, 0.8]))
        lib.partial_fit(d)
        if i % 50 == 0 or i == 499:
            S = lib.shared_covariance("expert")
            assert np.allclose(S, S.T) and np.linalg.eigvalsh(S).min() > 0
            for c in lib.components:
                assert np.allclose(c.cov, c.cov.T)
                assert np.linalg.eigvalsh(c.cov).min() > 0, f"component {c.id} lost definiteness at update {i}"
    events = {e["event"] for e in lib.history}
    assert {"created", "deleted"} <= events, events


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

    monkeypatch.setattr(algorithm, "gating_covariance", boom)
    with pytest.raises(np.linalg.LinAlgError):
        lib.partial_fit(synthetic_demo(0, rng))
    after = tmp_path / "after.npz"
    lib.save(after)
    assert before.read_bytes() == after.read_bytes()


@pytest.mark.parametrize("part", ["robot", "human"])
def test_an_update_that_overflows_is_refused_naming_the_demo_and_changes_nothing(tmp_path, part):
    # finite values so large that the scale's sums of squares overflow (found by a cold review: the
    # library took them and could never be saved again)
    import warnings

    lib = _taught_library(tasks=(0, 1))
    before = tmp_path / "before.npz"
    lib.save(before)
    good = synthetic_demo(0, np.random.default_rng(11))
    huge = Demonstration(t=good.t, human=good.human * (1e160 if part == "human" else 1.0),
                         robot=good.robot * (1e160 if part == "robot" else 1.0), name="huge.npz")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no overflow warning escapes either
        with pytest.raises(ValueError, match=r"demo 'huge.npz': .*too large"):
            lib.partial_fit(huge, check_units=False)  # the overflow check itself (the units check refuses it first)
    after = tmp_path / "after.npz"
    lib.save(after)
    assert before.read_bytes() == after.read_bytes()
    lib.partial_fit(synthetic_demo(0, np.random.default_rng(12)))  # and it still learns
    assert lib.n_seen == 13


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
    with pytest.raises(ValueError, match="does not move"):
        lib.recognize(np.zeros((20, 3)))
    with pytest.raises(ValueError, match="not fitted"):
        SkillLibrary().recognize(np.random.rand(20, 3))
    with pytest.raises(ValueError, match="Demonstration"):
        lib.partial_fit(np.random.rand(20, 3))
    # a cold review found n_steps=0 giving 100 steps and 2.5 giving 2
    human = synthetic_demo(0, np.random.default_rng(3)).human
    for bad in (0, 1, 2.5, True, "10", float("nan"), float("inf"), [10]):
        with pytest.raises(ValueError, match="n_steps must be an integer >= 2"):
            lib.predict_robot(human, observed_fraction=1.0, n_steps=bad)
    assert lib.predict_robot(human, observed_fraction=1.0, n_steps=7.0)[0].shape == (7, 7)
    assert lib.predict_robot(human, observed_fraction=1.0, n_steps=2)[0].shape == (2, 7)   # the least


def test_human_only_library_shares_gating_and_expert():
    rng = np.random.default_rng(11)
    lib = SkillLibrary()
    for i in range(10):
        lib.partial_fit(synthetic_demo(i % 2, rng, robot=False))
    c = lib.components[0]
    assert c.mean.shape == (lib.n_human,)
    np.testing.assert_array_equal(c.mean_gating, c.mean)
    assert lib.shared_covariance("expert").shape == (lib.n_human, lib.n_human)
    with pytest.raises(ValueError, match="human-only"):
        lib.predict_robot(synthetic_demo(0, rng, robot=False).human)


def test_components_view_is_read_only():
    lib = _taught_library(tasks=(0,))
    c = lib.components[0]
    with pytest.raises(ValueError):
        c.mean[0] = 1.0
    with pytest.raises(ValueError):
        c.cov[0, 0] = 1.0
    assert sum(c.weight for c in lib.components) == pytest.approx(1.0)


def test_expert_covariance_shrinks_own_scatter_towards_the_shared_one():
    lib = _taught_library(n_per_task=6, tasks=(0,))
    (c,) = lib.components
    model = lib._model(c.id)
    k = lib.config.expert_prior
    np.testing.assert_allclose(c.cov, (k * lib.shared_covariance("expert") + model.cluster.scatter)
                               / (k + c.support - 1), rtol=1e-12)


def test_config_rejects_bad_values_and_round_trips():
    with pytest.raises(ValueError, match="novelty_test"):
        LibraryConfig(novelty_test="magic")
    with pytest.raises(ValueError, match="prior_scale"):
        LibraryConfig(prior_scale=0.0)
    with pytest.raises(ValueError, match="novelty_quantile"):
        LibraryConfig(novelty_quantile=1.0)
    with pytest.raises(ValueError, match="split_quantile"):
        LibraryConfig(merge_quantile=0.9999, split_quantile=0.999)
    with pytest.raises(ValueError, match="shrinkage"):
        LibraryConfig(shrinkage=1.0)
    with pytest.raises(ValueError, match="are gone"):
        LibraryConfig.from_dict({"gating_floor": 1.0})
    with pytest.raises(ValueError, match="unknown"):
        LibraryConfig.from_dict({"magic": 1.0})
    # a cold review found these accepted ("no" acts as true) or refused without the field's name
    for name in ("basis_normalized", "subtract_start", "conditioning_gain", "adapt_to_noise", "average_holds",
                 "keep_single_demos_apart", "skip_false_starts"):
        with pytest.raises(ValueError, match=f"LibraryConfig.{name} must be true or false, got 'no'"):
            LibraryConfig(**{name: "no"})
    for bad in (float("nan"), float("inf"), "x", 4.5, True):
        with pytest.raises(ValueError, match="LibraryConfig.n_samples must be an integer in 4..100000"):
            LibraryConfig(n_samples=bad)
    assert LibraryConfig(n_samples=50.0).n_samples == 50 and LibraryConfig(subtract_start=np.bool_(False)).subtract_start is False
    cfg = LibraryConfig(n_basis_human=12)
    assert LibraryConfig.from_dict(cfg.dict()) == cfg


def test_loglik_novelty_test_also_separates_skills():
    lib = _taught_library(n_per_task=6, tasks=(0, 1, 2), novelty_test="loglik", log_T_nov=-80.0)
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
        assert a.component == b.component and a.status == b.status
        np.testing.assert_array_equal(a.log_likelihoods, b.log_likelihoods)
    demo = synthetic_demo(1, rng)
    assert lib.partial_fit(demo) == copy.partial_fit(demo)
    for c, d in zip(lib.components, copy.components):
        np.testing.assert_array_equal(c.cov, d.cov)
        assert c.age == d.age


def test_state_is_a_read_only_snapshot_that_later_learning_does_not_change():
    lib = _taught_library(tasks=(0, 1))
    state = lib.state()
    means = [np.array(c.mean) for c in state.components]
    lib.partial_fit(synthetic_demo(0, np.random.default_rng(13)))
    assert state.n_seen == lib.n_seen - 1
    for c, m in zip(state.components, means):
        np.testing.assert_array_equal(c.mean, m)


def test_library_state_rejects_inconsistent_components():
    state = _taught_library(tasks=(0, 1)).state()
    c0, c1 = state.components[:2]
    with pytest.raises(ValueError, match="duplicated"):
        replace(state, components=(c0, replace(c1, id=c0.id)))
    with pytest.raises(ValueError, match="shapes"):
        bad = replace(c0.cluster, mean=c0.cluster.mean[:-1])
        replace(state, components=(replace(c0, cluster=bad, subclusters=(bad, None)),))
    with pytest.raises(ValueError, match="sub-clusters"):
        replace(state, components=(replace(c0, subclusters=(replace(c0.cluster, support=0.5, tasks=()), None)),))
    with pytest.raises(ValueError, match="bad task weights"):
        heavy = replace(c0.cluster, tasks=(("0", c0.cluster.support + 1.0),))
        replace(state, components=(replace(c0, cluster=heavy, subclusters=(heavy, None)),))
    with pytest.raises(ValueError, match="age"):
        replace(state, components=(replace(c0, age=state.n_seen + 5),))
    with pytest.raises(ValueError, match="shared scale"):
        replace(state, scale=None)


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


def test_the_same_demonstrations_in_millimetres_give_the_same_library():
    """Units: the workspace normalizes them away, and nothing in the config is a length."""
    from drake_skills.data.workspace import Workspace

    rng = np.random.default_rng(17)
    demos = [synthetic_demo(i % 3, rng) for i in range(18)]
    ws_m = Workspace(np.full(3, -8.0), np.full(3, 8.0))
    ws_mm = Workspace(np.full(3, -8000.0), np.full(3, 8000.0))
    a, b = SkillLibrary(), SkillLibrary()
    for d in demos:
        ua = a.partial_fit(d, workspace=ws_m)
        ub = b.partial_fit(replace(d, human=1000.0 * d.human), workspace=ws_mm)
        assert (ua.created, ua.merged, ua.split) == (ub.created, ub.merged, ub.split)
    for c, e in zip(a.components, b.components):
        np.testing.assert_allclose(c.mean, e.mean, rtol=1e-8, atol=1e-8)


def test_the_novelty_rule_is_chosen_in_one_place_and_can_be_swapped():
    assert isinstance(novelty_rule(LibraryConfig()), Chi2Rule)
    assert isinstance(novelty_rule(LibraryConfig(novelty_test="loglik")), LogLikRule)

    class EverythingIsNovel:
        def novel(self, log_likelihoods, mahalanobis_sq, dof):
            return np.ones(len(mahalanobis_sq), bool)

        def merge_scores(self, mahalanobis_sq, support, inflate, logdet, dof):
            return np.full(len(mahalanobis_sq), np.inf)

        def merge_limit(self, support, logdet, dof):
            return 0.0

        def splits(self, mahalanobis_sq, dof):
            return np.zeros(len(mahalanobis_sq), bool)

    lib = _taught_library(tasks=(0,))
    st = lib.state()
    comps = lib._components
    w = lib.encode(synthetic_demo(0, np.random.default_rng(16)))
    kw = dict(n_human=lib.n_human, config=lib.config, next_id=st.next_id, demo_index=lib.n_seen)
    assert fold_in(comps, st.scale, w, 1.0, 1.0, rule=novelty_rule(lib.config), **kw).created == ()
    step = fold_in(comps, st.scale, w, 1.0, 1.0, rule=EverythingIsNovel(), **kw)
    assert step.created == (kw["next_id"],) and len(step.components) == len(comps) + 1


def test_observation_noise_is_learned_from_what_the_basis_cannot_hold():
    """A wave finer than the basis: the learned noise grows past the floor, and a whole wave recognized with its
    phase estimated is its skill (with the fixed floor of 0.05 its samples looked impossibly far from its own mean)."""
    rng = np.random.default_rng(70)

    def wave(phase):
        t = np.linspace(0, 3, 300)
        y = np.stack([6 * t / 3, 2 * np.sin(2 * np.pi * 3 * t + phase), 0.5 * t], axis=1)
        return Demonstration(t=t, human=y + rng.normal(0, 0.01, y.shape), task="wave")

    lib = SkillLibrary()
    for _ in range(6):
        lib.partial_fit(wave(rng.uniform(-0.3, 0.3)))
    assert lib.observation_noise() > 5 * lib.config.observation_noise
    fits = lib.config.basis_human.phi_uniform(100)
    assert fits.shape == (100, lib.config.n_basis_human)
    rec = lib.recognize(wave(0.1).human)  # whole motion, phase estimated
    assert rec.status == "skill" and rec.phase > 0.9


@pytest.mark.parametrize("bad", [0.0, -0.1, 1.5, float("nan"), True])
def test_split_within_share_outside_0_1_is_refused(bad):
    with pytest.raises(ValueError, match=r"split_within_share must (be in \(0, 1\] \(1: off\)|be a number)"):
        LibraryConfig(split_within_share=bad)


def test_a_few_far_apart_samples_that_read_as_noise_are_refused_with_the_reason_and_the_library_unchanged():
    """Five samples 6-17 units apart: their second differences read as noise of about 4 units per axis, so the
    adapted walk leaves no path. ``partial_fit`` refuses it (StillMotionError, a ValueError), says why and
    what to do, and changes nothing; without ``adapt_to_noise`` the same motion is learned."""
    from drake_skills.library.views import StillMotionError

    human = np.array([[0, 0, 0], [15.726, 7.05, 1.477], [12.153, 0.289, -3.747], [1.226, -7.97, -8.08],
                      [-0.031, -3.621, -3.842]])
    demo = Demonstration(t=np.arange(5) / 4.0, human=human, robot=np.zeros((5, 2)), name="coarse")
    lib = SkillLibrary()
    lib.partial_fit(Demonstration(t=np.linspace(0, 1, 50), human=np.outer(np.linspace(0, 1, 50), [3.0, 1.0, 0.5]),
                                  robot=np.zeros((50, 2))))
    before = lib.state()
    with pytest.raises(StillMotionError, match=r"demo 'coarse': human trajectory does not move: its path length is "
                                               r"0 once the walk adapts to tracker noise: its samples read as noise "
                                               r"of 4\.04 normalized units per axis, the plain path is 47\.1 "
                                               r"\(5 samples: too few or too far apart"):
        lib.partial_fit(demo)
    after = lib.state()
    assert after.n_seen == before.n_seen == 1 and after.history == before.history
    np.testing.assert_array_equal(after.components[0].mean, before.components[0].mean)
    plain = SkillLibrary(LibraryConfig(adapt_to_noise=False))
    plain.partial_fit(demo)
    assert plain.n_components == 1
