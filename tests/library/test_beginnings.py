"""The record of beginnings: a component that misses its own beginnings cannot be ruled out from one.

Each demonstration that joins a component is first tested, at ``BEGINNING_FRACTIONS`` (10 and 20 %) of its
own path, against that component's prefix model (``Cluster.tested`` / ``Cluster.missed``). A
beginning that one skill explains is "undecided" while another skill, answering differently,
misses most of its own beginnings at the share the beginning covers of its path and lies within
``BLIND_REACH`` thresholds (``Recognition.blind`` names it): on the real interactions the hand
wave's component rejects its own first 10-20 %, which the rocket's component explains, and the
robot started a rocket for a third of the hand waves.
"""
from dataclasses import replace

import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.data.synthetic import skill_bank
from drake_skills.library import recognition
from drake_skills.library.algorithm import ComponentModel, Components
from drake_skills.library.scale import BEGINNING_FRACTIONS, BLIND_RATE, Cluster, beginning_blind
from drake_skills.library.state import _check_cluster

from shared_data import require

B = len(BEGINNING_FRACTIONS)


def test_cluster_record_adds_each_outcome_at_its_weight_skips_untested_shares_and_pools_by_sum():
    assert BEGINNING_FRACTIONS == (0.1, 0.2)
    w = np.zeros(3)
    a = Cluster.of_sample(w, 1.0, 2.0)
    assert np.array_equal(a.tested, np.zeros(B)) and np.array_equal(a.missed, np.zeros(B))
    a, _ = a.add(w + 1, 0.75, 1.0, 2.0, np.array([1.0, np.nan]))
    np.testing.assert_allclose(a.tested, [0.75, 0.0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(a.missed, [0.75, 0.0], rtol=0, atol=1e-15)
    a, _ = a.add(w, 0.5, 1.0, 2.0, np.array([0.0, 1.0]))
    np.testing.assert_allclose(a.tested, [1.25, 0.5], rtol=0, atol=1e-15)
    np.testing.assert_allclose(a.missed, [0.75, 0.5], rtol=0, atol=1e-15)
    a, _ = a.add(w, 1.0, 1.0, 2.0)                      # no outcome: the record stays
    np.testing.assert_allclose(a.missed, [0.75, 0.5], rtol=0, atol=1e-15)
    b = Cluster.of_sample(w, 1.0, 2.0, support=0.5, missed=np.array([0.0, 1.0]))
    np.testing.assert_allclose(b.tested, [0.5, 0.5], rtol=0, atol=1e-15)
    np.testing.assert_allclose(b.missed, [0.0, 0.5], rtol=0, atol=1e-15)
    p, _ = a.pool(b)
    np.testing.assert_allclose(p.tested, a.tested + b.tested, rtol=0, atol=1e-15)
    np.testing.assert_allclose(p.missed, a.missed + b.missed, rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match="record of beginnings has shape"):
        a.add(w, 1.0, 1.0, 2.0, np.zeros(B + 1))


def test_beginning_blind_interpolates_the_miss_rate_and_is_never_blind_past_the_tested_shares():
    tested = np.array([[2.0, 2.0], [2.0, 4.0], [0.0, 0.0], [10.0, 0.0]])
    missed = np.array([[2.0, 0.0], [0.0, 3.0], [0.0, 0.0], [3.0, 0.0]])
    assert BLIND_RATE == 0.3
    # row 0: rates 1, 0 -> blind while the interpolated rate is above 0.3 (below share 0.17); row 1: 0, 0.75
    # -> from 0.14 up to 0.25; row 2: nothing tested; row 3: a rate of exactly 0.3 is not enough
    assert beginning_blind(tested, missed, np.array([0.05, 0.05, 0.05, 0.05])).tolist() == [True, False, False, False]
    assert beginning_blind(tested, missed, np.array([0.169, 0.139, 0.1, 0.1])).tolist() == [True, False, False, False]
    assert beginning_blind(tested, missed, np.array([0.171, 0.141, 0.2, 0.12])).tolist() == [False, True, False, False]
    assert beginning_blind(tested, missed, np.array([0.3, 0.25, 0.3, 0.3])).tolist() == [False, True, False, False]
    # past the last fraction by more than half a step: not tested, never blind
    assert beginning_blind(tested, missed, np.array([0.0, 0.26, 0.0, 0.0])).tolist() == [True, False, False, False]


def test_beginning_blind_reads_a_single_test_and_a_share_never_tested_and_integer_counts():
    """Integer counts (lists) as the records: one tested beginning missed at both shares is a rate of 1 (blind);
    a record tested only at 10 % reads 0 at 20 % (not NaN): blind at 5 %, not past 0.1 + 0.1 * (1 - 0.3)."""
    tested, missed = [[1, 1], [2, 0]], [[1, 1], [2, 0]]
    assert beginning_blind(tested, missed, [0.05, 0.05]).tolist() == [True, True]
    assert beginning_blind(tested, missed, [0.2, 0.169]).tolist() == [True, True]
    assert beginning_blind(tested, missed, [0.25, 0.171]).tolist() == [True, False]


def test_a_bad_record_of_beginnings_is_refused_by_the_state_check():
    bad = Cluster(1.0, np.zeros(3), np.zeros((3, 0)), 1.0, 1.0, np.ones(B), np.full(B, 2.0))
    with pytest.raises(ValueError, match="record of beginnings"):
        _check_cluster(bad, 3, "component 0")
    with pytest.raises(ValueError, match="record of beginnings"):
        _check_cluster(Cluster(1.0, np.zeros(3), np.zeros((3, 0)), 1.0, 1.0, np.ones(B + 1), np.zeros(B + 1)),
                       3, "component 0")


def test_partial_fit_records_the_beginnings_of_a_demonstration_against_the_component_it_joins_before_it_does():
    bank = skill_bank(2, 0, separation=3.0)
    rng = np.random.default_rng(2)
    lib = SkillLibrary(LibraryConfig())
    lib.partial_fit(bank.demo(0, rng))
    c0 = lib._components.items[0].cluster
    assert np.array_equal(c0.tested, np.zeros(B))             # the first demonstration: nothing to test against
    d = bank.demo(0, rng)
    expect = lib._beginnings_missed(lib._normalized(d.human), 0)
    assert expect.shape == (B,) and np.isin(expect, (0.0, 1.0)).all()
    u = lib.partial_fit(d)
    assert u.created == () and u.updated == (0,)
    c = lib._components.items[0].cluster
    lam = u.responsibilities[0]
    np.testing.assert_allclose(c.tested, lam * np.ones(B), rtol=0, atol=1e-12)
    np.testing.assert_allclose(c.missed, lam * expect, rtol=0, atol=1e-12)
    # a save and load keeps the record; so does every sub-cluster's
    lib2 = SkillLibrary.from_state(lib.state())
    for x, y in zip(lib._components.items, lib2._components.items):
        np.testing.assert_array_equal(x.cluster.missed, y.cluster.missed)


def _two_skills(seed):
    """Two synthetic skills 3 apart, 3 demonstrations each taught interleaved: (bank, rng, library)."""
    bank = skill_bank(2, 0, separation=3.0)
    rng = np.random.default_rng(seed)
    lib = SkillLibrary(LibraryConfig())
    for _ in range(3):
        for k in range(2):
            lib.partial_fit(bank.demo(k, rng))
    return bank, rng, lib


def test_a_library_file_keeps_the_record_of_beginnings(tmp_path):
    bank, rng, lib = _two_skills(3)
    blind = Cluster(*(getattr(lib._components.items[0].cluster, f) for f in
                      ("support", "mean", "factor", "duration", "path_length")), np.full(B, 2.0), np.array([2.0, 1.0]))
    c = lib._components.items[0]
    lib._components = Components.of([ComponentModel(c.id, c.created, blind, (blind, None))]
                                    + list(lib._components.items[1:]), lib.n_human)
    lib.save(tmp_path / "lib.npz")
    back = SkillLibrary.load(tmp_path / "lib.npz")
    np.testing.assert_array_equal(back._components.items[0].cluster.missed, [2.0, 1.0])
    np.testing.assert_array_equal(back._components.items[0].subclusters[0].tested, np.full(B, 2.0))


def _with_record(lib, index, missed_rate):
    """``lib`` with component row ``index``'s record set to ``missed_rate`` of 4 tested beginnings at every share."""
    items = list(lib._components.items)
    c = items[index]
    cl = replace(c.cluster, tested=np.full(B, 4.0), missed=np.full(B, 4.0 * missed_rate))
    items[index] = ComponentModel(c.id, c.created, cl, c.subclusters)
    out = SkillLibrary.from_state(lib.state())
    out._components = Components.of(items, lib.n_human)
    return out


def test_a_beginning_one_skill_explains_is_undecided_while_a_blind_skill_cannot_be_ruled_out(monkeypatch):
    """Two taught skills; a beginning of skill 0 is a skill-0 answer. With skill 1's record blind (its own
    beginnings missed), the same beginning is undecided, naming skill 1, as long as it lies within BLIND_REACH
    thresholds of it; a record that misses one of four of its beginnings blocks nothing, and neither does a blind skill
    the beginning is far from (BLIND_REACH 0) nor a record read for a beginning of a known fraction."""
    bank, rng, lib = _two_skills(4)
    assert lib.n_components == 2
    k0 = lib.recognize(bank.demo(0, rng).human, observed_fraction=1.0).component
    row1 = 1 - lib._components.index(k0)
    h = bank.demo(0, rng).human
    part = h[: len(h) // 8]
    rec = lib.recognize(part)
    assert rec.status == "skill" and rec.component == k0 and rec.blind == ()
    share = lib._normalized(part).length / lib._components.path_length[row1]
    assert share < 0.25, share                                # a share the record covers
    blind_lib = _with_record(lib, row1, 1.0)
    monkeypatch.setattr(recognition, "BLIND_REACH", np.inf)
    rec = blind_lib.recognize(part)
    assert rec.status == "undecided" and rec.component is None
    assert rec.blind == (lib._components.ids[row1],)
    assert _with_record(lib, row1, 0.25).recognize(part).status == "skill"    # one miss in four is not enough
    assert _with_record(lib, row1, 0.5).recognize(part).status == "undecided"  # two in four are
    # told the fraction, recognition tests the beginning at that phase, where the record says nothing
    frac = lib._normalized(part).length / lib._normalized(h).length
    assert blind_lib.recognize(part, observed_fraction=frac).status == \
        lib.recognize(part, observed_fraction=frac).status
    # the whole motion is answered on its weights: the record plays no part
    assert blind_lib.recognize(h, observed_fraction=1.0).component == k0
    # a blind skill whose response is the best one's (its robot weights the same) answers the same: no block
    items = list(blind_lib._components.items)
    h = lib.n_human
    c = items[row1]
    same = replace(c.cluster, mean=np.concatenate([c.cluster.mean[:h], items[1 - row1].cluster.mean[h:]]))
    items[row1] = ComponentModel(c.id, c.created, same, c.subclusters)
    same_lib = SkillLibrary.from_state(blind_lib.state())
    same_lib._components = Components.of(items, lib.n_human)
    # ... unless it was taught as another task (the demonstrations carry their task names): the block stands
    assert same_lib.recognize(part).status == "undecided"
    items[row1] = ComponentModel(c.id, c.created, replace(same, tasks=items[1 - row1].cluster.tasks), c.subclusters)
    same_lib._components = Components.of(items, lib.n_human)
    assert same_lib.recognize(part).component == k0
    # the skill's own record blocks nothing for itself
    assert _with_record(lib, 1 - row1, 1.0).recognize(part).component == k0
    monkeypatch.setattr(recognition, "BLIND_REACH", 0.0)
    assert blind_lib.recognize(part).status == "skill"
    # the reach is a multiple of the blind component's own threshold, inclusive
    from drake_skills.library.novelty import chi2_ppf
    r = blind_lib.recognize(part)
    ratio = r.mahalanobis_sq[row1] / chi2_ppf(lib.config.novelty_quantile, np.broadcast_to(r.dof, (2,))[row1])
    assert ratio > 1.0                                        # skill 1 does not explain it
    monkeypatch.setattr(recognition, "BLIND_REACH", ratio)
    assert blind_lib.recognize(part).status == "undecided"
    monkeypatch.setattr(recognition, "BLIND_REACH", ratio * (1 - 1e-9))
    assert blind_lib.recognize(part).status == "skill"


def test_on_the_real_interactions_the_robot_starts_no_wrong_response_and_the_wave_misses_its_own_start():
    """buetepage_hr, the training split taught in 3 random orders, the 9 test interactions replayed through the
    gating: no first commit is wrong (before the record: 34 % of them, all hand waves and some hand shakes taken
    for rockets, 20 orders) and every executed skill is as before (none wrong); the hand wave's component misses
    most of its own beginnings at 10 % of its path, the others none."""
    from drake_skills.evaluation.interaction import InteractionContext, InteractionSettings, interaction_trial
    from drake_skills.evaluation.labeled import CORRECT, WRONG

    s = InteractionSettings(data=str(require()), orders=3, fractions=(1.0,))
    ctx = InteractionContext.of(s)
    for i in range(3):
        trial = interaction_trial(ctx, i)
        assert (trial.first_commit != WRONG).all(), (i, trial.first_commit)
        assert (trial.executed != WRONG).all() and (trial.first_commit == CORRECT).sum() >= 7
    # the record itself, in one library of the training split: a hand wave's component misses most of its own
    # beginnings at 10 % of its path; no component of the other three tasks misses more than a quarter of them
    from drake_skills.evaluation.labeled import LabeledLibrary
    lab = LabeledLibrary(replace(LibraryConfig(), workspace=ctx.workspace))
    for j in np.random.default_rng(0).permutation(len(ctx.train)):
        lab.teach(ctx.train[j])
    rates = {}
    for c in lab.library._components.items:
        t, m = c.cluster.tested, c.cluster.missed
        if t[0] >= 2:
            rates.setdefault(lab.label_of(c.id), []).append(m[0] / t[0])
    assert max(rates["hand_wave"]) > 0.5, rates
    assert all(r <= 0.25 for task, rs in rates.items() if task != "hand_wave" for r in rs), rates


def test_fold_in_records_the_beginnings_only_for_the_component_that_takes_most_of_the_demonstration():
    """Two components of one skill that both explain a demonstration (responsibilities about 0.6 and 0.4; merges
    off): the record test is asked once, of the one that takes more than half, before the update; its record and
    its sub-clusters' (a new second one here) gain the outcome at that weight, the other component's none."""
    from drake_skills.library.algorithm import fold_in
    from drake_skills.library.novelty import novelty_rule
    from drake_skills.library.scale import SharedScale

    cfg = LibraryConfig(prior_strength=1e-6, shrinkage=0.0, merge_min_age=100)
    d = 3
    a = Cluster(3.0, np.zeros(d), np.zeros((d, 0)), 2.0, 4.0)
    b = Cluster(3.0, np.array([0.4, 0.0, 0.0]), np.zeros((d, 0)), 2.0, 4.0, np.array([1.0, 1.0]), np.zeros(B))
    items = [ComponentModel(0, 0, a, (a, None)), ComponentModel(1, 1, b, (b, None))]
    sc = SharedScale.empty(d).count(np.zeros(d)).count(np.ones(d))
    sc = sc.with_scatter(np.sqrt(500.0) * np.eye(d), +1.0, 500.0)
    asked = []

    def beginnings(k):
        asked.append(k)
        return np.array([1.0, 0.0]) if k == 0 else np.array([0.0, 1.0])

    step = fold_in(Components.of(items, d), sc, np.array([0.1, 0.0, 0.0]), 2.0, 4.0, n_human=d, config=cfg,
                   rule=novelty_rule(cfg), next_id=2, demo_index=5, beginnings=beginnings)
    lam = step.responsibilities
    assert 0.5 < lam[0] < 0.8 and 1e-3 < lam[1] < 0.5, dict(lam)
    assert asked == [0] and step.updated == (0, 1) and not step.merged
    c0, c1 = step.components.items
    np.testing.assert_allclose(c0.cluster.tested, [lam[0], lam[0]], rtol=0, atol=1e-12)
    np.testing.assert_allclose(c0.cluster.missed, [lam[0], 0.0], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(c1.cluster.tested, [1.0, 1.0])      # updated, but not recorded
    np.testing.assert_array_equal(c1.cluster.missed, np.zeros(B))
    subs = [s for s in c0.subclusters if s is not None]
    np.testing.assert_allclose(sum(s.tested for s in subs), c0.cluster.tested, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sum(s.missed for s in subs), c0.cluster.missed, rtol=0, atol=1e-12)


def test_partial_fit_stops_testing_a_full_record(monkeypatch):
    """A component whose record holds RECORD_TESTS tested beginnings at every share is not tested again."""
    from drake_skills.library.scale import RECORD_TESTS

    bank = skill_bank(1, 0)
    rng = np.random.default_rng(5)
    lib = SkillLibrary(LibraryConfig())
    lib.partial_fit(bank.demo(0, rng))
    calls = []
    real = SkillLibrary._beginnings_missed
    monkeypatch.setattr(SkillLibrary, "_beginnings_missed", lambda self, path, k: calls.append(k) or real(self, path, k))
    for _ in range(12):
        lib.partial_fit(bank.demo(0, rng))
    assert lib.n_components == 1
    tested = lib._components.items[0].cluster.tested
    assert len(calls) == int(np.ceil(RECORD_TESTS)) < 12
    assert (tested >= RECORD_TESTS - 1e-9).all() and (tested < RECORD_TESTS + 1).all()


def test_a_pending_first_test_joins_the_record_once_when_two_components_merge():
    """A fragment's first demonstration, tested when it was created against the component nearest to it, counts
    in the record (weight 1) when it merges, and only then; the merged halves keep nothing pending."""
    w = np.zeros(3)
    a = Cluster.of_sample(w, 1.0, 2.0, pending=np.array([1.0, 0.0]))
    b = Cluster.of_sample(w + 0.1, 1.0, 2.0, missed=np.array([0.0, np.nan]), pending=np.array([1.0, np.nan]))
    np.testing.assert_array_equal(a.tested, np.zeros(B))             # pending is not yet the record
    a2, _ = a.add(w, 1.0, 1.0, 2.0)
    np.testing.assert_array_equal(a2.pending, [1.0, 0.0])            # an update keeps it pending
    p, _ = a.pool(b)
    np.testing.assert_allclose(p.tested, [1.0 + 1.0 + 1.0, 1.0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(p.missed, [2.0, 0.0], rtol=0, atol=1e-15)
    assert np.isnan(p.pending).all()
    with pytest.raises(ValueError, match="pending test of beginnings has shape"):
        Cluster.of_sample(w, 1.0, 2.0, pending=np.zeros(B + 1))
