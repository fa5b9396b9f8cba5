"""Invariants of the library over streams of demonstrations (hypothesis, derandomized).

Streams mix novel skills, repeats, near-duplicates, tiny and 5-sample motions, random
wiggles, human-only and with robot, and bad demonstrations. After every update: each
covariance is exactly symmetric and positive definite, supports and ages agree with
what the stream did (supports sum to the demonstrations kept; a component is as old as
the oldest demonstration it holds), ids and history agree with the Updates, every
prediction is finite, and a failed update leaves the library as it was.
The long soak (thousands of updates) is a benchmark, not a test.
"""
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drake_skills import Demonstration, LibraryConfig, SkillLibrary

from synthetic import synthetic_demo

T = 24  # samples per demonstration (5 for the short ones)

KINDS = ["task", "task", "task", "repeat", "near_duplicate", "tiny", "short", "wiggle", "bad"]


def _config(novelty_test, duplicates=False):
    if duplicates:
        # Sigma_init far below the skill's scatter (noise 0.6): duplicates of a skill are created, then merge
        return LibraryConfig(n_samples=20, n_basis_human=5, n_basis_robot=4, sigma_init_human=0.05,
                             gating_floor=0.05, merge_min_age=3, delete_min_age=15, novelty_test=novelty_test)
    # a short deletion age makes deletions common
    return LibraryConfig(n_samples=20, n_basis_human=4, n_basis_robot=4, sigma_init_human=0.3, gating_floor=0.05,
                         merge_min_age=2, delete_min_age=8, novelty_test=novelty_test, log_T_nov=-25.0)


def _demo(kind, task, noise, seed, robot, previous):
    rng = np.random.default_rng(seed)
    if kind in ("repeat", "near_duplicate") and previous:
        d = previous[seed % len(previous)]
        if kind == "repeat":
            return d
        human = d.human + 1e-6 * rng.standard_normal(d.human.shape)
        return Demonstration(t=d.t, human=human, robot=d.robot)
    if kind == "wiggle":  # an outlier: a random walk
        t = np.linspace(0, 1, T)
        return Demonstration(t=t, human=np.cumsum(rng.normal(0, 1.0, (T, 3)), axis=0),
                             robot=rng.normal(0, 0.5, (T, 7)) if robot else None)
    d = synthetic_demo(task, rng, T=5 if kind == "short" else T, noise=noise, robot=robot)
    if kind == "tiny":
        return Demonstration(t=d.t, human=1e-3 * d.human, robot=d.robot)
    return d


def _bad(seed, robot, good):
    """A demonstration this library must refuse: wrong columns, missing/extra robot, or no motion."""
    which = seed % 3
    if which == 0:
        return Demonstration(t=good.t, human=good.human[:, :2], robot=good.robot)
    if which == 1:
        return Demonstration(t=good.t, human=good.human, robot=None if robot else np.zeros((len(good.t), 7)))
    return Demonstration(t=good.t, human=np.ones_like(good.human), robot=good.robot)


def _snapshot(lib):
    return (lib.n_seen, lib.history,
            [(c.id, c.age, c.support, c.duration, c.mean.tobytes(), c.cov.tobytes()) for c in lib.components])


class _Tracker:
    """What the stream did, kept independently of the library: creation index of each id, deleted support."""

    def __init__(self):
        self.origin = {}
        self.deleted_support = 0.0
        self.next_id = 0

    def follow(self, u):
        for k in u.created:
            assert k == self.next_id, (k, self.next_id)  # ids are never reused
            self.next_id += 1
            self.origin[k] = u.demo_index
        for keep, gone in u.merged:
            self.origin[keep] = min(self.origin[keep], self.origin.pop(gone))
        for k in u.deleted:
            self.origin.pop(k)


def _check(lib, tracker, u, n):
    comps = lib.components
    assert lib.n_seen == n
    assert [c.id for c in comps] == sorted(tracker.origin)
    for c in comps:
        assert np.array_equal(c.cov, c.cov.T), c.id
        assert np.linalg.eigvalsh(c.cov).min() > 0, f"component {c.id} lost definiteness"
        assert np.isfinite(c.mean).all() and np.isfinite(c.duration) and c.duration > 0
        assert 0 < c.support <= n
        assert c.age == n - tracker.origin[c.id]  # as old as the oldest demonstration it holds
    deleted = sum(e["support"] for e in lib.history if e["event"] == "deleted")
    # every demonstration adds support 1 (a new component, or responsibilities summing to 1); merges keep it
    assert sum(c.support for c in comps) + deleted == pytest.approx(n, abs=1e-5 * (1 + len(lib.history)))
    created = [e["id"] for e in lib.history if e["event"] == "created"]
    assert created == list(range(tracker.next_id))
    assert not set(u.deleted) & {c.id for c in comps}
    assert not {g for _, g in u.merged} & {c.id for c in comps}
    if u.created:
        assert u.recognized is None and u.updated == () and u.responsibilities == {}
    else:
        assert u.recognized is not None and sum(u.responsibilities.values()) == pytest.approx(1.0, abs=1e-9)


def _check_predictions(lib, human):
    rec = lib.recognize(human)
    assert np.isfinite(rec.log_likelihoods).all() and np.isfinite(rec.mahalanobis_sq).all()
    if lib.n_components:
        assert rec.responsibilities.sum() == pytest.approx(1.0, abs=1e-9)
    prefix = lib.recognize(human[:max(2, len(human) // 2)], observed_fraction=0.5)
    assert np.isfinite(prefix.log_likelihoods).all()
    if lib.has_robot and rec.component is not None:
        mean, cov = lib.predict_robot(human, n_steps=10)
        assert np.isfinite(mean).all() and np.isfinite(cov).all()
        assert (np.einsum("tii->ti", cov) > -1e-9).all()


def _run(stream, robot, novelty_test, duplicates=False):
    lib = SkillLibrary(_config(novelty_test, duplicates))
    tracker = _Tracker()
    previous = []
    events = set()
    n = 0
    for kind, task, noise, seed in stream:
        if kind == "bad" and previous:
            before = _snapshot(lib)
            with pytest.raises(ValueError):
                lib.partial_fit(_bad(seed, robot, previous[-1]))
            assert _snapshot(lib) == before
            continue
        d = _demo(kind, task, noise, seed, robot, previous)
        u = lib.partial_fit(d)
        n += 1
        assert u.demo_index == n - 1
        tracker.follow(u)
        _check(lib, tracker, u, n)
        _check_predictions(lib, d.human)
        previous.append(d)
        events |= {e["event"] for e in lib.history}
    return lib, events


_step = st.tuples(st.sampled_from(KINDS), st.integers(0, 3), st.sampled_from([0.05, 0.15, 0.8]),
                  st.integers(0, 2 ** 31 - 1))


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(stream=st.lists(_step, min_size=1, max_size=30), robot=st.booleans(),
       novelty_test=st.sampled_from(["chi2", "loglik"]), duplicates=st.booleans())
def test_library_invariants_hold_over_random_streams(stream, robot, novelty_test, duplicates):
    _run(stream, robot, novelty_test, duplicates)


def test_a_long_fixed_stream_creates_merges_and_deletes_and_keeps_every_invariant():
    """One deterministic stream of 150 demonstrations of two skills (noise 0.6) with outliers, repeats,
    near-duplicates, short, tiny and bad ones, where every kind of event happens."""
    rng = np.random.default_rng(9)
    kinds = ["task"] * 6 + ["wiggle", "repeat", "near_duplicate", "short", "tiny", "bad"]
    stream = [(kinds[int(rng.integers(len(kinds)))], int(rng.integers(2)), 0.6, int(rng.integers(2 ** 31 - 1)))
              for _ in range(150)]
    lib, events = _run(stream, True, "chi2", duplicates=True)
    assert {"created", "merged", "deleted"} <= events, events
    assert lib.n_seen == 150 - sum(k == "bad" for k, *_ in stream)
