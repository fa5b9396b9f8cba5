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
