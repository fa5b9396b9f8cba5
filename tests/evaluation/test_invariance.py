"""Invariance (issue 11 goals): the same real interactions in other units, rates, speeds and noise.

The default library learns the 32 training interactions of buetepage_hr.npz (hand columns) in
3 random orders, once as recorded and once transformed, and recognizes the 9 test
interactions (observed_fraction=1). A *decision* is the status and the task label of the
recognized component. Tolerances, per order:

* millimetres with the matching workspace: identical (the same updates after every
  demonstration, the same components and decisions, d^2 within 1e-9 relative);
* resampled from 150 Hz to 30 Hz (every 5th sample; the file's rate is not stated, 150 Hz is
  assumed here so that the rates are the issue's) and played 2x slower (interpolated at the
  same rate, twice the samples): identical decisions and the same component count (measured
  over 5 orders since the task names are used in learning, 2026-12-06: 4 components each time;
  before, the count was within 1);
* 2 mm of extra tracker noise (about where ``adapt_to_noise`` starts to act, 0.3 tolerances
  here), 5 noise draws: identical decisions (one exception below) and the same component count
  (measured over 10 draws x 5 orders on 2026-12-06: 4 components in all 50; before the task names
  were used the count moved by -3 to +3). With the walk's vertices at single noisy samples (``average_holds=False``) the
  rest at the end of each interaction added path, and the decisions changed in every draw: the
  far rocket test interaction (d^2 ~150 against a threshold of 47) was recognized. Since
  ``skip_false_starts`` that rocket (037, a false start before it) is read from its restart and
  recognized; with noise it may be unknown in the first order (never another skill).
* 10 mm of camera-like noise: no wrong answer with the default ``adapt_to_noise``, and at
  least one without it (the test names the measured counts).
"""
import numpy as np
import pytest

from drake_skills.data.demonstration import Demonstration
from drake_skills.data.interaction import load_interactions
from drake_skills.data.workspace import Workspace
from drake_skills.evaluation.interaction import workspace_of
from drake_skills.evaluation.labeled import LabeledLibrary
from drake_skills.library.config import LibraryConfig
from shared_data import require

ORDERS = (0, 1, 2)


@pytest.fixture(scope="module")
def interactions():
    return load_interactions(require(), rate_hz=150.0)


@pytest.fixture(scope="module")
def baseline(interactions):
    """The recorded interactions learned in each order: (order, result of _learn)."""
    train, test = interactions.train, interactions.test
    ws = workspace_of(train)
    orders = [np.random.default_rng(o).permutation(len(train)) for o in ORDERS]
    return [(order, _learn(train, test, ws, order)) for order in orders]


def _learn(train, test, ws, order, **config):
    lab = LabeledLibrary(LibraryConfig(workspace=ws, **config))
    events = []
    for j in order:
        u = lab.teach(train[j])
        events.append((u.recognized is None, len(u.merged), len(u.deleted), len(u.split)))
    recs = [lab.library.recognize(d.human, observed_fraction=1.0) for d in test]
    decisions = [(r.status, lab.label_of(r.component)) for r in recs]
    d2 = np.array([r.mahalanobis_sq.min() for r in recs])
    return lab.library.n_components, events, decisions, d2


def _like(d, t, human, robot):
    return Demonstration(t=t, human=human, robot=robot, task=d.task, name=d.name)


def _millimetres(d):
    return _like(d, d.t, 1000.0 * d.human, d.robot)


def _every_fifth(d):
    return _like(d, d.t[::5], d.human[::5], d.robot[::5])


def _half_speed(d):
    t = np.arange(2 * d.n_samples - 1) * (d.t[1] - d.t[0])

    def interp(y):
        return np.stack([np.interp(t, 2 * d.t, y[:, k]) for k in range(y.shape[1])], axis=1)

    return _like(d, t, interp(d.human), interp(d.robot))


def _runs(interactions, baseline, transform, ws, **config):
    train = [transform(d) for d in interactions.train]
    test = [transform(d) for d in interactions.test]
    ws = ws or workspace_of(interactions.train)
    return [(base, _learn(train, test, ws, order, **config)) for order, base in baseline]


def test_millimetres_with_the_matching_workspace_change_nothing(interactions, baseline):
    ws = workspace_of(interactions.train)
    for (K, ev, dec, d2), (K2, ev2, dec2, d22) in _runs(interactions, baseline, _millimetres,
                                                         Workspace(1000.0 * ws.lower, 1000.0 * ws.upper)):
        assert (K2, ev2, dec2) == (K, ev, dec)
        np.testing.assert_allclose(d22, d2, rtol=1e-9)


@pytest.mark.parametrize("transform", [_every_fifth, _half_speed], ids=["150Hz_to_30Hz", "2x_slower"])
def test_sampling_rate_and_speed_keep_the_decisions(interactions, baseline, transform):
    for (K, ev, dec, d2), (K2, ev2, dec2, d22) in _runs(interactions, baseline, transform, None):
        assert dec2 == dec
        assert K2 == K, (K, K2)


@pytest.mark.parametrize("seed", [2, 3, 4, 5, 6])
def test_tracker_noise_of_2mm_keeps_every_decision_and_the_components(interactions, baseline, seed):
    """Five noise draws x the 3 orders: every decision the same and the same component count (measured over
    draws 2-11 x 5 orders: 4 components in all 50; before the task names were used in learning the count moved
    by -3 to +3). With the walk's vertices at the samples (``average_holds=False``) the decisions change in every
    draw (the rocket 037 recognized).

    One exception since ``skip_false_starts`` (2026-12-06): the rocket 037, read from its restart after a false
    start, lies near the novelty threshold, so with noise it may be unknown: never another skill (measured:
    unknown in every order of draws 2 and 8 of 2-11, recognized in the others)."""
    rng = np.random.default_rng(seed)

    def noisy(d):
        return _like(d, d.t, d.human + rng.normal(0.0, 0.002, d.human.shape), d.robot)

    names = [d.name for d in interactions.test]
    for (K, ev, dec, d2), (K2, ev2, dec2, d22) in _runs(interactions, baseline, noisy, None):
        for name, a, b in zip(names, dec, dec2):
            if ":037:" in name and b != a:
                assert a == ("skill", "rocket") and b == ("unknown", None), (a, b)
            else:
                assert b == a, (name, a, b)
        assert K2 == K, (K, K2)


def test_camera_noise_of_10mm_gives_no_wrong_answer_because_the_walk_adapts_to_it(interactions, baseline):
    """10 mm of white noise per axis on every interaction (a camera skeleton tracker; 2-2.5 times the
    arc-length tolerance on this workspace). The plain walk counts nearly every sample, its phase
    becomes time-like and the library answers wrong (measured: 4 of 9 wrong in 1 of the 3 orders,
    components 10, 8, 4); with ``adapt_to_noise`` (the default) none wrong in any order (before
    ``skip_false_starts`` 8 of 9 right in each, the rocket 037 unknown as without noise) and at most 10 components (measured
    5, 8, 9; 5, 6, 6 with ``average_holds`` off). The noise is drawn once, so both walks see the
    same samples."""
    rng = np.random.default_rng(7)
    noise = {d.name: rng.normal(0.0, 0.010, d.human.shape) for d in interactions.train + interactions.test}

    def noisy(d):
        return _like(d, d.t, d.human + noise[d.name], d.robot)

    tasks = [d.task for d in interactions.test]
    wrong = {}
    for adapt in (True, False):
        # the task names off (mixed_task_share 1, keep_tasks_apart off, same_task_reach 1): the plain walk's wrong
        # answers come from components it merges across tasks, which the defaults keep apart or answer "undecided"
        # (0 wrong either way, measured): this test is about the walk
        runs = _runs(interactions, baseline, noisy, None, adapt_to_noise=adapt, mixed_task_share=1.0,
                     keep_tasks_apart=False, same_task_reach=1.0)
        wrong[adapt] = [sum(st == "skill" and lab != task for (st, lab), task in zip(dec, tasks))
                        for _, (K, ev, dec, d2) in runs]
        if adapt:
            assert max(K for _, (K, ev, dec, d2) in runs) <= 10
    assert wrong[True] == [0, 0, 0]
    assert sum(wrong[False]) >= 1, wrong
