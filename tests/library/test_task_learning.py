"""The teacher's task names in learning: one task's components merge within ``same_task_reach`` merge limits (and
its halves split only beyond as many split limits); a demonstration taught as another task never joins a component,
and two components taught as different tasks never merge (``keep_tasks_apart``). Libraries built by hand, the
distances set in merge (split) limits, checked against numbers computed here."""
from dataclasses import replace

import numpy as np
import pytest

from drake_skills import LibraryConfig
from drake_skills.library.novelty import chi2_ppf
from drake_skills.library.scale import Cluster
from drake_skills.library.state import ComponentState

import library_states as ls
from synthetic import synthetic_demo

H = 15
#: 5 basis functions x 3-D wrist, no robot; no deletions; consolidation 0 (a pair's merge limit is the quantile).
BASE = dict(n_samples=30, n_basis_human=5, n_basis_robot=5, delete_min_age=1000, consolidation=0.0)
#: Names counted only: the paper's update.
COUNTED = dict(same_task_reach=1.0, keep_tasks_apart=False)


def _demo(task="z"):
    return replace(synthetic_demo(0, np.random.default_rng(0), T=30, robot=False), task=task)


def _named(comp: ComponentState, name):
    tasks = () if name is None else ((name, comp.cluster.support),)
    cl = replace(comp.cluster, tasks=tasks)
    return ComponentState(comp.id, comp.age, cl, (cl, None))


def _pair(cfg, factor, names, *, supports=(3.0, 3.0), limit=None, scale=None):
    """Two components (ids 0, 1) of ``supports`` at ``factor`` times ``limit`` (default: the merge limit) of each
    other (two-sample distance under the library's gating covariance), far from the demonstration of
    :func:`_demo`, named ``names``; ``scale``: the library's shared scale (default ``library_states.iso_scale``)."""
    w = ls.encode(cfg, _demo())
    g = ls.library(cfg, [], dim_human=3, dim_robot=0, scale=scale).shared_covariance()[0, 0]
    u = ls.unit(np.random.default_rng(1), H)
    a = w + np.sqrt(g) * 60.0 * ls.unit(np.random.default_rng(2), H)
    limit = chi2_ppf(cfg.merge_quantile, H) if limit is None else limit
    b = a + u * np.sqrt(factor * limit * g * (1.0 / supports[0] + 1.0 / supports[1]))
    comps = [_named(ls.component(i, m, support=s, age=5), n)
             for i, (m, n, s) in enumerate(zip((a, b), names, supports))]
    return ls.library(cfg, comps, dim_human=3, dim_robot=0, n_seen=5, scale=scale)


@pytest.mark.parametrize("factor, names, merges", [
    (1.5, ("a", "a"), True),      # one task, within the reach (2): merged
    (1.98, ("a", "a"), True),
    (2.02, ("a", "a"), False),    # beyond it: two
    (1.5, ("a", "b"), False),     # two tasks: never, not even within one merge limit
    (0.5, ("a", "b"), False),
    (0.5, ("a", None), True),     # an unnamed one: the paper's test
    (1.5, ("a", None), False),
    (1.5, (None, None), False),
])
def test_components_merge_by_their_names_within_the_reach(factor, names, merges):
    cfg = LibraryConfig(**BASE)
    lib = _pair(cfg, factor, names)
    step = lib.partial_fit(_demo())
    assert (step.merged == ((0, 1),)) == merges, step.merged
    assert lib.n_components == (2 if merges else 3)


@pytest.mark.parametrize("factor, names, merges", [
    (1.5, ("a", "a"), False), (0.5, ("a", "b"), True), (0.5, ("a", None), True)])
def test_with_the_names_only_counted_the_paper_merges_by_distance_alone(factor, names, merges):
    cfg = LibraryConfig(**BASE, **COUNTED)
    step = _pair(cfg, factor, names).partial_fit(_demo())
    assert (step.merged == ((0, 1),)) == merges


def test_the_reach_is_the_setting():
    cfg = LibraryConfig(**BASE, same_task_reach=3.0)
    assert _pair(cfg, 2.9, ("a", "a")).partial_fit(_demo()).merged == ((0, 1),)
    assert _pair(cfg, 3.1, ("a", "a")).partial_fit(_demo()).merged == ()


def test_a_mixed_component_is_no_task_for_merging():
    """A component whose other names hold mixed_task_share or more is unnamed for the rules: it merges with a
    component of either name by distance alone."""
    cfg = LibraryConfig(**BASE)
    lib = _pair(cfg, 0.5, ("a", "b"))
    c0 = lib.state().components[0]
    mixed = replace(c0.cluster, tasks=(("a", 2.0), ("b", 1.0)))
    comps = (ComponentState(0, c0.age, mixed, (mixed, None)), lib.state().components[1])
    lib = ls.library(cfg, list(comps), dim_human=3, dim_robot=0, n_seen=5)
    assert lib.partial_fit(_demo()).merged == ((0, 1),)


def _split_case(cfg, factor, names):
    """One component (id 0) whose two halves (support 3 each, no scatter) lie ``factor`` split limits apart."""
    w = ls.encode(cfg, _demo())
    g = ls.library(cfg, [], dim_human=3, dim_robot=0).shared_covariance()[0, 0]
    a = w + np.sqrt(g) * 60.0 * ls.unit(np.random.default_rng(2), H)
    b = a + ls.unit(np.random.default_rng(1), H) * np.sqrt(factor * chi2_ppf(cfg.split_quantile, H) * g * 2.0 / 3.0)
    halves = [Cluster(3.0, m, np.zeros((H, 0)), 1.0, 5.0) for m in (a, b)]
    halves = [replace(x, tasks=() if n is None else n if isinstance(n, tuple) else ((n, 3.0),))
              for x, n in zip(halves, names)]
    whole, _ = halves[0].pool(halves[1])
    return ls.library(cfg, [ComponentState(0, 5, whole, tuple(halves))], dim_human=3, dim_robot=0, n_seen=5)


@pytest.mark.parametrize("factor, names, counted, splits", [
    (1.5, ("a", "a"), False, False),   # one task's halves within the reach of the split limit: kept
    (2.5, ("a", "a"), False, True),
    (1.5, ("a", "a"), True, True),     # names counted only: the split limit
    (1.5, (None, None), False, True),
    (1.5, ("a", None), False, True),
    # a half taught as "a" with other names holding mixed_task_share (0.2, exactly) or more has no task
    (1.5, ("a", (("a", 2.0), ("b", 0.5))), False, True),
    (1.5, ("a", (("a", 2.5), ("b", 0.5))), False, False),   # 1/6 of other names: it is "a"
])
def test_halves_of_one_task_split_only_beyond_the_reach(factor, names, counted, splits):
    cfg = LibraryConfig(**BASE, **(COUNTED if counted else {}))
    step = _split_case(cfg, factor, names).partial_fit(_demo())
    assert bool(step.split) == splits, step.split


@pytest.mark.parametrize("task, joins", [("a", True), (None, True), ("b", False)])
def test_a_demonstration_taught_as_another_task_joins_no_component(task, joins):
    """A component taught as "a" sits on the demonstration: "a" or no name joins it; "b" is a new component (and,
    two tasks, the two never merge); with the names only counted "b" joins it too."""
    cfg = LibraryConfig(**BASE)
    w = ls.encode(cfg, _demo())
    lib = ls.library(cfg, [_named(ls.component(0, w, support=3.0, age=5), "a")], dim_human=3, dim_robot=0, n_seen=5)
    step = lib.partial_fit(_demo(task))
    assert (step.updated == (0,)) == joins and (step.created == ()) == joins
    assert lib.n_components == (1 if joins else 2) and step.merged == ()
    counted = ls.library(LibraryConfig(**BASE, **COUNTED), [_named(ls.component(0, w, support=3.0, age=5), "a")],
                         dim_human=3, dim_robot=0, n_seen=5)
    assert counted.partial_fit(_demo(task)).updated == (0,)


def test_config_refuses_a_reach_below_one_and_a_flag_that_is_not_a_bool():
    for bad in (0.5, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="same_task_reach"):
            LibraryConfig(same_task_reach=bad)
    with pytest.raises(ValueError, match="keep_tasks_apart"):
        LibraryConfig(keep_tasks_apart="no")
    assert (LibraryConfig().same_task_reach, LibraryConfig().keep_tasks_apart) == (2.0, True)


def test_a_component_seen_once_keeps_its_stricter_limit_whatever_the_names():
    """While the shared scale is more prior than data, a pair with a component seen once merges only within the
    single-demonstration quantile of the distance itself: the name widens the merge limit, not that one. The
    scale's 1 degree of freedom is below ``prior_strength``; the supports are 1 and 3 (one young, so
    ``keep_single_demos_apart`` plays no part); 1.5 young limits lie within 2 merge limits."""
    cfg = LibraryConfig(**BASE)
    scale = ls.iso_scale(H, 1.0, dof=1.0)
    assert scale.dof < cfg.prior_strength
    young = chi2_ppf(cfg.single_demo_quantile, H)
    assert 1.5 * young < 2.0 * chi2_ppf(cfg.merge_quantile, H)
    for factor, merges in ((1.5, False), (0.8, True)):
        lib = _pair(cfg, factor, ("a", "a"), supports=(1.0, 3.0), limit=young, scale=scale)
        assert bool(lib.partial_fit(_demo()).merged) == merges, factor


def test_with_the_loglik_test_two_tasks_never_merge_and_one_task_does():
    cfg = LibraryConfig(**BASE, novelty_test="loglik", log_T_nov=1e3, log_T_merge=-40.0)
    for names, merges in ((("a", "b"), False), (("a", "a"), True), (("a", None), True)):
        lib = _pair(cfg, 0.0, names)                                          # the same mean: merged by distance
        assert (lib.partial_fit(_demo()).merged == ((0, 1),)) == merges, names


@pytest.mark.parametrize("task, tested", [("b", [1]), ("a", [0]), (None, [0])])
def test_a_novel_demonstration_s_beginnings_are_tested_against_the_nearest_component_it_may_join(task, tested):
    """A new component keeps its beginnings' test against the nearest component (counted if they merge later):
    for a demonstration taught as "b", the nearest it may join (component 1, unnamed, farther) rather than the
    nearer one taught as "a" (component 0)."""
    cfg = LibraryConfig(**BASE)
    w = ls.encode(cfg, _demo())
    g = ls.library(cfg, [], dim_human=3, dim_robot=0).shared_covariance()[0, 0]
    u = ls.unit(np.random.default_rng(3), H)
    comps = [_named(ls.component(0, w + 12.0 * np.sqrt(g) * u, support=3.0, age=5), "a"),
             _named(ls.component(1, w + 20.0 * np.sqrt(g) * u, support=3.0, age=5), None)]
    lib = ls.library(cfg, comps, dim_human=3, dim_robot=0, n_seen=5)
    calls = []
    lib._beginnings_missed = lambda path, k: calls.append(k) or np.array([0.0, 0.0])
    step = lib.partial_fit(_demo(task))
    assert step.created and calls == tested


def test_a_novel_demonstration_of_a_task_no_component_may_take_tests_no_beginnings():
    cfg = LibraryConfig(**BASE)
    w = ls.encode(cfg, _demo())
    g = ls.library(cfg, [], dim_human=3, dim_robot=0).shared_covariance()[0, 0]
    comp = _named(ls.component(0, w + 12.0 * np.sqrt(g) * ls.unit(np.random.default_rng(3), H), support=3.0, age=5),
                  "a")
    lib = ls.library(cfg, [comp], dim_human=3, dim_robot=0, n_seen=5)
    calls = []
    lib._beginnings_missed = lambda path, k: calls.append(k) or np.array([0.0, 0.0])
    assert lib.partial_fit(_demo("b")).created and calls == []
    assert np.isnan(lib.state().components[-1].cluster.pending).all()
