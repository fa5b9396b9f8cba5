"""Property tests over random demonstration streams: every update keeps the library's invariants (hypothesis).

Each example is a stream of demonstrations drawn from a few kinds (repeats of one of
four skills at several noise levels, pure novelty, identical repeats, 5-sample
motions, slow and fast versions) folded in one at a time; after every update
:func:`~drake_skills.library.invariants.invariant_violations` must find nothing
(the sums kept in two places agree, the shared covariance is SPD), the counts add
up, and recognition and prediction of a stream member are finite. About 2,000 updates
in all (40 streams of 20-80), ~5 s of CPU; the soak benchmark (``drake-skills bench
--suite soak``) runs the same check over 100,000.
"""
import numpy as np
from hypothesis import HealthCheck, Phase, event, given, settings
from hypothesis import strategies as st

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.library.invariants import invariant_violations

from synthetic import synthetic_demo

#: One demonstration of the stream: (kind, task, seed).
KINDS = ("skill", "noisy", "wide", "novel", "repeat", "short", "slow")
#: "wide" four times as often: its streams are the ones that merge and split.
EVENT = st.tuples(st.sampled_from(KINDS + ("wide",) * 3), st.integers(0, 3), st.integers(0, 2 ** 31 - 1))
#: The library's defaults, and settings that make deletions, merges and splits frequent.
CONFIGS = (LibraryConfig(), LibraryConfig(delete_min_age=3, novelty_quantile=0.99, merge_quantile=0.99, split_quantile=0.995),
           LibraryConfig(novelty_quantile=0.99999, merge_quantile=0.99, split_quantile=0.995))


def _demo(kind: str, task: int, seed: int, last):
    rng = np.random.default_rng(seed)
    if kind == "repeat" and last is not None:
        return last
    if kind == "novel":  # a reach to anywhere
        d = synthetic_demo(task, rng, noise=6.0)
    elif kind == "wide":  # one skill spread so wide that its components merge and split
        d = synthetic_demo(task, rng, noise=3.0)
    elif kind == "noisy":
        d = synthetic_demo(task, rng, noise=1.0)
    elif kind == "short":
        d = synthetic_demo(task, rng, T=5)
    elif kind == "slow":
        d = synthetic_demo(task, rng, scale=4.0)
    else:
        d = synthetic_demo(task, rng)
    return d


@settings(max_examples=40, deadline=None, derandomize=True, phases=(Phase.generate, Phase.shrink),
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(stream=st.lists(EVENT, min_size=20, max_size=80), which=st.sampled_from([0, 1, 2, 2]))
def test_every_update_of_a_random_stream_keeps_the_invariants(stream, which):
    lib = SkillLibrary(CONFIGS[which])
    last = None
    for n, (kind, task, seed) in enumerate(stream, 1):
        last = _demo(kind, task, seed, last)
        u = lib.partial_fit(last)
        problems = invariant_violations(lib.state(), check_covariance=n % 10 == 0 or n == len(stream))
        assert not problems, (n, kind, problems)
        assert lib.n_seen == n and lib.state().scale.n == n
        assert set(u.created) <= {c.id for c in lib.components} | set(u.deleted) | {b for _, b in u.merged}
    for e in {e["event"] for e in lib.history}:
        event(e)  # --hypothesis-show-statistics: how often streams create, merge, split and delete
    ids = [c.id for c in lib.components]
    assert len(set(ids)) == len(ids) and all(0 <= i < lib.state().next_id for i in ids)
    if lib.n_components:
        rec = lib.recognize(last.human, observed_fraction=1.0)
        assert np.isfinite(rec.posterior).all() and rec.status in {"skill", "undecided", "unknown"}
        mean, cov = lib.predict_robot(last.human[: max(2, len(last.t) // 2)], component=ids[-1])
        assert np.isfinite(mean).all() and np.isfinite(cov).all()


def test_the_invariant_check_finds_a_broken_sum():
    """The property above can fail: one wrong term in the pooled scatter or a sub-cluster is reported."""
    import dataclasses

    rng = np.random.default_rng(0)
    lib = SkillLibrary()
    for i in range(12):
        lib.partial_fit(synthetic_demo(i % 3, rng))
    state = lib.state()
    assert invariant_violations(state) == []
    sc = state.scale
    bad = dataclasses.replace(state, scale=dataclasses.replace(sc, pooled=sc.pooled * (1 + 1e-6)))
    assert any("pooled scatter" in p for p in invariant_violations(bad))
    c = next(c for c in state.components if c.subclusters[1] is not None)
    a, b = c.subclusters
    shifted = dataclasses.replace(c, subclusters=(dataclasses.replace(a, mean=a.mean + 1e-3), b))
    comps = tuple(shifted if x is c else x for x in state.components)
    assert any(f"component {c.id}: its sub-clusters' mean" in p
               for p in invariant_violations(dataclasses.replace(state, components=comps)))
