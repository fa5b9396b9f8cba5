"""Task names (Demonstration.task) kept with the clusters, and skills taught as several tasks not acted on."""
import json
from dataclasses import replace

import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.library.recognition import undecided_reason
from drake_skills.library.scale import Cluster, main_task, mixed_share, pooled_tasks, with_task
from drake_skills.library.views import UnknownSkillError
from synthetic import WORKSPACE, synthetic_demo


def test_task_weights_are_a_moment_of_the_cluster():
    w = np.zeros(3)
    a = Cluster.of_sample(w, 1.0, 1.0, task="tomato")
    assert a.tasks == (("tomato", 1.0),)
    assert Cluster.of_sample(w, 1.0, 1.0).tasks == ()                       # no name, no weight
    assert Cluster.of_sample(w, 1.0, 1.0, support=0.25, task="x").tasks == (("x", 0.25),)
    b = a.add(np.ones(3), 0.4, 1.0, 1.0, task="bowl")[0]
    assert b.tasks == (("bowl", 0.4), ("tomato", 1.0))                      # sorted by name, at the weight
    assert b.add(np.ones(3), 1.0, 1.0, 1.0)[0].tasks == b.tasks              # an unnamed demonstration adds none
    c = b.add(np.ones(3), 0.5, 1.0, 1.0, task="tomato")[0]
    assert c.tasks == (("bowl", 0.4), ("tomato", 1.5))
    assert c.pool(b)[0].tasks == (("bowl", 0.8), ("tomato", 2.5))
    assert with_task((), None, 1.0) == () and pooled_tasks((), (("a", 1.0),)) == (("a", 1.0),)
    assert mixed_share(c.tasks) == pytest.approx(0.4 / 1.9) and mixed_share(()) == 0.0
    assert mixed_share((("a", 2.0),)) == 0.0
    assert main_task(c.tasks) == "tomato" and main_task(()) is None
    assert main_task((("a", 1.0), ("b", 1.0))) == "a"                        # a tie: the first name
    assert main_task((("a", 0.0),)) is None and main_task((("a", 0.0), ("b", 0.5))) == "b"  # no weight, no name


def _library(tasks, *, names=True, seed=0, **cfg):
    """Three synthetic skills x 6; ``tasks``: the name each skill's demonstrations are taught under."""
    rng, names_rng = np.random.default_rng(seed), np.random.default_rng(seed + 1)
    lib = SkillLibrary(LibraryConfig(workspace=WORKSPACE, **cfg))
    order = [k for _ in range(6) for k in range(3)]
    for i in rng.permutation(len(order)):
        d = synthetic_demo(order[i], rng)
        k = order[i]
        name = tasks[k] if isinstance(tasks[k], str) else tasks[k](names_rng)
        lib.partial_fit(replace(d, task=name if names else None))
    return lib


#: Names counted, not used to learn (the paper's update): what a library did before ``keep_tasks_apart`` and
#: ``same_task_reach``, and still does where a stream is unnamed.
COUNTED = dict(keep_tasks_apart=False, same_task_reach=1.0)


def _taught_as_two(rng):
    return ("bowl", "tomato")[int(rng.integers(2))]


def test_the_weights_follow_responsibilities_and_sum_to_each_component_support():
    lib = _library(("a", "b", "c"))
    for c in lib._components.items:
        assert sum(w for _, w in c.cluster.tasks) == pytest.approx(c.support, rel=1e-9)
        assert mixed_share(c.cluster.tasks) < 1e-6
        for half in c.subclusters:
            if half is not None:
                assert sum(w for _, w in half.tasks) == pytest.approx(half.support, rel=1e-9)


def test_a_skill_taught_under_two_names_is_undecided_and_says_why():
    """Skill 0's demonstrations are named "bowl" or "tomato" at random (one motion, two tasks: the wrist cannot tell
    them apart), learned with the names counted only (one mixed component): the library does not act on it.
    Skills 1 and 2, named once each, answer as before."""
    lib = _library((_taught_as_two, "b", "c"), **COUNTED)
    q = [synthetic_demo(k, np.random.default_rng(50 + k)) for k in range(3)]
    rec = lib.recognize(q[0].human, observed_fraction=1.0)
    k0 = lib.recognize(q[0].human, observed_fraction=1.0).contested[0]
    assert rec.status == "undecided" and rec.component is None and rec.contested == (k0,)
    assert mixed_share(lib._model(k0).cluster.tasks) >= 0.2
    assert undecided_reason(rec) == f"taught as several tasks: {k0}"
    with pytest.raises(UnknownSkillError, match="taught under more than one task name"):
        lib.predict_robot(q[0].human)
    # beginnings too: undecided for the names where the phase is searched; at 0.6 of the path the prefix
    # (80 of 100 samples) fits no skill's first 60 %
    assert lib.recognize(q[0].human[:80]).status == "undecided"
    assert lib.recognize(q[0].human[:80]).contested == (k0,)
    assert lib.recognize(q[0].human[:80], observed_fraction=0.6).status == "unknown"
    for k in (1, 2):
        r = lib.recognize(q[k].human, observed_fraction=1.0)
        assert r.status == "skill" and r.contested == ()
    # the setting off (1), or the same demonstrations without names: the skill is answered
    for other in (_library((_taught_as_two, "b", "c"), mixed_task_share=1.0, **COUNTED),
                  _library((_taught_as_two, "b", "c"), names=False)):
        r = other.recognize(q[0].human, observed_fraction=1.0)
        assert r.status == "skill" and r.component == k0 and r.contested == ()


def test_the_share_at_which_a_skill_is_not_acted_on():
    lib = _library(("a", "b", "c"))
    q = synthetic_demo(0, np.random.default_rng(50)).human
    k = lib.recognize(q, observed_fraction=1.0).component
    row = lib._components.index(k)
    items = list(lib._components.items)
    c = items[row]
    s = c.support
    from drake_skills.library.algorithm import ComponentModel, Components

    for share, status in ((0.19, "skill"), (0.2, "undecided"), (0.21, "undecided")):
        tasks = (("a", s * (1 - share)), ("z", s * share))
        items[row] = ComponentModel(c.id, c.created, replace(c.cluster, tasks=tasks), c.subclusters)
        lib._components = Components.of(items, lib.n_human)
        assert lib.recognize(q, observed_fraction=1.0).status == status, share


def test_a_skill_taught_as_another_task_does_not_answer_like_the_best_one():
    """Two components with the same robot response: one answers for both (same response), unless they were taught
    under different names."""
    lib = _library(("a", "b", "c"))
    q = synthetic_demo(0, np.random.default_rng(50)).human
    best = lib._components.index(lib.recognize(q, observed_fraction=1.0).component)
    items = list(lib._components.items)
    other = 1 - best if best < 2 else 0
    h = lib.n_human
    cand = np.zeros(len(items), bool)
    cand[[best, other]] = True
    from drake_skills.library.algorithm import ComponentModel, Components

    c = items[other]
    same_response = np.concatenate([c.cluster.mean[:h], items[best].cluster.mean[h:]])
    for tasks, pooled in ((items[best].cluster.tasks, True), (c.cluster.tasks, False), ((), True)):
        items[other] = ComponentModel(c.id, c.created, replace(c.cluster, mean=same_response, tasks=tasks),
                                      c.subclusters)
        lib._components = Components.of(items, lib.n_human)
        assert bool(lib._same_response(best, cand)[other]) == pooled, tasks
        # every task setting off (as a file written before task names loads): the names say nothing, the response
        # does; with either learning setting on the names are in use and the filter holds
        off = dict(mixed_task_share=1.0, other_task_reach=0.0, **COUNTED)
        lib_off = SkillLibrary.from_state(replace(lib.state(), config=replace(lib.config, **off)))
        assert bool(lib_off._same_response(best, cand)[other]), tasks
        for on in (dict(keep_tasks_apart=True), dict(same_task_reach=2.0)):
            lib_on = SkillLibrary.from_state(replace(lib.state(), config=replace(lib.config, **{**off, **on})))
            assert bool(lib_on._same_response(best, cand)[other]) == pooled, (tasks, on)


def test_task_weights_survive_a_file_and_a_file_without_them_loads_with_none_and_the_rule_off(tmp_path):
    lib = _library((_taught_as_two, "b", "c"), **COUNTED)
    p = lib.save(tmp_path / "lib.npz")
    back = SkillLibrary.load(p)
    for a, b in zip(lib._components.items, back._components.items):
        assert a.cluster.tasks == b.cluster.tasks
        assert [x.tasks for x in a.subclusters if x is not None] == [x.tasks for x in b.subclusters if x is not None]
    assert back.config.mixed_task_share == 0.2 and (back.config.same_task_reach, back.config.keep_tasks_apart) == (
        1.0, False)                                                         # as learned: the file keeps the config
    with np.load(p, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["metadata"]))
    for c in meta["components"]:
        c.pop("tasks")
        for s in c["subclusters"]:
            if s is not None:
                s.pop("tasks")
    for key in ("mixed_task_share", "other_task_reach", "same_task_reach", "keep_tasks_apart"):
        del meta["config"][key]
    arrays["metadata"] = np.array(json.dumps(meta))
    np.savez(tmp_path / "old.npz", **arrays)
    old = SkillLibrary.load(tmp_path / "old.npz")
    assert all(c.cluster.tasks == () for c in old._components.items)
    assert (old.config.mixed_task_share, old.config.other_task_reach) == (1.0, 0.0)
    assert (old.config.same_task_reach, old.config.keep_tasks_apart) == (1.0, False)  # it learns on as it did
    # it answers as the same library did before task names: the mixed skill is acted on
    unnamed = _library((_taught_as_two, "b", "c"), names=False, mixed_task_share=1.0, other_task_reach=0.0)
    for k in range(3):
        q = synthetic_demo(k, np.random.default_rng(50 + k)).human
        a, b = old.recognize(q, observed_fraction=1.0), unnamed.recognize(q, observed_fraction=1.0)
        assert (a.status, a.component) == (b.status, b.component) and a.status == "skill", k
        np.testing.assert_allclose(a.posterior, b.posterior, rtol=1e-9, atol=1e-12)
    meta["components"][0]["tasks"] = {"a": -1.0}
    arrays["metadata"] = np.array(json.dumps(meta))
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(ValueError, match="tasks must map task names to weights >= 0"):
        SkillLibrary.load(tmp_path / "bad.npz")
    meta["components"][0]["tasks"] = {"a": 10 ** 400}                       # an integer no float holds
    arrays["metadata"] = np.array(json.dumps(meta))
    np.savez(tmp_path / "huge.npz", **arrays)
    with pytest.raises(ValueError, match=r"huge\.npz.*OverflowError"):
        SkillLibrary.load(tmp_path / "huge.npz")


def test_learning_is_the_same_with_and_without_task_names_when_they_are_only_counted():
    """``COUNTED``: the names are counted, never used to learn: the same components, means and supports."""
    a, b = _library((_taught_as_two, "b", "c"), **COUNTED), _library((_taught_as_two, "b", "c"), names=False)
    assert [c.id for c in a._components.items] == [c.id for c in b._components.items]
    for x, y in zip(a._components.items, b._components.items):
        np.testing.assert_array_equal(x.mean, y.mean)
        assert x.support == y.support


def test_config_refuses_a_share_outside_zero_one():
    for bad in (0.0, -0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match="mixed_task_share"):
            LibraryConfig(mixed_task_share=bad)
    for bad in (-0.1, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="other_task_reach"):
            LibraryConfig(other_task_reach=bad)
    assert LibraryConfig(other_task_reach=0.0).other_task_reach == 0.0     # 0: off


def test_a_skill_with_a_skill_taught_as_another_task_near_it_is_undecided():
    """Skill 1's component moved to 1.5 (then 2.5) merge limits of skill 0's (two-sample distance): within
    other_task_reach (2) a motion of skill 0 is undecided, naming it; beyond, or with the reach 0, answered."""
    from drake_skills.library.algorithm import ComponentModel, Components
    from drake_skills.library.novelty import chi2_ppf

    lib = _library(("a", "b", "c"))
    q = synthetic_demo(0, np.random.default_rng(50)).human
    k0 = lib.recognize(q, observed_fraction=1.0).component
    r0 = lib._components.index(k0)
    items = list(lib._components.items)
    r1 = next(i for i in range(len(items)) if main_task(items[i].cluster.tasks) == "b")
    h = lib.n_human
    metric = lib._metric()
    z0 = metric.whiten(items[r0].cluster.mean[:h])
    u = np.zeros(h)
    u[0] = 1.0
    inflate = 1.0 / items[r0].support + 1.0 / items[r1].support
    limit = chi2_ppf(lib.config.merge_quantile, h)
    c1 = items[r1]
    for factor, undecided in ((1.5, True), (2.5, False)):
        z1 = z0 + u * np.sqrt(factor * limit * inflate)                 # two-sample d2 = factor x limit
        mean = c1.cluster.mean.copy()
        mean[:h] = metric.chol @ z1
        items[r1] = ComponentModel(c1.id, c1.created, replace(c1.cluster, mean=mean), c1.subclusters)
        lib._components = Components.of(items, h)
        rec = lib.recognize(q, observed_fraction=1.0)
        assert (rec.status == "undecided") == undecided, factor
        assert rec.contested == ((c1.id,) if undecided else ()), rec.contested
        if undecided:
            assert undecided_reason(rec) == f"{k0} lies near skills taught as other tasks: {c1.id}"
            with pytest.raises(UnknownSkillError, match="taught as other tasks, lie about as near"):
                lib.predict_robot(q)
    items[r1] = ComponentModel(c1.id, c1.created, replace(c1.cluster, mean=mean - mean + c1.cluster.mean),
                               c1.subclusters)
    lib._components = Components.of(items, h)
    off = SkillLibrary.from_state(replace(lib.state(), config=replace(lib.config, other_task_reach=0.0)))
    z1 = z0 + u * np.sqrt(1.5 * limit * inflate)
    mean = c1.cluster.mean.copy()
    mean[:h] = metric.chol @ z1
    items[r1] = ComponentModel(c1.id, c1.created, replace(c1.cluster, mean=mean), c1.subclusters)
    off._components = Components.of(items, h)
    assert off.recognize(q, observed_fraction=1.0).status == "skill"


def test_the_reach_holds_only_once_the_scale_is_more_data_than_prior():
    """The same geometry (skill 1's component at 1.5 merge limits of skill 0's under the metric of the time) on the
    learned scale contests the answer; on a scale still more prior than data (pooled dof below prior_strength: a
    library of tasks seen once, where every pair lies near) it does not."""
    from drake_skills.library.algorithm import ComponentModel, Components
    from drake_skills.library.novelty import chi2_ppf

    base = _library(("a", "b", "c"))
    q = synthetic_demo(0, np.random.default_rng(50)).human
    k0 = base.recognize(q, observed_fraction=1.0).component
    for dof, contested in ((base._scale.dof, True), (base.config.prior_strength - 0.5, False)):
        lib = SkillLibrary.from_state(base.state())
        lib._scale = replace(base._scale, dof=dof)
        items = list(lib._components.items)
        r0 = lib._components.index(k0)
        r1 = next(i for i in range(len(items)) if main_task(items[i].cluster.tasks) == "b")
        h = lib.n_human
        metric = lib._metric()
        inflate = 1.0 / items[r0].support + 1.0 / items[r1].support
        z1 = metric.whiten(items[r0].cluster.mean[:h]) + np.eye(h)[0] * np.sqrt(
            1.5 * chi2_ppf(lib.config.merge_quantile, h) * inflate)
        mean = items[r1].cluster.mean.copy()
        mean[:h] = metric.chol @ z1
        c1 = items[r1]
        items[r1] = ComponentModel(c1.id, c1.created, replace(c1.cluster, mean=mean), c1.subclusters)
        lib._components = Components.of(items, h)
        assert lib._contested(r0) == ((c1.id,) if contested else ()), dof


def _placed(base, factor, *, config=None, dof=None, keep=None, best_tasks=None):
    """A copy of ``base`` (three skills named a, b, c) with skill b's component at ``factor`` merge limits (two-sample
    distance) of skill a's; ``config``/``dof`` replace the library's; ``keep``: only these rows of (a, b); ``best_tasks``
    replaces a's task weights. Returns (library, row of a, id of b)."""
    from drake_skills.library.algorithm import ComponentModel, Components
    from drake_skills.library.novelty import chi2_ppf

    lib = SkillLibrary.from_state(replace(base.state(), config=config or base.config))
    if dof is not None:
        lib._scale = replace(base._scale, dof=dof)
    items = list(lib._components.items)
    r0 = next(i for i in range(len(items)) if main_task(items[i].cluster.tasks) == "a")
    r1 = next(i for i in range(len(items)) if main_task(items[i].cluster.tasks) == "b")
    h = lib.n_human
    metric = lib._metric()
    inflate = 1.0 / items[r0].support + 1.0 / items[r1].support
    z1 = metric.whiten(items[r0].cluster.mean[:h]) + np.eye(h)[0] * np.sqrt(
        factor * chi2_ppf(lib.config.merge_quantile, h) * inflate)
    c1 = items[r1]
    mean = c1.cluster.mean.copy()
    mean[:h] = metric.chol @ z1
    items[r1] = ComponentModel(c1.id, c1.created, replace(c1.cluster, mean=mean), c1.subclusters)
    if best_tasks is not None:
        c0 = items[r0]
        items[r0] = ComponentModel(c0.id, c0.created, replace(c0.cluster, tasks=best_tasks), c0.subclusters)
    if keep:
        items = [items[r0], items[r1]]
        r0 = 0
    lib._components = Components.of(items, h)
    return lib, r0, c1.id


def test_the_reach_is_a_multiple_of_the_merge_limit_below_one_too():
    """other_task_reach 0.5: a skill taught as another task at 0.4 merge limits contests the answer, at 0.6 it does not."""
    base = _library(("a", "b", "c"))
    cfg = replace(base.config, other_task_reach=0.5)
    for factor, contested in ((0.4, True), (0.6, False)):
        lib, r0, k1 = _placed(base, factor, config=cfg)
        assert lib._contested(r0) == ((k1,) if contested else ()), factor


def test_the_reach_holds_in_a_library_of_two_skills():
    base = _library(("a", "b", "c"))
    lib, r0, k1 = _placed(base, 1.5, keep=True)
    assert len(lib._components) == 2
    assert lib._contested(r0) == (k1,)


def test_the_reach_holds_from_the_pooled_dof_equal_to_the_prior_strength():
    base = _library(("a", "b", "c"))
    assert base._scale.dof > base.config.prior_strength
    lib, r0, k1 = _placed(base, 1.5, dof=float(base.config.prior_strength))
    assert lib._contested(r0) == (k1,)


def test_a_skill_taught_without_a_name_is_never_contested_by_named_neighbours():
    """No name on the best skill: nothing says its neighbours answer differently (nor that it is mixed)."""
    base = _library(("a", "b", "c"))
    lib, r0, _ = _placed(base, 1.5, best_tasks=())
    assert lib._contested(r0) == ()


def test_the_mixed_share_is_relative_to_the_weight_whatever_its_total():
    assert mixed_share((("a", 0.3), ("b", 0.2))) == pytest.approx(0.4)      # a total below one (fractional responsibilities)
    assert mixed_share((("a", 3.0), ("b", 1.0))) == pytest.approx(0.25)
    assert mixed_share((("a", 0.0), ("b", 0.0))) == 0.0


def test_a_skill_taught_under_two_names_is_not_acted_on_under_the_loglik_test_too():
    """The mixed share holds whatever the novelty test; the reach (in merge limits of the chi-square rule) does not
    apply to a log-likelihood library."""
    lib = _library((_taught_as_two, "b", "c"), novelty_test="loglik", **COUNTED)
    q = synthetic_demo(0, np.random.default_rng(50)).human
    assert len(lib._components) == 3
    rec = lib.recognize(q, observed_fraction=1.0)
    assert rec.status == "undecided" and len(rec.contested) == 1 and rec.component is None
    assert mixed_share(lib._model(rec.contested[0]).cluster.tasks) >= 0.2
    r = _library((_taught_as_two, "b", "c"), novelty_test="loglik", mixed_task_share=1.0, **COUNTED).recognize(
        q, observed_fraction=1.0)
    assert r.status == "skill" and r.component == rec.contested[0]          # the rule off: answered
    base = _library(("a", "b", "c"), novelty_test="loglik")
    lib, r0, _ = _placed(base, 0.5)
    assert lib._contested(r0) == ()                                         # no reach under loglik


def test_a_whole_motion_beyond_the_reach_of_the_neighbours_limit_is_not_held_by_it():
    """The default reach (2). Skill a's component placed at d^2 25 from a motion, skill b's 1.99 merge limits from a's
    (two-sample), so the means contest. With b where the motion lies 1.5 times b's novelty limit from it (beyond the
    limit, within the reach) the answer stays undecided; with b on the far side, beyond twice the limit, it is answered
    (the contest released). A beginning keeps the contest (a beginning's candidates may be pruned)."""
    from drake_skills.library.algorithm import ComponentModel, Components
    from drake_skills.library.novelty import chi2_ppf
    from drake_skills.promp.basis import ridge_weights

    base = _library(("a", "b", "c"))
    cfg = base.config
    assert cfg.other_task_reach == 2.0
    q = synthetic_demo(0, np.random.default_rng(50)).human
    lib, r0, k1 = _placed(base, 1.99)
    h = lib.n_human
    metric = lib._metric()
    items = list(lib._components.items)
    r1 = lib._components.index(k1)
    c0, c1 = items[r0], items[r1]
    y = lib._normalized(q).resample(lib.config.n_samples)
    zq = metric.whiten(ridge_weights(y, lib.config.basis_human, lib.config.ridge))
    e, w = np.eye(h)[0], np.eye(h)[1]
    r = np.sqrt(25.0 * (1.0 + 1.0 / c0.support))
    z0 = zq + r * e                                                     # the motion at d^2 25 from a's component
    t = np.sqrt(1.99 * chi2_ppf(cfg.merge_quantile, h) * (1.0 / c0.support + 1.0 / c1.support))
    limit = chi2_ppf(cfg.novelty_quantile, h)
    cb = 1.0 + 1.0 / c1.support
    # |q - b|^2 = r^2 + t^2 + 2 r t cos(theta) for b = a + t (cos(theta) e + sin(theta) w): 1.5 limits of b's
    cos = (1.5 * limit * cb - r * r - t * t) / (2.0 * r * t)
    assert -1.0 < cos < 1.0
    within = cos * e + np.sqrt(1.0 - cos * cos) * w

    def moved(c, z):
        mean = c.cluster.mean.copy()
        mean[:h] = metric.chol @ z
        return ComponentModel(c.id, c.created, replace(c.cluster, mean=mean), c.subclusters)

    items[r0] = moved(c0, z0)
    for where, held in ((within, True), (e, False)):                   # within the reach; away from the motion
        items[r1] = moved(c1, z0 + t * where)
        lib._components = Components.of(items, h)     # a new version: the memos start again
        assert lib._contested(r0) == (k1,)             # the means lie within the reach either way
        rec = lib.recognize(q, observed_fraction=1.0)
        d2_b = float(rec.mahalanobis_sq[r1])
        assert rec.mahalanobis_sq[r0] == pytest.approx(25.0, rel=1e-9)
        if held:    # past b's own limit (a test of the limit alone would release it), within twice it
            assert d2_b == pytest.approx(1.5 * limit, rel=1e-9)
        else:
            assert d2_b > 2.0 * limit, (d2_b, limit)
        assert rec.best == c0.id and rec.posterior[r0] >= 1.0 - cfg.decision_risk, rec.posterior
        assert rec.contested == ((k1,) if held else ()), (held, rec.contested)
        assert rec.status == ("undecided" if held else "skill") and rec.component == (None if held else c0.id)
    # the same distances judged as a beginning's (``shares`` given): the contest is kept
    as_begin = lib._decide(rec.log_likelihoods, rec.mahalanobis_sq, rec.dof, np.full(len(items), 0.5),
                           shares=np.full(len(items), 0.5))
    assert as_begin.contested == (k1,) and as_begin.status == "undecided"


def test_an_answer_that_is_not_a_skill_names_no_contest():
    """Only a motion one skill explains is judged by the names: an unknown or plainly undecided one has an empty
    tuple (not None) in ``contested``, and its reason says nothing of task names."""
    lib = _library(("a", "b", "c"))
    far = synthetic_demo(0, np.random.default_rng(50)).human * 3.0 + 5.0     # no skill explains it
    rec = lib.recognize(far, workspace=WORKSPACE, observed_fraction=1.0)
    assert rec.status == "unknown" and rec.contested == () and isinstance(rec.contested, tuple)
    assert undecided_reason(rec) == ""
