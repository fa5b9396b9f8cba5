"""A tracker that misbehaves (issue 16): each fault is screened by the stated rule, and the robot stays safe.

Per fault, the feed (drake_skills.systems.wrist_faults) and the screen
(drake_skills.systems.normalizer.screen_sample) are checked as pure functions; then
one closed-loop trial with every fault at once and one with the wrist lost check
that the robot command stays finite, within the joint position and velocity limits,
and that a lost wrist makes the robot hold.
"""
import numpy as np
import pytest

from drake_skills import SkillLibrary
from drake_skills.scenario.salad import generate_subject
from drake_skills.sim.config import SimConfig
from drake_skills.sim.demo import CollaborationSim
from drake_skills.sim.models import IIWA7_JOINT_LIMITS, IIWA7_VELOCITY_LIMITS
from drake_skills.systems.decision_rule import DecisionRule
from drake_skills.systems.gating import GatingDecision, gating_step
from drake_skills.systems.normalizer import SampleRule, screen_sample
from drake_skills.systems.wrist_faults import TrackerFaults, tracker_feed
from drake_skills.systems.wrist_source import WristTrial

RULE = SampleRule()


def _trial():
    t = np.linspace(0.0, 2.0, 201)
    return WristTrial(t, np.column_stack([0.3 * t, 0.1 * np.sin(t), np.zeros_like(t)]), 1.0)


def _screen(feed):
    """Run the screen over a feed at the normalizer's 64 Hz: the verdict of every tick."""
    good, good_t, seen = None, 0.0, None
    out = []
    for t in np.arange(feed.times[0], feed.times[-1], 1 / 64):
        p, stamp = feed.at(t)
        v = screen_sample(p, stamp, good, good_t, seen, RULE)
        seen = stamp if np.isfinite(stamp) else seen
        if v == "":
            good, good_t = p, stamp
        out.append((t, v, feed.kinds[np.searchsorted(feed.times, t + 1e-12) - 1]))
    return out


@pytest.mark.parametrize("kind, faults", [
    ("nan", TrackerFaults(nan_rate=4.0)), ("outlier", TrackerFaults(outlier_rate=4.0)),
    ("stale", TrackerFaults(stale_rate=2.0)), ("dropout", TrackerFaults(dropout_rate=2.0))])
def test_each_fault_is_rejected_and_nothing_else_is(kind, faults):
    feed = tracker_feed(_trial(), faults, np.random.default_rng(3))
    assert (feed.kinds == kind).sum() >= 3  # the fault happens
    verdicts = _screen(feed)
    hit = [v for _, v, k in verdicts if k == kind]
    clean = [v for _, v, k in verdicts if k == ""]
    expect = {"nan": "nan", "outlier": "outlier", "stale": "stale", "dropout": "stale"}[kind]
    # a held sample counts once: the first tick of a stale run or dropout is new, the rest are rejected
    assert hit.count(expect) >= len(hit) - (feed.kinds == kind).sum() // 2 and expect in hit
    assert clean.count("") == len(clean)  # good samples are all accepted


def test_latency_delays_the_samples_and_rejects_none():
    feed = tracker_feed(_trial(), TrackerFaults(latency=0.1), np.random.default_rng(0))
    assert np.allclose(feed.times - feed.stamps, 0.1)
    assert all(v == "" for _, v, _ in _screen(feed))


def test_a_wrist_that_jumps_for_good_stays_rejected():
    good = np.zeros(3)
    assert screen_sample(np.array([0.05, 0, 0]), 0.1, good, 0.0, 0.0, RULE) == ""  # 0.5 m/s
    assert screen_sample(np.array([1.0, 0, 0]), 0.1, good, 0.0, 0.0, RULE) == "outlier"
    assert screen_sample(np.array([1.0, 0, 0]), 60.0, good, 0.0, 59.9, RULE) == "outlier"  # a minute later too


def test_the_gating_bridges_short_gaps_and_holds_after_the_lost_timeout():
    rule = DecisionRule(lost_timeout=0.5)
    s = GatingDecision()
    dt = 1 / 64
    for i in range(10):
        s = gating_step(s, i * dt, np.array([0.01 * i, 0, 0]), SkillLibrary(), rule)
    n = s.motion.n
    t = 10 * dt
    while t - 10 * dt <= 0.5:  # NaN for up to the timeout: bridged, nothing appended, still observing
        s = gating_step(s, t, np.full(3, np.nan), SkillLibrary(), rule)
        assert s.status != "lost" and s.motion.n == n
        t += dt
    s = gating_step(s, t, np.full(3, np.nan), SkillLibrary(), rule)
    assert s.status == "lost" and s.final and s.component is None and s.rejected > 0


#: Every fault at once, at rates well above the demo presets.
ALL_FAULTS = TrackerFaults(dropout_rate=1.0, stale_rate=1.0, nan_rate=3.0, outlier_rate=3.0, latency=0.05)


@pytest.fixture(scope="module")
def taught():
    """One Diagram, taught three tomato demonstrations, for both closed-loop trials (one build: ~1 s)."""
    subject = generate_subject(1, n_demos=4, seed=0)
    sim = CollaborationSim(SimConfig(faults=ALL_FAULTS), SkillLibrary(), subject.workspace())
    for demo in subject.by_task("tomato")[:3]:
        sim.teach(demo)
    return sim, subject.by_task("tomato")[3]


def _within_limits(log):
    lower, upper = IIWA7_JOINT_LIMITS
    assert np.isfinite(log.q_desired).all() and np.isfinite(log.qd_desired).all()
    assert (log.q_desired >= lower - 1e-9).all() and (log.q_desired <= upper + 1e-9).all()
    assert (np.abs(log.qd_desired) <= IIWA7_VELOCITY_LIMITS + 1e-6).all()


def test_with_every_fault_at_once_the_command_stays_finite_and_within_limits(taught):
    sim, demo = taught
    outcome, log = sim.run_trial(demo)
    _within_limits(log)
    assert outcome.status in {"skill", "unknown", "undecided", "lost"}


def test_a_lost_wrist_makes_the_robot_hold(taught, monkeypatch):
    """The marker is lost 0.1 s into the motion (before any commit) and never comes back: 'lost', the robot holds still."""
    import drake_skills.systems.wrist_faults as wf

    sim, demo = taught
    real = wf.tracker_feed

    def losing(trial, f, rng, margin):
        feed = real(trial, f, rng, margin=margin)
        pos = np.array(feed.positions)
        pos[feed.times >= trial.start_time + 0.1] = np.nan
        return type(feed)(feed.times, pos, feed.stamps, feed.kinds)

    monkeypatch.setattr(sim.config, "faults", TrackerFaults(latency=1e-9))  # "any" fault: the feed path is taken
    monkeypatch.setattr(wf, "tracker_feed", losing)
    outcome, log = sim.run_trial(demo)
    assert outcome.status == "lost" and outcome.component is None and not outcome.executed
    _within_limits(log)
    moved = np.abs(log.q_desired - log.q_desired[0]).max()
    assert moved < 1e-6, moved  # lost before any commit: the robot never left its hold pose


def test_a_wrist_lost_after_the_commit_stops_the_robot(taught, monkeypatch):
    """The marker is lost 0.2 s after the robot committed: 'lost', nothing executed, the command slows to rest."""
    import drake_skills.systems.wrist_faults as wf
    from drake_skills.systems.decision_rule import DecisionRule

    sim, demo = taught
    monkeypatch.setattr(sim.config, "faults", TrackerFaults(latency=1e-9))
    clean, _ = sim.run_trial(demo)
    assert np.isfinite(clean.plan_start) and clean.commits, "the perfect-tracker trial commits while moving"
    real = wf.tracker_feed
    lost_at = clean.plan_start - clean.start_time + 0.2  # s after the trial start

    def losing(trial, f, rng, margin):
        feed = real(trial, f, rng, margin=margin)
        pos = np.array(feed.positions)
        pos[feed.times >= trial.start_time + lost_at] = np.nan
        return type(feed)(feed.times, pos, feed.stamps, feed.kinds)

    monkeypatch.setattr(wf, "tracker_feed", losing)
    outcome, log = sim.run_trial(demo)
    assert outcome.status == "lost" and outcome.component is None and not outcome.executed
    _within_limits(log)
    t = log.times - outcome.start_time
    # once lost (lost_timeout after the marker), the command decelerates smoothly to rest and
    # never speeds up again (measured: 1.36 -> 0.015 rad/s over the 0.5 s the trial has left)
    # (from when the loss has passed the gating, the conditioner and the trajectory source, one update
    # of 1/64 s each: until then the plan runs on, and a plan starting from rest is still speeding up)
    from drake_skills.systems.conditioner import CONDITIONER_PERIOD
    from drake_skills.systems.gating import GATING_PERIOD
    from drake_skills.systems.trajectory_source import SOURCE_PERIOD
    seen = lost_at + DecisionRule().lost_timeout + GATING_PERIOD + CONDITIONER_PERIOD + SOURCE_PERIOD
    speed = np.abs(log.qd_desired[t >= seen]).max(axis=1)
    assert speed.size >= 5
    assert np.all(np.diff(speed) <= 1e-9), speed
    assert speed[-1] < 0.05, speed[-1]  # rad/s


def test_over_lcm_the_station_s_faulty_tracker_leaves_the_commands_within_limits_and_the_decision_as_without(
        taught):
    """The LCM station publishes the same faulty feed (memq://): every command on the bus is finite, within the
    joint limits, and between two commands (5 ms) within the speed limits; the decision is the perfect tracker's
    or 'lost' with the robot holding."""
    from drake import lcmt_iiwa_command

    from drake_skills.sim.lcm_demo import LcmCollaborationSim

    direct, demo = taught
    sim = LcmCollaborationSim(SimConfig(), direct.library, direct.workspace)
    assert sim.parts.lcm.get_lcm_url() == "memq://"
    perfect, _ = sim.run_trial(demo)
    commands, wrists = [], []
    sim.parts.lcm.Subscribe(sim.config.lcm.command_channel, lambda data: commands.append(
        (lambda m: (m.utime, m.joint_position))(lcmt_iiwa_command.decode(data))))
    from drake import lcmt_drake_signal

    sim.parts.lcm.Subscribe(sim.config.lcm.wrist_channel,
                            lambda data: wrists.append(lcmt_drake_signal.decode(data).val))
    sim.config.faults = ALL_FAULTS
    outcome, log = sim.run_trial(demo)
    assert np.isnan(np.array(wrists)).any(axis=1).sum() >= 3  # the station sent the tracker's NaN
    _within_limits(log)
    q = np.array([c[1] for c in commands])
    lower, upper = IIWA7_JOINT_LIMITS
    assert len(q) > 100 and np.isfinite(q).all() and (q >= lower).all() and (q <= upper).all()
    dt = np.diff([c[0] for c in commands]) * 1e-6
    period = sim.config.lcm.command_period
    steady = np.isclose(dt, period, atol=1e-6)
    assert (np.abs(np.diff(q, axis=0))[steady] / period <= IIWA7_VELOCITY_LIMITS + 1e-9).all()
    if outcome.status == "lost":
        assert not outcome.executed
    else:
        assert (outcome.status, outcome.component) == (perfect.status, perfect.component), (outcome, perfect)


@pytest.mark.parametrize("ticks", [2, 6])
def test_a_glitch_on_the_first_frames_of_a_trial_changes_nothing(taught, monkeypatch, ticks):
    """The first 2 or 6 tracker ticks (128 Hz: 1-3 of the normalizer's) are 1 m off (beyond max_jump): the trial
    ends as with a clean feed (TrackerFaults.start_glitch_ticks, `demo --faults start`).

    Before the start was confirmed (``normalizer.start_chain``), the glitch became the trial's start and the
    speed bound's reference: every real sample was an "outlier" and the trial ended "lost".
    """
    sim, demo = taught
    monkeypatch.setattr(sim.config, "faults", TrackerFaults(latency=1e-9))
    clean, _ = sim.run_trial(demo)
    monkeypatch.setattr(sim.config, "faults", TrackerFaults(start_glitch_ticks=ticks))
    outcome, log = sim.run_trial(demo)
    _within_limits(log)
    assert clean.status == "skill" and outcome.status == clean.status and outcome.component == clean.component
    assert outcome.executed == clean.executed


def test_a_glitch_that_holds_for_four_ticks_of_the_normalizer_is_the_documented_limit(taught, monkeypatch):
    """10 tracker ticks (5 of the normalizer's, 78 ms) at the same wrong place confirm as the start: the real
    wrist is then rejected and the trial ends "lost", the robot holding (normalizer docstring, README)."""
    sim, demo = taught
    monkeypatch.setattr(sim.config, "faults", TrackerFaults(start_glitch_ticks=10))
    outcome, log = sim.run_trial(demo)
    _within_limits(log)
    assert outcome.status == "lost" and outcome.component is None and not outcome.executed


def test_the_start_glitch_fault_displaces_the_first_ticks_of_a_feed_in_one_direction():
    feed = tracker_feed(_trial(), TrackerFaults(start_glitch_ticks=3), np.random.default_rng(0))
    clean = tracker_feed(_trial(), TrackerFaults(), np.random.default_rng(0))
    assert list(feed.kinds[:4]) == ["start"] * 3 + [""]
    d = feed.positions[:3] - clean.positions[:3]
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)  # outlier_distance, 1 m
    np.testing.assert_allclose(d, np.repeat(d[:1], 3, axis=0), atol=1e-12)   # one direction
    np.testing.assert_array_equal(feed.positions[3:], clean.positions[3:])


def test_the_start_fault_has_a_preset_and_its_setting_is_checked():
    from drake_skills.systems.wrist_faults import faults_from_spec

    assert faults_from_spec("start").start_glitch_ticks == 3 and faults_from_spec("start").any
    assert faults_from_spec("all").start_glitch_ticks == 3
    for bad in (-1, 1.5, True):
        with pytest.raises(ValueError, match="start_glitch_ticks must be an integer >= 0"):
            TrackerFaults(start_glitch_ticks=bad)
