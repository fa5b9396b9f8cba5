import numpy as np
import pytest

from drake_skills.systems.conditioner import ConditionedTrajectory, Conditioning
from drake_skills.systems.gating import GatingDecision
from drake_skills.systems.trial_monitor import TrialMonitor, TrialStatus, trial_status

KW = dict(settle_time=0.5, unknown_hold_time=0.75)


def test_a_trial_observes_conditions_executes_and_ends_after_the_settle_time():
    committed = GatingDecision(component=3, status="skill", time=2.0)  # while the person moves
    final = GatingDecision(component=3, final=True, status="skill", time=2.0)
    traj = ConditionedTrajectory(3, np.zeros((5, 7)), np.zeros((5, 7)), 1.5, 2.0 + 1 / 64)
    assert trial_status(GatingDecision(), Conditioning(), **KW) == TrialStatus("observing")
    assert trial_status(committed, Conditioning(), **KW) == TrialStatus("conditioning")
    assert trial_status(committed, Conditioning(3, traj), **KW) == TrialStatus("executing")  # no end yet
    assert trial_status(final, Conditioning(3, traj), **KW) == TrialStatus("executing")  # not re-conditioned yet
    status = trial_status(final, Conditioning(3, traj, final=True, time=2.5), **KW)
    assert status.phase == "executing" and status.end_time == traj.end_time + 0.5
    assert not status.done(traj.end_time) and status.done(traj.end_time + 0.5)


def test_unknown_and_a_failed_conditioning_hold_for_the_hold_time():
    unknown = GatingDecision(final=True, status="unknown", component=None, time=2.0)
    assert trial_status(unknown, Conditioning(), **KW) == TrialStatus("holding", 2.75)
    failed = GatingDecision(final=True, status="skill", component=4, time=2.0)
    assert trial_status(failed, Conditioning(4, None), **KW) == TrialStatus("holding", 2.75)
    given_up = GatingDecision(component=None, status="pending", time=2.0)  # gave up while moving: observe on
    assert trial_status(given_up, Conditioning(None, None), **KW) == TrialStatus("observing")


def test_the_monitor_system_reads_its_two_inputs():
    monitor = TrialMonitor(**KW)
    context = monitor.CreateDefaultContext()
    monitor.GetInputPort("decision").FixValue(context, GatingDecision(final=True, status="unknown", time=1.0))
    monitor.GetInputPort("conditioning").FixValue(context, Conditioning())
    assert monitor.GetOutputPort("trial_status").Eval(context) == TrialStatus("holding", 1.75)
    with pytest.raises(ValueError, match="settle_time"):
        TrialMonitor(settle_time=-1.0, unknown_hold_time=0.0)
    with pytest.raises(ValueError, match="phase"):
        TrialStatus("done")
