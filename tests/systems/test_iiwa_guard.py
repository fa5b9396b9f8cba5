"""The command guard: latch, joint limits, speed limits, hold on a stale status, resume only near the hold."""
import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from drake_skills.sim.models import HOME_Q, IIWA7_JOINT_LIMITS, IIWA7_VELOCITY_LIMITS
from drake_skills.systems.iiwa_guard import GuardLimits, GuardState, IiwaCommandGuard, guard_step, status_received

LIMITS = GuardLimits(*IIWA7_JOINT_LIMITS, IIWA7_VELOCITY_LIMITS, period=0.005, stale_timeout=0.1)


def _run(q_desired_at, times, status_times=None, q_measured=None):
    """guard_step over ``times``; the status is new at every step unless ``status_times`` says otherwise.

    The robot follows the command exactly (a position-mode driver), unless ``q_measured`` fixes it.
    """
    state = GuardState()
    out = []
    for k, t in enumerate(times):
        ts = t if status_times is None else status_times(t)
        measured = q_measured if q_measured is not None else (HOME_Q if state.command is None else state.command)
        state = guard_step(state, t, measured, ts, q_desired_at(t), LIMITS)
        out.append(state)
    return out


def test_the_first_status_latches_the_command_at_the_measured_pose():
    state = guard_step(GuardState(), 0.0, HOME_Q, 12.5, HOME_Q + 0.3, LIMITS)
    assert state.status_time == 12.5 and state.arrival_time == 0.0
    step = LIMITS.v_max * LIMITS.period  # the first command moves at most one speed-limited step
    np.testing.assert_allclose(state.command, HOME_Q + np.minimum(0.3, step), atol=1e-12)


def test_no_status_no_command():
    assert not status_received(np.zeros(7), 0.0)  # what IiwaStatusReceiver makes of the default message
    assert status_received(np.zeros(7), 1.0) and status_received(HOME_Q, 0.0)
    assert guard_step(GuardState(), 0.3, np.zeros(7), 0.0, HOME_Q, LIMITS).command is None


def test_commands_move_at_most_the_speed_limit_per_period_and_stay_inside_the_joint_limits():
    lower, upper = IIWA7_JOINT_LIMITS
    far = upper + 1.0  # beyond every upper limit
    times = np.arange(400) * LIMITS.period
    states = _run(lambda t: far, times)
    q = np.array([s.command for s in states])
    assert (np.abs(np.diff(q, axis=0)) <= LIMITS.v_max * LIMITS.period + 1e-12).all()
    assert (q <= upper - LIMITS.margin + 1e-12).all() and (q >= lower + LIMITS.margin - 1e-12).all()
    np.testing.assert_allclose(q[-1], upper - LIMITS.margin, atol=1e-12)  # 2 s is enough to get there
    assert states[-1].limited > 0


def test_a_desired_motion_within_the_limits_passes_unchanged():
    times = np.arange(100) * LIMITS.period
    wave = lambda t: HOME_Q + 0.2 * math.sin(2 * t)  # 0.4 rad/s, well under every limit
    states = _run(wave, times)
    # one period behind at most (the latch step), then exact
    for t, s in zip(times[1:], states[1:]):
        np.testing.assert_allclose(s.command, wave(t), atol=1e-12)
    assert states[-1].limited == 0


def test_a_stale_status_freezes_the_command_and_it_resumes_only_near_the_frozen_pose():
    times = np.arange(200) * LIMITS.period  # 1 s
    moving = lambda t: HOME_Q + 0.3 * t   # 0.3 rad/s ramp
    # the status stops changing at 0.25 s (robot silent)...
    silent = lambda t: min(t, 0.25)
    states = _run(moving, times, status_times=silent)
    frozen = [s for t, s in zip(times, states) if t > 0.25 + 0.1 + 1e-9]
    assert all(s.holding for s in frozen) and states[-1].stale_events == 1
    held = frozen[0].command
    for s in frozen:
        np.testing.assert_array_equal(s.command, held)
    np.testing.assert_allclose(held, moving(0.35), atol=0.3 * LIMITS.period + 1e-12)  # frozen where it was
    # ...then it speaks again: still frozen while the desired pose is far, resumes when it comes back
    s = states[-1]
    s = guard_step(s, 1.0, held, 1.0, moving(1.0), LIMITS)   # the robot is where it was held
    assert s.holding and s.arrival_time == 1.0
    np.testing.assert_array_equal(s.command, held)
    s = guard_step(s, 1.005, held, 1.005, held + 0.005, LIMITS)
    assert not s.holding
    np.testing.assert_allclose(s.command, held + 0.005, atol=1e-12)


def test_the_guard_system_refuses_to_start_without_a_status():
    guard = IiwaCommandGuard(LIMITS)
    context = guard.CreateDefaultContext()
    guard.GetInputPort("desired_state").FixValue(context, np.concatenate([HOME_Q, np.zeros(7)]))
    guard.GetInputPort("position_measured").FixValue(context, np.zeros(7))  # the default message, decoded
    guard.GetInputPort("velocity_estimated").FixValue(context, np.zeros(7))
    guard.GetInputPort("status_time").FixValue(context, [0.0])
    simulator = Simulator(guard, context)
    with pytest.raises(RuntimeError, match="no lcmt_iiwa_status"):
        simulator.Initialize()
    with pytest.raises(RuntimeError, match="no good lcmt_iiwa_status"):
        guard.GetOutputPort("measured_state").Eval(context)
    guard.GetInputPort("position_measured").FixValue(context, HOME_Q)
    guard.GetInputPort("status_time").FixValue(context, [3.0])
    simulator.Initialize()
    np.testing.assert_allclose(guard.GetOutputPort("position").Eval(context), HOME_Q)
    np.testing.assert_allclose(guard.GetOutputPort("measured_state").Eval(context)[:7], HOME_Q)
    simulator.AdvanceTo(0.2)  # the status time never changes: stale after 0.1 s
    status = guard.GetOutputPort("guard_status").Eval(context)
    assert status.holding and status.stale_events == 1
    np.testing.assert_allclose(guard.GetOutputPort("position").Eval(context), HOME_Q)
    roundtrip = GuardState.from_vector(status.to_vector(7), 7)
    np.testing.assert_array_equal(roundtrip.command, status.command)
    assert (roundtrip.holding, roundtrip.stale_events, roundtrip.status_time) == (True, 1, 3.0)


def test_limits_are_validated():
    lower, upper = IIWA7_JOINT_LIMITS
    with pytest.raises(ValueError, match="shape"):
        GuardLimits(lower[:6], upper, IIWA7_VELOCITY_LIMITS, period=0.005)
    with pytest.raises(ValueError, match="stale_timeout"):
        GuardLimits(lower, upper, IIWA7_VELOCITY_LIMITS, period=0.005, stale_timeout=0.0)


# ------------------------------------------------- found by a cold review of the LCM path (2026-12-02)
def test_a_robot_moved_during_a_status_gap_is_re_latched_not_jumped_back_to():
    # the status stops for 0.3 s while the robot is restarted and jogged 0.25 rad; then fresh statuses
    state = _run(lambda t: HOME_Q, np.arange(20) * LIMITS.period)[-1]
    np.testing.assert_allclose(state.command, HOME_Q)
    for t in np.arange(20, 80) * LIMITS.period:   # silent: the command is frozen
        state = guard_step(state, t, HOME_Q, 19 * LIMITS.period, HOME_Q, LIMITS)
    assert state.holding
    jogged = HOME_Q + np.r_[0.25, np.zeros(6)]
    t = 80 * LIMITS.period
    state = guard_step(state, t, jogged, t, HOME_Q, LIMITS)   # fresh again; the desired pose is the old hold
    np.testing.assert_allclose(state.command, jogged)          # where the robot is, not 0.25 rad away
    assert state.holding and state.lag_events == 1
    for k in range(1, 20):   # and it holds there while the desired pose is far from it
        t = (80 + k) * LIMITS.period
        state = guard_step(state, t, jogged, t, HOME_Q, LIMITS)
        np.testing.assert_allclose(state.command, jogged)
    state = guard_step(state, t + LIMITS.period, jogged, t + LIMITS.period, jogged + 0.004, LIMITS)
    assert state.holding and state.needs_trial   # not mid-trial, even where the desired path passes by
    from dataclasses import replace
    state = replace(state, needs_trial=False)    # what the guard's initialization does at the next trial
    state = guard_step(state, t + 2 * LIMITS.period, jogged, t + 2 * LIMITS.period, jogged + 0.004, LIMITS)
    assert not state.holding   # the next trial's hold pose, latched from the measured position


def test_late_statuses_of_a_moving_robot_freeze_the_command_without_a_jump():
    # statuses that arrive late (new ones keep coming, so not stale) of a robot that still moves: the
    # command must not jump back to where the robot was (the first form stepped 0.31 rad in 5 ms,
    # then re-latched 12 times: a sawtooth)
    q_cmd = HOME_Q + 0.5
    state = GuardState(q_cmd, 0.0, 0.0, False, measured=HOME_Q + 0.45, velocity=np.zeros(7))
    moving = np.full(7, 1.5)
    for k in range(1, 40):
        t = k * LIMITS.period
        reported = q_cmd - 0.35 + 0.3 * k * LIMITS.period   # 0.35 rad behind, catching up
        state = guard_step(state, t, reported, t, q_cmd + 0.1 * t, LIMITS, q_velocity=moving)
        np.testing.assert_allclose(state.command, q_cmd)     # frozen where it was: no jump, no sawtooth
    assert state.holding and state.needs_trial and state.lag_events == 1
    # at rest far from the held command (it stopped there): commanded where it is, still until the next trial
    state = guard_step(state, 1.0, HOME_Q, 1.0, HOME_Q, LIMITS, q_velocity=np.zeros(7))
    np.testing.assert_allclose(state.command, HOME_Q)
    assert state.holding and state.needs_trial and state.lag_events == 2


def test_a_robot_that_stops_on_its_own_is_never_led_by_more_than_max_lag():
    # a protective stop: statuses keep coming, the robot does not move, the command would run ahead
    times = np.arange(400) * LIMITS.period
    states = _run(lambda t: HOME_Q + 0.5 * t, times, q_measured=HOME_Q)
    lead = np.array([np.abs(s.command - HOME_Q).max() for s in states])
    assert lead.max() <= LIMITS.max_lag + LIMITS.step_max.max() + 1e-12
    assert states[-1].holding and states[-1].lag_events == 1
    np.testing.assert_allclose(states[-1].command, HOME_Q)


def test_a_robot_parked_inside_the_margin_is_moved_out_at_the_speed_limit():
    lower, upper = IIWA7_JOINT_LIMITS
    parked = HOME_Q.copy()
    parked[3] = upper[3] - 1e-4   # 0.006 degrees from its limit, inside the 1 degree margin
    state, q = GuardState(), [parked]
    for t in np.arange(50) * LIMITS.period:   # the robot follows the command
        state = guard_step(state, t, q[-1], t, parked, LIMITS)
        q.append(state.command)
    q = np.array(q)
    # from where it is, at most one speed-limited step per period (the first command jumped into the
    # margin: 0.0174 rad in 5 ms, 3.47 rad/s against 2.27)
    assert (np.abs(np.diff(q, axis=0)) <= LIMITS.step_max + 1e-12).all()
    np.testing.assert_allclose(q[-1][3], upper[3] - LIMITS.margin, atol=1e-12)


def test_a_non_finite_desired_pose_holds_the_command():
    state = _run(lambda t: HOME_Q, np.arange(5) * LIMITS.period)[-1]
    for bad in (np.full(7, np.nan), np.r_[HOME_Q[:6], np.inf]):
        held = guard_step(state, 5 * LIMITS.period, HOME_Q, 5 * LIMITS.period, bad, LIMITS)
        assert np.isfinite(held.command).all()
        np.testing.assert_allclose(held.command, state.command)


def test_a_nan_status_at_a_trial_start_gives_the_last_good_measured_state():
    guard = IiwaCommandGuard(LIMITS)
    context = guard.CreateDefaultContext()
    guard.GetInputPort("desired_state").FixValue(context, np.concatenate([HOME_Q, np.zeros(7)]))
    guard.GetInputPort("position_measured").FixValue(context, HOME_Q)
    guard.GetInputPort("velocity_estimated").FixValue(context, np.full(7, 0.01))
    guard.GetInputPort("status_time").FixValue(context, [3.0])
    simulator = Simulator(guard, context)
    simulator.Initialize()
    simulator.AdvanceTo(0.02)
    bad = HOME_Q.copy()
    bad[2] = np.nan
    guard.GetInputPort("position_measured").FixValue(context, bad)
    guard.GetInputPort("status_time").FixValue(context, [3.02])
    np.testing.assert_allclose(guard.GetOutputPort("measured_state").Eval(context), np.r_[HOME_Q, np.full(7, 0.01)])
    simulator.AdvanceTo(0.05)
    assert np.isfinite(guard.GetOutputPort("position").Eval(context)).all()
