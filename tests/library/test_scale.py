"""The library at scale (issue 19): the optimized code agrees with the brute-force reference, and big files are safe.

Speed is shown by ``drake-skills bench --suite scale`` (BENCHMARKS.md), never here.
"""
from dataclasses import replace

import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.data.synthetic import skill_bank
from drake_skills.library.novelty import novelty_rule

from brute_force import Reference


def _stream(K, order, seed, reps=3):
    rng = np.random.default_rng(seed)
    bank = skill_bank(K, rng)
    labels = np.repeat(np.arange(K), reps)
    if order == "random":
        labels = rng.permutation(labels)
    return bank, [bank.demo(int(k), rng) for k in labels], rng


def _assert_same_state(lib: SkillLibrary, ref: Reference):
    comps = lib.state().components
    assert [c.id for c in comps] == [c.id for c in ref.items]
    for c, r in zip(comps, ref.items):
        assert lib.n_seen - c.age == r.created
        np.testing.assert_array_equal(c.mean, r.mean)
        np.testing.assert_array_equal(c.cluster.factor, r.cluster.factor)
        assert c.support == r.support
        for s, t in zip(c.subclusters, r.subclusters):
            assert (s is None) == (t is None)
            if s is not None:
                np.testing.assert_array_equal(s.mean, t.mean)
                assert s.support == t.support
    sc = lib.state().scale
    np.testing.assert_array_equal(sc.pooled, ref.scale.pooled)
    assert sc.dof == ref.scale.dof and lib.state().next_id == ref.next_id


def _learn_both(demos, config=None):
    lib = SkillLibrary(config)
    ref = None
    for d in demos:
        w, path = lib.encode(d), lib.path_length(d.human)
        if ref is None:
            ref = Reference(lib.config, novelty_rule(lib.config), d.dim_human * lib.config.n_basis_human)
        expect = ref.partial_fit(w, d.duration, path)
        got = lib.partial_fit(d)
        for key in ("recognized", "created", "updated", "merged", "split", "deleted", "subcluster"):
            assert getattr(got, key) == expect[key], key
        assert dict(got.responsibilities) == expect["responsibilities"]
    return lib, ref


@pytest.mark.parametrize("order", ["random", "row"])
def test_partial_fit_builds_the_same_library_as_the_brute_force_reference(order):
    """40 synthetic skills, 3 demonstrations each: every update, every component and the scale agree exactly."""
    _, demos, _ = _stream(40, order, seed=1)
    lib, ref = _learn_both(demos)
    _assert_same_state(lib, ref)
    assert lib.n_components == 40  # and the library finds the skills it was shown


@pytest.fixture(scope="module")
def letters():
    from drake_skills.data.lasa import LASA_SHAPES, lasa_workspace, load_lasa

    demos = load_lasa(LASA_SHAPES[:12], n_demos=4, subsample=4)
    return demos, lasa_workspace(demos)


def test_partial_fit_matches_the_reference_through_merges_splits_and_deletions(letters):
    """12 letters, a wide prior (early merges that split later) and a short deletion age: every branch agrees."""
    demos, ws = letters
    order = np.random.default_rng(1).permutation(len(demos))
    cfg = LibraryConfig(workspace=ws, prior_scale=0.6, delete_min_age=2)
    lib, ref = _learn_both([demos[j] for j in order], cfg)
    events = {e["event"] for e in lib.history}
    assert {"created", "merged", "split", "deleted"} <= events, events
    _assert_same_state(lib, ref)


def _assert_same_answer(rec, expect, *, exact_arrays=True):
    assert rec.status == expect["status"] and rec.component == expect["component"]
    assert rec.ids == expect["ids"]
    np.testing.assert_array_equal(rec.posterior > 0, expect["posterior"] > 0)
    tol = dict(rtol=0, atol=0) if exact_arrays else dict(rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(rec.posterior, expect["posterior"], **tol)
    np.testing.assert_allclose(rec.log_likelihoods, expect["log_likelihoods"], **tol)
    np.testing.assert_array_equal(rec.phases, expect["phases"])


def _probes(bank, rng, n=12):
    """Whole motions and prefixes of taught skills, and motions of a skill never taught."""
    other = skill_bank(1, rng).demo(0, rng).human
    out = [other, other[:40]]
    for i in range(n):
        h = bank.demo(int(rng.integers(bank.n_skills)), rng).human
        out += [h, h[: int(len(h) * rng.uniform(0.25, 0.9))]]
    return out


def _reference_answers(lib, ref, human):
    """Whole-motion and prefix answers of the reference for one motion."""
    shared = lib.shared_covariance("expert")
    y_whole = lib.human_samples(human)
    y, length = lib._normalized(human, None, False)
    return (ref.recognize_fixed(y_whole, 1.0, lib.has_robot, shared),
            ref.recognize_prefix(y, length, lib.has_robot, shared))


@pytest.fixture(scope="module")
def synthetic_library():
    bank, demos, rng = _stream(40, "random", seed=3)
    lib, ref = _learn_both(demos)
    return bank, lib, ref, rng


def test_recognize_answers_as_the_brute_force_reference(synthetic_library):
    """Whole motions (one matrix product) and prefixes (phase searched per component): same answers."""
    bank, lib, ref, rng = synthetic_library
    statuses = set()
    for human in _probes(bank, rng):
        whole, prefix = _reference_answers(lib, ref, human)
        _assert_same_answer(lib.recognize(human, observed_fraction=1.0), whole)
        _assert_same_answer(lib.recognize(human), prefix, exact_arrays=False)
        statuses |= {whole["status"], prefix["status"]}
    assert {"skill", "unknown"} <= statuses


def test_recognize_answers_as_the_reference_on_letters_with_undecided_answers(letters):
    demos, ws = letters
    rng = np.random.default_rng(4)
    order = rng.permutation(len(demos))
    train, test = order[:30], order[30:]
    lib, ref = _learn_both([demos[j] for j in train], LibraryConfig(workspace=ws))
    statuses = set()
    for j in test:
        h = demos[j].human
        for human in (h, h[: len(h) // 2]):
            whole, prefix = _reference_answers(lib, ref, human)
            _assert_same_answer(lib.recognize(human, observed_fraction=1.0), whole)
            _assert_same_answer(lib.recognize(human), prefix, exact_arrays=False)
            statuses |= {whole["status"], prefix["status"]}
    assert {"skill", "unknown", "undecided"} <= statuses, statuses
