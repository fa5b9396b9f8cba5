"""A motion that no skill explains is read again from where it last set off (LibraryConfig.skip_false_starts)."""
import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.library.views import UnknownSkillError
from synthetic import WORKSPACE, synthetic_demo

TASKS = (0, 1, 2)


def _library(skip=True, false_starts=False, seed=0):
    rng = np.random.default_rng(seed)
    lib = SkillLibrary(LibraryConfig(workspace=WORKSPACE, skip_false_starts=skip))
    order = [t for _ in range(6) for t in TASKS]
    for i in rng.permutation(len(order)):
        d = synthetic_demo(order[i], rng)
        lib.partial_fit(_with_false_start(d) if false_starts else d)
    return lib


def _with_false_start(demo, toward=(1.0, -4.0, 2.0), n=30):
    """``demo`` with a false start before it: out 4.6 normalized units toward ``toward`` and back to the start."""
    z = np.sin(np.linspace(0.0, np.pi, n))[:, None]
    fs = demo.human[0] + z * np.asarray(toward, float)
    human = np.vstack([fs, demo.human[1:]])
    dt = demo.t[1] - demo.t[0]
    robot = None if demo.robot is None else np.vstack([np.repeat(demo.robot[:1], n, axis=0), demo.robot[1:]])
    return type(demo)(t=dt * np.arange(len(human)), human=human, robot=robot, task=demo.task, name="fs")


@pytest.fixture(scope="module")
def lib():
    return _library()


@pytest.fixture(scope="module")
def queries():
    rng = np.random.default_rng(7)
    return [synthetic_demo(t, rng) for t in TASKS]


@pytest.mark.parametrize("fraction", [1.0, None])
def test_a_motion_after_a_false_start_is_read_from_where_it_set_off_again(lib, queries, fraction):
    """Whole (fraction 1) and with the phase estimated: the answer of the motion alone, read from sample 29 (the
    false start's last sample, back at the start: the first 30 samples are the false start)."""
    for q in queries:
        clean = lib.recognize(q.human, observed_fraction=fraction)
        rec = lib.recognize(_with_false_start(q).human, observed_fraction=fraction)
        assert clean.status == "skill" and clean.restart is None
        assert rec.status == "skill" and rec.component == clean.component
        assert rec.restart == 29


def test_without_skip_false_starts_the_same_motion_is_unknown(queries):
    off = _library(skip=False)
    for q in queries:
        assert off.recognize(q.human, observed_fraction=1.0).status == "skill"
        rec = off.recognize(_with_false_start(q).human, observed_fraction=1.0)
        assert rec.status == "unknown" and rec.restart is None


def test_answers_of_motions_read_whole_do_not_change(lib, queries):
    """Clean motions: the same answer, statistics and no restart, with the setting on or off."""
    off = _library(skip=False)
    for q in queries:
        for f in (1.0, None, 0.5):
            a, b = lib.recognize(q.human, observed_fraction=f), off.recognize(q.human, observed_fraction=f)
            assert (a.status, a.component, a.restart) == (b.status, b.component, None)
            np.testing.assert_array_equal(a.mahalanobis_sq, b.mahalanobis_sq)


def test_a_library_taught_false_starts_answers_them_whole(queries):
    """Only an unknown motion is read again: where the false start is part of the skill, the whole answers."""
    taught = _library(false_starts=True)
    for q in queries:
        rec = taught.recognize(_with_false_start(q).human, observed_fraction=1.0)
        assert rec.status == "skill" and rec.restart is None


def test_an_unknown_motion_stays_unknown_when_its_last_start_is_unknown_too(lib):
    rng = np.random.default_rng(3)
    untaught = synthetic_demo(3, rng)
    for f in (1.0, None):
        assert lib.recognize(untaught.human, observed_fraction=f).status == "unknown"
        rec = lib.recognize(_with_false_start(untaught).human, observed_fraction=f)
        assert rec.status == "unknown" and rec.restart is None
    with pytest.raises(UnknownSkillError):
        lib.predict_robot(_with_false_start(untaught).human)


def test_a_given_fraction_below_one_reads_the_motion_as_given(lib, queries):
    """The caller's fraction is of the motion as given: no reading from a restart."""
    rec = lib.recognize(_with_false_start(queries[0]).human, observed_fraction=0.9)
    assert rec.restart is None


@pytest.mark.parametrize("fraction", [1.0, None])
def test_the_robot_answer_is_conditioned_on_the_motion_from_its_restart(lib, queries, fraction):
    """predict_robot on the false-started motion = predict_robot on the samples from its restart (1e-9), with the
    component recognized or given with ``restart``; the phase likewise."""
    q = queries[1]
    fs = _with_false_start(q).human
    i = lib.recognize(fs, observed_fraction=fraction).restart
    mean, cov = lib.predict_robot(fs, fraction)
    ref_mean, ref_cov = lib.predict_robot(fs[i:], fraction)
    np.testing.assert_allclose(mean, ref_mean, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(cov, ref_cov, rtol=1e-9, atol=1e-12)
    k = lib.recognize(fs[i:], observed_fraction=fraction).component
    given, _ = lib.predict_robot(fs, fraction, component=k, restart=i)
    np.testing.assert_allclose(given, ref_mean, rtol=1e-9, atol=1e-12)
    assert lib.estimate_phase(fs, k, restart=i) == pytest.approx(lib.estimate_phase(fs[i:], k), abs=1e-12)
    # restart 0: the whole motion, as given (here: with the false start)
    whole, _ = lib.predict_robot(fs, fraction, component=k, restart=0)
    assert np.abs(whole - ref_mean).max() > 1e-6


def test_a_restart_outside_the_motion_is_refused_naming_it(lib, queries):
    fs = _with_false_start(queries[0]).human
    for bad in (-1, len(fs) - 1, 2.5, "3", True):
        with pytest.raises(ValueError, match=rf"restart must be an integer in 0..{len(fs) - 2}, got"):
            lib.predict_robot(fs, 1.0, component=lib.components[0].id, restart=bad)
        with pytest.raises(ValueError, match="restart must be an integer"):
            lib.estimate_phase(fs, lib.components[0].id, restart=bad)


def _returning_near(demo, miss=(0.3, -0.2, 0.1), n=30):
    """``demo`` after a false start that comes back ``miss`` away from the start (not exactly to it), the motion
    itself moved there; the motion begins at sample ``n - 1``."""
    z = np.sin(np.linspace(0.0, np.pi, n))[:, None]
    back = np.linspace(0.0, 1.0, n)[:, None] * np.asarray(miss, float)
    fs = demo.human[0] + z * np.array([1.0, -4.0, 2.0]) + back
    human = np.vstack([fs, demo.human[1:] + np.asarray(miss, float)])
    return type(demo)(t=(demo.t[1] - demo.t[0]) * np.arange(len(human)), human=human, task=demo.task, name="near")


def _assert_skips_only_near_the_start(h, restart, begin=29):
    """The restart lies at or after where the false start came back (``begin``), and the samples of the motion it
    skips lie within RESTART_NEAR of the farthest distance from the start."""
    from drake_skills.promp.preprocessing import RESTART_NEAR

    d = np.linalg.norm(h - h[0], axis=1)
    assert begin <= restart and d[begin:restart + 1].max() <= RESTART_NEAR * d.max(), (restart, d[begin:restart + 1])


def test_a_false_start_that_comes_back_near_the_start_is_read_as_the_motion_from_there(lib, queries):
    """The reading from the restart is Eq. (14) on the samples from there: the same statistics (1e-9) as the
    motion given from that sample on, whose start the library subtracts itself. The restart is the vertex nearest
    the start between the two excursions: where the person came back (sample 29), or a little into the motion
    when it passes nearer to the start than that: what is skipped of the motion stays near the start."""
    for q in queries:
        h = _returning_near(q).human
        rec = lib.recognize(h, observed_fraction=1.0)
        _assert_skips_only_near_the_start(h, rec.restart)
        ref = lib.recognize(h[rec.restart:], observed_fraction=1.0)
        assert (rec.status, rec.component) == (ref.status, ref.component) == ("skill", lib.recognize(q.human).component)
        np.testing.assert_allclose(rec.mahalanobis_sq, ref.mahalanobis_sq, rtol=1e-9)


def test_without_subtracting_the_start_the_reading_from_a_restart_begins_where_the_motion_began():
    """``subtract_start=False``: the samples from the restart are moved back to the motion's first sample."""
    rng = np.random.default_rng(0)
    lib = SkillLibrary(LibraryConfig(workspace=WORKSPACE, subtract_start=False))
    for i in rng.permutation(18):
        lib.partial_fit(synthetic_demo(int(i) % 3, rng))
    h = _returning_near(synthetic_demo(1, np.random.default_rng(7))).human
    rec = lib.recognize(h, observed_fraction=1.0)
    assert rec.status == "skill"
    i = rec.restart
    _assert_skips_only_near_the_start(h, i)
    moved = h[i:] - h[i] + h[0]
    np.testing.assert_allclose(rec.mahalanobis_sq, lib.recognize(moved, observed_fraction=1.0).mahalanobis_sq,
                               rtol=1e-9)


def test_restart_zero_reads_the_whole_motion_even_without_a_component(lib, queries):
    """``restart=0`` is the caller's choice: the whole motion, false start included, which no skill explains."""
    fs = _with_false_start(queries[0]).human
    lib.predict_robot(fs)   # read from its restart: a skill
    with pytest.raises(UnknownSkillError):
        lib.predict_robot(fs, restart=0)
    with pytest.raises(UnknownSkillError):
        lib.predict_robot(fs, 1.0, restart=0)


def test_an_undecided_answer_is_never_read_again(lib, queries):
    """Only "unknown" is read again: the same motion given as undecided (or as a skill) comes back as it was."""
    from dataclasses import replace

    h = _with_false_start(queries[0]).human
    path = lib._normalized(h)
    unknown = lib._recognize_whole(path)
    assert unknown.status == "unknown" and lib._read_again(unknown, path, lib._recognize_whole)[0].restart == 29
    for status in ("undecided", "skill"):
        rec = replace(unknown, status=status)
        assert lib._read_again(rec, path, lib._recognize_whole)[0] is rec


def test_learning_is_the_same_with_the_setting_on_or_off():
    """Demonstrations with false starts are learned as given: the same components, means and ids either way."""
    on, off = _library(skip=True, false_starts=True), _library(skip=False, false_starts=True)
    assert [c.id for c in on.components] == [c.id for c in off.components]
    for a, b in zip(on.components, off.components):
        np.testing.assert_array_equal(a.mean, b.mean)
        assert a.support == b.support


def test_a_library_with_a_skill_that_sets_off_twice_reads_no_motion_again():
    """A beckon (out and back, then task 0's reach; its own robot answer) is a skill of its own: a larger beckon,
    unknown as a whole, must not be answered as task 0 from its tail. Without the beckon skill it is."""
    def beckon(rng, amp=1.0):
        d = _with_false_start(synthetic_demo(0, rng), toward=amp * np.array([1.0, -4.0, 2.0]))
        return type(d)(t=d.t, human=d.human, robot=d.robot + np.r_[0.0, 0, 0, 0, 0, 1.0, 0], task="beckon")

    rng = np.random.default_rng(0)
    lib = SkillLibrary(LibraryConfig(workspace=WORKSPACE))
    order = [t for _ in range(6) for t in (0, 1, 2, 3)]
    for i in rng.permutation(len(order)):
        lib.partial_fit(beckon(rng) if order[i] == 3 else synthetic_demo(order[i], rng))
    assert lib._sets_off_twice().sum() == 1
    big = beckon(np.random.default_rng(9), amp=2.0).human
    rec = lib.recognize(big, observed_fraction=1.0)
    assert rec.status == "unknown" and rec.restart is None
    plain = _library()
    assert not plain._sets_off_twice().any()
    assert plain.recognize(big, observed_fraction=1.0).restart == 29


def test_a_restart_whose_tail_does_not_move_answers_unknown_and_a_given_one_says_so(lib):
    """Out and back, then noise within the walk's tolerance: read whole it is unknown; its tail has no path, so
    the answer stays unknown (no StillMotionError). A given restart there is refused naming it."""
    first = np.sin(np.linspace(0, np.pi, 400))[:, None] * np.array([3.0, 4.0, 0.0])
    second = np.sin(np.linspace(0, np.pi, 60))[:, None] * np.array([-2.5, 3.0, 1.0])
    rest = np.full((20, 3), 0.0)
    h = np.vstack([first, second[1:], rest])
    assert lib.recognize(h, observed_fraction=1.0).status == "unknown"
    with pytest.raises(ValueError, match=r"restart 470: the motion from there on does not move"):
        lib.predict_robot(h, 1.0, component=lib.components[0].id, restart=470)


def test_whether_a_skill_sets_off_twice_is_kept_with_each_component_so_an_update_pays_for_what_it_changed(
        monkeypatch):
    import drake_skills.library.recognition as recognition

    lib = _library()
    calls = []
    real = recognition.restart_vertex
    monkeypatch.setattr(recognition, "restart_vertex", lambda *a, **k: calls.append(1) or real(*a, **k))
    assert lib._sets_off_twice().tolist() == [False] * lib.n_components and len(calls) == lib.n_components
    calls.clear()
    assert len(lib._sets_off_twice()) == lib.n_components and not calls          # the same version: cached
    update = lib.partial_fit(synthetic_demo(2, np.random.default_rng(11)))
    changed = len(set(update.created) | set(update.updated) | {a for a, _ in update.merged})
    lib._sets_off_twice()
    assert 1 <= len(calls) <= changed, (calls, update)


@pytest.mark.filterwarnings("ignore::drake_skills.library.views.UnitsWarning")  # small on purpose
def test_an_excursion_of_fewer_than_five_walk_tolerances_is_no_false_start():
    """A small motion (its farthest 1.3 normalized units): an out and back of 0.42 units (its walked vertices
    0.35-0.42) reaches a fifth of it, but not 5 tolerances (0.5): not a false start, so the motion stays unknown;
    0.8 units is one. (Without the tolerance floor the first is read again: checked.)"""
    rng = np.random.default_rng(0)
    # the three skills this small lie within each other's reach and merge: taught as several tasks, the merged
    # component would be undecided (mixed_task_share); this test is about the restart alone
    lib = SkillLibrary(LibraryConfig(workspace=WORKSPACE, mixed_task_share=1.0))

    def small(d):
        return type(d)(t=d.t, human=0.2 * d.human, robot=d.robot, task=d.task)

    for t in [0, 1, 2] * 6:
        lib.partial_fit(small(synthetic_demo(t, rng)))
    q = small(synthetic_demo(0, np.random.default_rng(7)))
    for size, read_again in ((0.42, False), (0.8, True)):
        h = _with_false_start(q, toward=size * np.array([0.0, 0.0, 1.0])).human
        rec = lib.recognize(h, observed_fraction=1.0)
        assert rec.status == ("skill" if read_again else "unknown") and (rec.restart is not None) == read_again, \
            (size, rec.status, rec.restart)
