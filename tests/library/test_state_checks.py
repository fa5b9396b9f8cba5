"""LibraryState's checks of a hand-built state, the scale functions' edge cases, the stacked component arrays.

Each invalid state is rejected with the message a user (or a file's loader) sees.
"""
import re

import numpy as np
import pytest

from drake_skills import LibraryConfig
from drake_skills.library.algorithm import ComponentModel, Components
from drake_skills.library.scale import Cluster, SharedScale, gating_covariance, observation_noise, shared_covariance
from drake_skills.library.state import ComponentState, LibraryState

import library_states as ls

CFG = LibraryConfig(n_basis_human=2, n_basis_robot=2)
D = 2 * 2 + 1 * 2  # dim_human 2, dim_robot 1


def _state(cluster=None, subclusters=None, **kw):
    cl = cluster if cluster is not None else Cluster(2.0, np.zeros(D), np.zeros((D, 0)), 1.0, 1.0)
    subs = subclusters if subclusters is not None else (cl, None)
    args = dict(config=CFG, dim_human=2, dim_robot=1, next_id=1, n_seen=3,
                components=(ComponentState(0, 2, cl, subs),), history=(), scale=ls.iso_scale(D))
    args.update(kw)
    return LibraryState(**args)


def _raises(message, fn):
    with pytest.raises(ValueError, match="^" + re.escape(message) + "$"):
        fn()


def _cl(support=2.0, mean=None, factor=None, duration=1.0, path_length=1.0):
    return Cluster(support, np.zeros(D) if mean is None else mean, np.zeros((D, 0)) if factor is None else factor,
                   duration, path_length)


@pytest.mark.parametrize("cluster, message", [
    ("not a cluster", "component 0 is not a Cluster"),
    (_cl(support=0.0), "component 0 has support 0.0"),
    (_cl(support=-1.0), "component 0 has support -1.0"),
    (_cl(support=float("inf")), "component 0 has support inf"),
    (_cl(mean=np.zeros(D + 1)), "component 0 has mean and scatter shapes (7,), (6, 0); the dimensions say 6 weights"),
    (_cl(mean=[0.0, 1.0]), "component 0 has mean and scatter shapes (2,), (6, 0); the dimensions say 6 weights"),
    (_cl(factor=np.zeros((D + 1, 1))), "component 0 has mean and scatter shapes (6,), (7, 1); the dimensions say 6 "
                                        "weights"),
    (_cl(factor=np.zeros(D)), "component 0 has mean and scatter shapes (6,), (6,); the dimensions say 6 weights"),
    (_cl(factor=[[0.0]] * (D - 1)), "component 0 has mean and scatter shapes (6,), (5, 1); the dimensions say 6 "
                                    "weights"),
    (_cl(factor=np.zeros((D, D + 1))), "component 0 has mean and scatter shapes (6,), (6, 7); the dimensions say 6 "
                                       "weights"),
    (_cl(mean=np.r_[np.nan, np.zeros(D - 1)]), "component 0 has NaN or inf in its mean or scatter"),
    (_cl(factor=np.full((D, 1), np.inf)), "component 0 has NaN or inf in its mean or scatter"),
    (_cl(duration=-0.5), "component 0 has duration -0.5 and path length 1.0"),
    (_cl(duration=float("nan")), "component 0 has duration nan and path length 1.0"),
    (_cl(path_length=-1.0), "component 0 has duration 1.0 and path length -1.0"),
    (_cl(path_length=float("inf")), "component 0 has duration 1.0 and path length inf"),
])
def test_a_bad_component_cluster_is_rejected_by_name(cluster, message):
    if isinstance(cluster, Cluster) and cluster.support > 0 and np.isfinite(cluster.support):
        subs = (cluster, None)
    else:
        subs = (_cl(), None)
    _raises(message, lambda: _state(cluster, subs))


def test_the_boundaries_of_a_valid_cluster_are_accepted():
    """Duration and path length 0, a factor of d columns, support just above 0 (with a matching sub-cluster)."""
    cl = _cl(support=1e-9, factor=np.eye(D), duration=0.0, path_length=0.0)
    assert _state(cl, (cl, None)).components[0].support == 1e-9


def test_sub_clusters_are_checked_by_name_and_must_sum_to_the_support():
    good = _cl()
    _raises("sub-cluster 1 of component 0 has support -2.0", lambda: _state(good, (good, _cl(support=-2.0))))
    _raises("sub-cluster 0 of component 0 has duration -1.0 and path length 1.0",
            lambda: _state(good, (_cl(duration=-1.0), None)))
    _raises("component 0 needs two sub-clusters (the second may be None)", lambda: _state(good, (None, good)))
    _raises("component 0 needs two sub-clusters (the second may be None)", lambda: _state(good, (good,)))
    _raises("component 0 has support 2.0 but its sub-clusters 3.0", lambda: _state(good, (good, _cl(support=1.0))))
    half = _cl(support=1.0)
    assert len(_state(good, (half, half)).components) == 1
    # within 1e-6 relative of the support is the same support
    _state(good, (_cl(support=2.0 + 1e-7), None))
    _raises("component 0 has support 2.0 but its sub-clusters 2.00001",
            lambda: _state(good, (_cl(support=2.00001), None)))


def test_the_state_checks_ids_ages_dimensions_and_the_scale():
    good = _cl()
    c = ComponentState(0, 2, good, (good, None))
    _raises("config must be a LibraryConfig, got dict", lambda: _state(config={}))
    _raises("trained_with_workspace must be True, False or None, got 1", lambda: _state(trained_with_workspace=1))
    _raises("dim_human and dim_robot are both None or both set, got 2 and None", lambda: _state(dim_robot=None))
    _raises("components but no dimensions", lambda: _state(dim_human=None, dim_robot=None, scale=None))
    _raises("dimensions must be dim_human >= 1 and dim_robot >= 0, got 0, 1",
            lambda: _state(dim_human=0, components=()))
    _raises("dimensions must be dim_human >= 1 and dim_robot >= 0, got 2, -1",
            lambda: _state(dim_robot=-1, components=()))
    _raises("n_seen and next_id must be >= 0, got -1, 1", lambda: _state(n_seen=-1))
    _raises("n_seen and next_id must be >= 0, got 3, -1", lambda: _state(next_id=-1, components=()))
    _raises("a fitted library needs its shared scale", lambda: _state(scale=None))
    _raises("shared scale has shapes (6,), (5, 5); the dimensions say 6 weights",
            lambda: _state(scale=SharedScale(0, np.zeros(D), np.zeros(D), np.zeros((D - 1, D - 1)), 0.0)))
    _raises("shared scale has NaN or inf entries or a negative count",
            lambda: _state(scale=SharedScale(-1, np.zeros(D), np.zeros(D), np.zeros((D, D)), 0.0)))
    _raises("shared scale has NaN or inf entries or a negative count",
            lambda: _state(scale=SharedScale(0, np.zeros(D), np.zeros(D), np.zeros((D, D)), 0.0, -1.0)))
    _raises("shared scale has NaN or inf entries or a negative count",
            lambda: _state(scale=SharedScale(0, np.full(D, np.nan), np.zeros(D), np.zeros((D, D)), 0.0)))
    _raises("shared scale has NaN or inf entries or a negative count",
            lambda: _state(scale=SharedScale(0, np.zeros(D), np.zeros(D), np.zeros((D, D)), np.inf)))
    _raises("shared scale has negative variances or degrees of freedom",
            lambda: _state(scale=SharedScale(0, np.zeros(D), np.full(D, -1e-3), np.zeros((D, D)), 0.0)))
    _raises("shared scale has negative variances or degrees of freedom",
            lambda: _state(scale=SharedScale(0, np.zeros(D), np.zeros(D), np.zeros((D, D)), -1e-6)))
    # rounding below zero is not negative
    assert _state(scale=SharedScale(0, np.zeros(D), np.full(D, -1e-12), np.zeros((D, D)), -1e-12)).n_seen == 3
    _raises("component id 0 is duplicated or out of range (next id 1)", lambda: _state(components=(c, c)))
    _raises("component id 0 is duplicated or out of range (next id 0)", lambda: _state(next_id=0))
    _raises("component id -1 is duplicated or out of range (next id 1)",
            lambda: _state(components=(ComponentState(-1, 2, good, (good, None)),)))
    _raises("component 0 has age 0; the library has seen 3 demonstrations",
            lambda: _state(components=(ComponentState(0, 0, good, (good, None)),)))
    _raises("component 0 has age 4; the library has seen 3 demonstrations",
            lambda: _state(components=(ComponentState(0, 4, good, (good, None)),)))
    assert _state(components=(ComponentState(0, 3, good, (good, None)),)).components[0].age == 3
    assert _state(n_seen=0, components=(ComponentState(0, 1, good, (good, None)),)).n_seen == 0
    empty = LibraryState(CFG, None, None, 0, 0)
    assert (empty.n_human, empty.n_weights) == (0, 0)
    st = _state()
    assert (st.n_human, st.n_weights) == (4, 6)


def test_components_index_raises_a_key_error_naming_the_id():
    cl = Cluster.of_sample(np.arange(3.0), 1.0, 2.0)
    comps = Components.of([ComponentModel(4, 0, cl, (cl, None)), ComponentModel(9, 1, cl, (cl, None))], 2)
    assert comps.index(9) == 1 and comps.ids == (4, 9)
    with pytest.raises(KeyError) as e:
        comps.index(5)
    assert e.value.args == (5,)
    empty = Components.of([], 3)
    assert empty.means_h.shape == (0, 3) and empty.sub_means_h.shape == (0, 2, 3) and len(empty) == 0


def test_observation_noise_of_a_scale_that_has_counted_nothing_is_the_floor():
    sc = SharedScale.empty(4)
    assert observation_noise(sc, 0.05) == 0.05
    assert observation_noise(SharedScale(4, np.zeros(4), np.zeros(4), np.zeros((4, 4)), 0.0, 2.0), 0.05) == 0.5
    assert observation_noise(SharedScale(4, np.zeros(4), np.zeros(4), np.zeros((4, 4)), 0.0, 0.1), 0.05) == 0.05


def test_the_covariances_default_to_no_prior_floor():
    rng = np.random.default_rng(0)
    sc = SharedScale.empty(5)
    for w in rng.standard_normal((6, 5)):
        sc = sc.count(w)
    kw = dict(prior_scale=0.3, prior_strength=2.0, shrinkage=0.3)
    np.testing.assert_array_equal(shared_covariance(sc, 3, **kw), shared_covariance(sc, 3, prior_floor=0.0, **kw))
    np.testing.assert_array_equal(gating_covariance(sc, 3, **kw), gating_covariance(sc, 3, prior_floor=0.0, **kw))
    assert not np.array_equal(shared_covariance(sc, 3, prior_floor=5.0, **kw), shared_covariance(sc, 3, **kw))


def test_fold_in_counts_no_fit_residual_by_default():
    from drake_skills.library.algorithm import fold_in
    from drake_skills.library.novelty import novelty_rule

    cfg = LibraryConfig()
    w = np.arange(6.0)
    kw = dict(n_human=4, config=cfg, rule=novelty_rule(cfg), next_id=0, demo_index=0)
    step = fold_in(Components.of([], 4), SharedScale.empty(6), w, 1.0, 2.0, **kw)
    assert step.scale.fit_m2 == 0.0 and step.created == (0,)
    assert fold_in(Components.of([], 4), SharedScale.empty(6), w, 1.0, 2.0, fit_residual=0.3, **kw).scale.fit_m2 == 0.3


def test_gating_scores_of_no_components_are_empty():
    from drake_skills.library.algorithm import Metric, gating_scores

    logp, d2 = gating_scores(np.ones(3), Components.of([], 3), Metric.of(np.eye(3)))
    assert logp.shape == d2.shape == (0,)


def test_the_covariance_of_a_scale_without_spread_is_its_floor():
    """No pooled scatter, no prior (prior_floor 0, and one demonstration has no spread): the covariance is the
    relative floor 1e-9 (mean square weight) on the diagonal, positive definite; with nothing counted, 1e-300."""
    kw = dict(prior_scale=0.3, prior_strength=2.0, shrinkage=0.3, prior_floor=0.0)
    w = np.array([1.0, -2.0, 3.0, 0.5])
    one = SharedScale.empty(4).count(w)
    G = gating_covariance(one, 3, **kw)
    np.testing.assert_allclose(G, (1e-9 * np.mean(w[:3] ** 2) + 1e-300) * np.eye(3), rtol=1e-12, atol=0)
    np.linalg.cholesky(G)
    S = shared_covariance(one, 3, **kw)
    np.testing.assert_allclose(np.diag(S), [1e-9 * np.mean(w[:3] ** 2)] * 3 + [1e-9 * 0.25], rtol=1e-12)
    G0 = gating_covariance(SharedScale.empty(3), 3, **kw)
    np.testing.assert_array_equal(G0, 1e-300 * np.eye(3))
    np.linalg.cholesky(G0)


def test_the_state_checks_at_their_boundaries():
    good = _cl()
    _raises("component 0 has age 2; the library has seen 1 demonstrations",
            lambda: _state(n_seen=1, components=(ComponentState(0, 2, good, (good, None)),)))
    # one human dimension (a pen tip) and no robot are valid
    one = LibraryState(CFG, 1, 0, 0, 0, scale=ls.iso_scale(2))
    assert (one.n_human, one.n_weights) == (2, 2)
    _raises("shared scale has shapes (5,), (6, 6); the dimensions say 6 weights",
            lambda: _state(scale=SharedScale(0, np.zeros(D - 1), np.zeros(D), np.zeros((D, D)), 0.0)))
    _raises("shared scale has shapes (6,), (6, 6); the dimensions say 6 weights",
            lambda: _state(scale=SharedScale(0, np.zeros(D), np.zeros(D + 1), np.zeros((D, D)), 0.0)))
    _raises("shared scale has NaN or inf entries or a negative count",
            lambda: _state(scale=SharedScale(0, np.zeros(D), np.zeros(D), np.zeros((D, D)), 0.0, np.inf)))
    # negative variances: below -1e-9 (1 + the largest magnitude) is an error, rounding above it is not
    big = np.r_[1e6, -1e-4, np.zeros(D - 2)]
    assert _state(scale=SharedScale(0, np.zeros(D), big, np.zeros((D, D)), 0.0)).n_seen == 3
    _raises("shared scale has negative variances or degrees of freedom",
            lambda: _state(scale=SharedScale(0, np.zeros(D), np.r_[-1.5e-9, np.zeros(D - 1)], np.zeros((D, D)), 0.0)))
    # the sub-clusters' supports sum to the support within 1e-6 relative (at least 1e-6)
    big_cl = _cl(support=100.0)
    _state(big_cl, (_cl(support=100.0 + 5e-5), None))
    _raises("component 0 has support 1.0 but its sub-clusters 1.0000015",
            lambda: _state(_cl(support=1.0), (_cl(support=1.0000015), None)))


def test_a_human_only_library_learns_without_warnings():
    import warnings

    from synthetic import synthetic_demo

    lib = __import__("drake_skills").SkillLibrary(LibraryConfig(n_samples=30, n_basis_human=5))
    rng = np.random.default_rng(3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # e.g. the mean of an empty robot block
        for i in range(4):
            lib.partial_fit(synthetic_demo(i % 2, rng, T=30, robot=False))
        lib.recognize(synthetic_demo(0, rng, T=30, robot=False).human)
    assert lib.n_components == 2
