import numpy as np
import pytest

from drake_skills.systems.conditioner import ConditionedTrajectory, Conditioning
from drake_skills.systems.gating import GatingDecision
from drake_skills.systems.trial_monitor import TrialMonitor, TrialStatus, trial_status

KW = dict(settle_time=0.5, unknown_hold_time=0.75)


def test_a_trial_observes_conditions_executes_and_ends_after_the_settle_time():
    decided = GatingDecision(decided=True, component=3, time=2.0)
    traj = ConditionedTrajectory(3, np.zeros((5, 7)), np.zeros((5, 7)), 1.5, 2.0 + 1 / 64)
    assert trial_status(GatingDecision(), Conditioning(), **KW) == TrialStatus("observing")
    assert trial_status(decided, Conditioning(), **KW) == TrialStatus("conditioning")
    status = trial_status(decided, Conditioning(3, traj), **KW)
    assert status.phase == "executing" and status.end_time == traj.end_time + 0.5
    assert not status.done(traj.end_time) and status.done(traj.end_time + 0.5)


def test_unknown_and_a_failed_conditioning_hold_for_the_hold_time():
    unknown = GatingDecision(decided=True, component=None, time=2.0)
    assert trial_status(unknown, Conditioning(), **KW) == TrialStatus("holding", 2.75)
    failed = GatingDecision(decided=True, component=4, time=2.0)
    assert trial_status(failed, Conditioning(4, None), **KW) == TrialStatus("holding", 2.75)


def test_the_monitor_system_reads_its_two_inputs():
    monitor = TrialMonitor(**KW)
    context = monitor.CreateDefaultContext()
    monitor.GetInputPort("decision").FixValue(context, GatingDecision(decided=True, component=None, time=1.0))
    monitor.GetInputPort("conditioning").FixValue(context, Conditioning())
    assert monitor.GetOutputPort("trial_status").Eval(context) == TrialStatus("holding", 1.75)
    with pytest.raises(ValueError, match="settle_time"):
        TrialMonitor(settle_time=-1.0, unknown_hold_time=0.0)
    with pytest.raises(ValueError, match="phase"):
        TrialStatus("done")
