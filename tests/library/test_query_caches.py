"""The caches that make a controller's queries cheap never change an answer.

A controller asks about the same prefix three times per tick (the gating recognizes
it, the conditioner estimates its phase and conditions on it), so a library keeps the
last few normalized motions (``PATH_MEMO``) and prefix recognition keeps whole phase
sets' eigendecompositions (``prefix._STACKED_ENTRIES``). Each cached answer must be
the one computed from scratch, and a changed input must never meet a stale entry.
"""
import sys
import threading
from collections import OrderedDict

import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.library import incremental, prefix
from drake_skills.library.prefix import PHASE_GRID, score_phases
from drake_skills.promp.preprocessing import Workspace

from synthetic import WORKSPACE, synthetic_demo


def _lib(seed=0):
    rng = np.random.default_rng(seed)
    lib = SkillLibrary(LibraryConfig(workspace=WORKSPACE))
    for i in range(8):
        lib.partial_fit(synthetic_demo(i % 2, rng))
    return lib, rng


def _same_recognition(a, b):
    assert a.status == b.status and a.component == b.component
    np.testing.assert_array_equal(a.log_likelihoods, b.log_likelihoods)
    np.testing.assert_array_equal(a.mahalanobis_sq, b.mahalanobis_sq)
    np.testing.assert_array_equal(a.phases, b.phases)


def test_a_remembered_motion_gives_the_answers_of_a_fresh_library_bit_for_bit():
    lib, rng = _lib()
    fresh = SkillLibrary.from_state(lib.state())
    prefix_ = synthetic_demo(1, rng).human[:50]
    first = lib.recognize(prefix_)
    again = lib.recognize(prefix_)            # from the memo
    _same_recognition(first, again)
    _same_recognition(again, fresh.recognize(prefix_))
    k = first.phases.argmax()
    cid = first.ids[k]
    assert lib.estimate_phase(prefix_, cid) == fresh.estimate_phase(prefix_, cid)
    m1, c1 = lib.predict_robot(prefix_, component=cid)
    m2, c2 = fresh.predict_robot(prefix_, component=cid)
    np.testing.assert_array_equal(m1, m2)
    np.testing.assert_array_equal(c1, c2)


def test_an_input_changed_in_place_is_normalized_again():
    lib, rng = _lib()
    y = synthetic_demo(0, rng).human[:60].copy()
    before = lib.path_length(y)
    y[30:] *= 1.5                               # same array object, same shape, other samples
    after = lib.path_length(y)
    assert after != pytest.approx(before, rel=1e-3)
    assert after == pytest.approx(SkillLibrary.from_state(lib.state()).path_length(y), rel=0, abs=0)


def test_the_memo_tells_workspaces_and_normalized_input_apart():
    lib, rng = _lib()
    y = synthetic_demo(0, rng).human[:60]
    wide = Workspace(np.full(3, -10.0), np.full(3, 10.0))   # twice the extent: about half the path
    base = lib.path_length(y)
    # not exactly half: the arc length counts moves of resample_tolerance normalized units
    assert lib.path_length(y, workspace=wide) == pytest.approx(0.5 * base, rel=0.02)
    assert lib.path_length(y, workspace=wide) == SkillLibrary.from_state(lib.state()).path_length(y, workspace=wide)
    assert lib.path_length(y, normalized=True) == pytest.approx(
        SkillLibrary.from_state(lib.state()).path_length(y, normalized=True), rel=0, abs=0)
    assert lib.path_length(y) == base


def test_the_memo_keeps_only_the_last_few_motions():
    lib, rng = _lib()
    ys = [synthetic_demo(0, rng).human[:40 + i] for i in range(incremental.PATH_MEMO + 3)]
    for y in ys:
        lib.path_length(y)
    assert len(lib._paths) == incremental.PATH_MEMO


def test_stacked_eigendecompositions_equal_the_uncached_ones_and_stay_bounded():
    lib, rng = _lib()
    cfg = lib.config
    comps = lib._components
    metric = lib._metric()
    inflate = 1.0 + 1.0 / comps.support
    y = lib.human_samples(synthetic_demo(1, rng).human[:60], observed_fraction=0.5)
    cache: dict = {}
    sets = [tuple(PHASE_GRID[i:j]) for i in range(20) for j in range(i + 1, 21, 2)]
    assert len(sets) > prefix._STACKED_ENTRIES
    for phases in sets + sets[:5]:           # the first five again, after they were evicted
        got = score_phases(y, phases, comps.means_h, inflate, metric.chol, cfg.basis_human, 0.01, cache)
        ref = score_phases(y, phases, comps.means_h, inflate, metric.chol, cfg.basis_human, 0.01, None)
        for a, b in zip(got, ref):
            np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-10)
    for kind in ("gram", "fit"):
        assert len(cache[kind]["stacked"]) == prefix._STACKED_ENTRIES


def test_a_remembered_motion_does_not_share_the_callers_array():
    """normalized=True takes the caller's array as is; the memo keeps its own copy of the samples."""
    lib, rng = _lib()
    y = lib.human_samples(synthetic_demo(0, rng).human[:60])       # already normalized
    first = lib._normalized(y, None, True)
    kept = y.copy()
    y[:] = 0.0                                                      # the caller reuses its buffer
    again = lib._normalized(kept, None, True)                       # the old samples, another array
    assert again is first
    np.testing.assert_array_equal(again.y, kept)


def test_queries_from_several_threads_give_the_serial_answers_while_the_caches_evict(monkeypatch):
    """Four threads recognize beginnings of six motions at once, with a stacked cache of two entries (so that
    every query evicts) and a thread switch every microsecond: no error, every posterior the serial one. A smoke
    test: the old eviction (it iterated a dict other threads changed) failed it in about 1 of 5 runs; the two
    tests below replay the interleavings that broke it, deterministically."""
    monkeypatch.setattr(prefix, "_STACKED_ENTRIES", 2)
    lib, _ = _lib()
    probes = [synthetic_demo(t % 2, np.random.default_rng(10 + t)).human for t in range(6)]
    cuts = [int(f * len(probes[0])) for f in np.linspace(0.2, 0.9, 15)]
    serial = {(i, c): lib.recognize(p[:c]).posterior.copy() for i, p in enumerate(probes) for c in cuts}
    errors = []

    def work(seed):
        r = np.random.default_rng(seed)
        try:
            for _ in range(300):
                i, c = int(r.integers(len(probes))), cuts[int(r.integers(len(cuts)))]
                if not np.allclose(lib.recognize(probes[i][:c]).posterior, serial[(i, c)], rtol=1e-9, atol=1e-12):
                    errors.append(f"probe {i} cut {c}: another posterior")
        except Exception as exc:  # noqa: BLE001 - reported below
            errors.append(repr(exc))

    old = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)
    try:
        threads = [threading.Thread(target=work, args=(s,)) for s in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        sys.setswitchinterval(old)
    assert errors == []


class _EmptiedByAnotherThread(OrderedDict):
    """A cache another thread empties between this thread's size check and its eviction."""

    def __len__(self):
        n = max(super().__len__(), prefix._STACKED_ENTRIES)
        self.clear()
        return n


def test_a_stacked_cache_emptied_by_another_thread_mid_eviction_still_answers():
    lib, rng = _lib()
    probe = synthetic_demo(1, rng).human[:40]
    expect = lib.recognize(probe)
    lib.recognize(probe[:30])  # builds the cache
    cache = lib._prefix[1]
    for store in cache.values():
        store["stacked"] = _EmptiedByAnotherThread()
        store["phase"].clear()  # so that the next query computes and evicts
    _same_recognition(lib.recognize(probe), expect)


class _EvictedByAnotherThread(OrderedDict):
    """A cache from which another thread evicts every entry as soon as it is written."""

    def __setitem__(self, key, value):
        super().__setitem__(key, value)
        super().__delitem__(key)


def test_the_robot_covariance_of_a_component_survives_another_thread_evicting_it():
    """``predict_robot`` needs each component's covariance; one evicted by another thread right after this one
    computed it must still be returned (the old code read it back from the cache: KeyError)."""
    lib, rng = _lib()
    human = synthetic_demo(0, rng).human
    mean, cov = lib.predict_robot(human, observed_fraction=1.0)
    lib._expert_cache = (lib._scale, _EvictedByAnotherThread())
    mean2, cov2 = lib.predict_robot(human, observed_fraction=1.0)
    np.testing.assert_allclose(mean2, mean, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(cov2, cov, rtol=1e-12, atol=1e-12)


def test_a_robot_covariance_cached_for_another_cluster_at_the_same_id_is_not_used():
    """The cache is keyed by ``id(cluster)``; a freed cluster's id can be reused by a new one, so an entry counts
    only if it holds the very cluster asked about (a stale matrix there would condition on the wrong skill)."""
    lib, rng = _lib()
    human = synthetic_demo(0, rng).human
    mean, cov = lib.predict_robot(human, observed_fraction=1.0)
    stale = OrderedDict()
    for c in lib._components.items:
        d = c.cluster.scatter.shape[0]
        stale[id(c.cluster)] = (object(), np.eye(d) * 1e3)  # another cluster's entry at this id
    lib._expert_cache = (lib._scale, stale)
    mean2, cov2 = lib.predict_robot(human, observed_fraction=1.0)
    np.testing.assert_allclose(mean2, mean, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(cov2, cov, rtol=1e-12, atol=1e-12)


def test_the_seen_blocks_of_a_component_survive_eviction_and_ignore_another_clusters_entry():
    """Eq. (13) on a prefix (``_condition``, before the learned gains) reads each component's human blocks seen
    through ``S^-1`` from a cache kept like the expert covariance's: an entry evicted by another thread right after
    it was computed is still returned, and an entry at the same id holding another cluster is not used (it would
    condition on the wrong skill); one holding the very cluster is."""
    lib, rng = _lib()
    y = lib.human_samples(synthetic_demo(0, rng).human[:40], observed_fraction=0.5)
    c = lib._model(lib.components[0].id)

    def conditioned():
        return lib._condition(c, y, 0.5)[2:]

    mean, cov = conditioned()
    lib._seen_cache = (lib._scale, _EvictedByAnotherThread())
    mean2, cov2 = conditioned()
    np.testing.assert_allclose(mean2, mean, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(cov2, cov, rtol=1e-12, atol=1e-12)
    h = lib.n_human
    wrong = (np.ones(h), np.eye(h) * 1e3, np.ones((c.mean.size - h, h)))
    lib._seen_cache = (lib._scale, OrderedDict((id(d.cluster), (object(), wrong)) for d in lib._components.items))
    mean3, cov3 = conditioned()
    np.testing.assert_allclose(mean3, mean, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(cov3, cov, rtol=1e-12, atol=1e-12)
    lib._seen_cache = (lib._scale, OrderedDict([(id(c.cluster), (c.cluster, wrong))]))
    assert np.abs(conditioned()[0] - mean).max() > 1e-3   # the cache is read: the very cluster's entry is used


def test_a_library_that_learns_answers_a_beginning_from_new_caches():
    """Recognize a beginning (the prefix caches fill), learn 4 more demonstrations, recognize it again: the
    statistics equal those of a library restored from the state (no cache at all), not the old ones."""
    lib, rng = _lib()
    probe = synthetic_demo(1, rng).human[:45]
    before = lib.recognize(probe)
    for k in range(4):
        lib.partial_fit(synthetic_demo(k % 2, rng))     # taught skills: the same components, the same sizes
    after = lib.recognize(probe)
    fresh = SkillLibrary.from_state(lib.state()).recognize(probe)
    np.testing.assert_allclose(after.mahalanobis_sq, fresh.mahalanobis_sq, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(after.log_likelihoods, fresh.log_likelihoods, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(after.posterior, fresh.posterior, rtol=0, atol=1e-12)
    assert len(before.ids) == len(after.ids) and not np.allclose(before.mahalanobis_sq, after.mahalanobis_sq,
                                                                   rtol=1e-6)


def test_the_blocks_are_kept_read_only_and_a_second_call_returns_the_kept_ones():
    """``_seen_blocks`` computes a component's blocks once per scale (the entry under ``id(cluster)`` holds the
    cluster and the blocks), returns the very arrays again, and none of them can be written (a caller that changed
    one would change every later conditioning)."""
    lib, _ = _lib()
    c = lib._model(lib.components[0].id)
    first = lib._seen_blocks(c)
    entry = lib._seen_cache[1][id(c.cluster)]
    assert entry[0] is c.cluster and entry[1] is first
    again = lib._seen_blocks(c)
    assert all(a is b for a, b in zip(again, first))
    assert not any(a.flags.writeable for a in first)


def test_the_per_cluster_caches_hold_at_most_64_entries_and_compute_each_once():
    """``_per_cluster`` (the expert covariance's and the seen blocks' cache): 70 clusters asked twice each in turn
    compute 70 + 6 times (the 6 oldest evicted), and the cache keeps 64 entries."""
    lib, _ = _lib()

    class _Comp:
        def __init__(self):
            self.cluster = object()

    comps = [_Comp() for _ in range(70)]
    calls = []
    for c in comps + comps[-64:] + comps[:6]:
        lib._per_cluster("_test_cache", c, lambda c=c: calls.append(c) or ("value", c))
    assert len(calls) == 70 + 6
    assert len(lib._test_cache[1]) == 64
    assert lib._per_cluster("_test_cache", comps[0], lambda: "computed again") == ("value", comps[0])


def test_a_component_the_library_did_not_change_is_conditioned_on_the_new_scale_after_learning():
    """Condition on a beginning with each component (the blocks seen through S^-1 are kept), teach 4 more
    demonstrations of skill 0 only: the component of skill 1 keeps its cluster object but the shared scale moved,
    so its conditioning must be that of a library restored from the state (no cache), not the kept one."""
    lib, rng = _lib()
    probe = synthetic_demo(1, rng).human[:45]
    ids = [c.id for c in lib.components]
    before = {k: lib.predict_robot(probe, 0.5, component=k)[0] for k in ids}
    clusters = {c.id: c.cluster for c in lib._components.items}
    for _ in range(4):
        lib.partial_fit(synthetic_demo(0, rng))
    kept = [c.id for c in lib._components.items if clusters.get(c.id) is c.cluster]
    assert kept, "the stream must leave a component untouched for this test to mean anything"
    fresh = SkillLibrary.from_state(lib.state())
    for k in kept:
        after = lib.predict_robot(probe, 0.5, component=k)[0]
        np.testing.assert_allclose(after, fresh.predict_robot(probe, 0.5, component=k)[0], rtol=1e-12, atol=1e-12)
        assert np.abs(after - before[k]).max() > 1e-6   # the scale moved: a kept entry would give the old answer


def test_the_metric_an_update_leaves_behind_is_the_metric_of_the_library_s_scale_bit_for_bit():
    """partial_fit keeps the gating metric its last step factored (``Step.metric``) as the library's: it must be the
    metric of the committed scale (a stream of creations and updates; ``test_scale.py`` checks one with merges,
    splits and deletions)."""
    from drake_skills.library.algorithm import gating_metric

    rng = np.random.default_rng(3)
    lib = SkillLibrary(LibraryConfig(workspace=WORKSPACE))
    seeded = 0
    for i in range(14):
        lib.partial_fit(synthetic_demo(i % 3, rng))
        hit = lib._memo.get("metric")
        if hit is not None and hit[0][0] is lib._components and hit[0][1] is lib._scale:
            seeded += 1
            fresh = gating_metric(lib._scale, lib.n_human, lib.config)
            for a, b in ((hit[1].cov, fresh.cov), (hit[1].inv_chol, fresh.inv_chol), (hit[1].chol, fresh.chol)):
                np.testing.assert_array_equal(a, b)
            assert hit[1].logdet == fresh.logdet
    assert seeded >= 12, seeded  # every update after the first here: nothing splits or is deleted


def test_conditioning_from_the_blocks_equals_conditioning_the_assembled_covariance():
    """_condition reads the expert covariance's blocks (the human ones through S^-1) instead of assembling the whole
    (d, d) matrix: the robot's prior and posterior equal those of Eq. (13) on the assembled matrix within 1e-12."""
    from drake_skills.promp.interaction import condition_on_observations

    lib, rng = _lib(5)
    h = lib.n_human
    for k, f in ((0, 0.4), (1, 0.75), (0, 1.0)):
        c = lib._model(lib.components[k].id)
        y = lib.human_samples(synthetic_demo(k, rng).human, observed_fraction=f)
        U = lib._prefix_model().unshrink
        mean = np.concatenate([U @ c.mean[:h], c.mean[h:]])
        cov = np.array(lib._expert_cov(c))
        cov[:h, :] = U @ cov[:h, :]
        cov[:, :h] = cov[:, :h] @ U.T
        Phi = lib.config.basis_human.phi(np.linspace(0.0, f, y.shape[0]))
        want_mean, want_cov = condition_on_observations(mean, cov, Phi, y, lib._noise(), start=h)
        prior_w, prior_cov, got_mean, got_cov = lib._condition(c, y, f)
        np.testing.assert_array_equal(prior_w, c.mean[h:])
        np.testing.assert_array_equal(prior_cov, cov[h:, h:])
        np.testing.assert_allclose(got_mean, want_mean, rtol=1e-12, atol=1e-12 * np.abs(want_mean).max())
        np.testing.assert_allclose(got_cov, want_cov, rtol=1e-12, atol=1e-12 * np.abs(want_cov).max())


def test_the_cached_basis_of_a_prefix_is_the_basis_at_evenly_spaced_phases_and_read_only():
    """prefix._basis_at, which prefix scoring and Eq. (13) on a prefix (_condition) share: Phi over [0, f] and its Gram
    matrix, the same objects on a second call, neither writable."""
    from drake_skills.promp.basis import GaussianBasis

    b = GaussianBasis(7)
    P, G = prefix._basis_at(b, 0.35, 23)
    np.testing.assert_array_equal(P, b.phi(np.linspace(0.0, 0.35, 23)))
    np.testing.assert_array_equal(G, P.T @ P)
    again = prefix._basis_at(b, 0.35, 23)
    assert again[0] is P and again[1] is G and not P.flags.writeable and not G.flags.writeable
    with pytest.raises(ValueError, match="phase must lie in"):
        prefix._basis_at(b, 1.5, 4)


def test_predict_robot_variances_only_gives_the_diagonals_of_the_full_covariance():
    """The conditioner's call (variances_only=True): the same mean, and each joint's variance the diagonal of the
    per-step covariance within 1e-12 of the largest, for a prefix (phase estimated) and a whole motion."""
    lib, rng = _lib(6)
    k = lib.components[0].id
    human = synthetic_demo(0, rng).human
    for y, f in ((human[:50], None), (human, 1.0)):
        m_full, cov = lib.predict_robot(y, f, component=k)
        m_var, var = lib.predict_robot(y, f, component=k, variances_only=True)
        np.testing.assert_array_equal(m_full, m_var)
        assert var.shape == m_var.shape
        np.testing.assert_allclose(var, np.diagonal(cov, axis1=1, axis2=2), rtol=0, atol=1e-12 * np.abs(cov).max())


def test_the_task_name_check_of_a_skill_is_computed_once_per_library_version_and_row(monkeypatch):
    """``_contested`` depends on nothing but the library (its names, means and scale) and the row asked for: it is
    kept per version and row, and computed again once the library learns."""
    from drake_skills.data.synthetic import skill_bank
    from drake_skills.library.recognition import RecognitionMixin

    bank = skill_bank(3, 0, separation=3.0)
    rng = np.random.default_rng(12)
    lib = SkillLibrary(LibraryConfig())
    for _ in range(3):
        for k in range(3):
            d = bank.demo(k, rng)
            lib.partial_fit(type(d)(d.t, d.human, d.robot, task=f"t{k}", name=d.name))
    calls = []
    real = RecognitionMixin._contested_now

    def counted(self, best):
        calls.append(best)
        return real(self, best)
    monkeypatch.setattr(RecognitionMixin, "_contested_now", counted)
    first = [lib._contested(i) for i in range(lib.n_components)]
    again = [lib._contested(i) for i in range(lib.n_components)]
    assert again == first and calls == list(range(lib.n_components))
    before = len(calls)
    lib.partial_fit(bank.demo(0, rng))             # a new version: every row computed again, once
    for _ in range(2):
        for i in range(lib.n_components):
            lib._contested(i)
    assert calls[before:] == list(range(lib.n_components))
