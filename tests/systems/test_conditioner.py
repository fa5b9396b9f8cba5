import numpy as np
import pytest

from drake_skills.systems.conditioner import ConditionedTrajectory, InteractionProMPConditioner, condition_robot
from drake_skills.systems.gating import ObservedMotion, identity_workspace

WORKSPACE = identity_workspace(3)  # the synthetic demos are in normalized units


def _motion(demo):
    y = WORKSPACE.normalize(demo.human)
    return ObservedMotion(demo.t.copy(), y)


def test_condition_robot_equals_predict_robot(library, demo):
    k = library.recognize(demo.human, workspace=WORKSPACE).component
    traj = condition_robot(library, k, _motion(demo), start_time=2.0)
    mean, cov = library.predict_robot(demo.human, workspace=WORKSPACE, component=k)
    np.testing.assert_allclose(traj.mean, mean, atol=1e-9)
    np.testing.assert_allclose(traj.std ** 2, np.diagonal(cov, axis1=1, axis2=2), atol=1e-12)
    assert traj.duration == pytest.approx(library.component(k).duration)
    assert traj.end_time == pytest.approx(2.0 + traj.duration)
    # the conditioned answer ends near the demonstration's robot end point
    assert np.abs(traj.mean[-1] - demo.robot[-1]).max() < 0.1


def _step(system, context):
    scratch = context.Clone()
    system.CalcForcedUnrestrictedUpdate(context, scratch.get_mutable_state())
    context.SetAbstractState(0, scratch.get_abstract_state(0).get_value())


def test_no_trajectory_while_pending_or_unknown(library, demo):
    cond = InteractionProMPConditioner(library)
    context = cond.CreateDefaultContext()
    cond.GetInputPort("observed_motion").FixValue(context, _motion(demo))
    for k in (-2, -1):
        cond.GetInputPort("component").FixValue(context, [k])
        _step(cond, context)
        assert cond.GetOutputPort("robot_trajectory").Eval(context) is None


def test_conditions_once_per_decision(library, demo, monkeypatch):
    cond = InteractionProMPConditioner(library)
    context = cond.CreateDefaultContext()
    k = library.recognize(demo.human, workspace=WORKSPACE).component
    cond.GetInputPort("observed_motion").FixValue(context, _motion(demo))
    cond.GetInputPort("component").FixValue(context, [k])
    calls = []
    original = library.predict_robot
    monkeypatch.setattr(library, "predict_robot", lambda *a, **kw: calls.append(1) or original(*a, **kw))
    context.SetTime(1.5)
    _step(cond, context)
    traj = cond.GetOutputPort("robot_trajectory").Eval(context)
    assert isinstance(traj, ConditionedTrajectory) and traj.component == k and traj.start_time == 1.5
    for i in range(5):
        context.SetTime(1.5 + (i + 1) / 64)
        _step(cond, context)
    assert len(calls) == 1
    assert cond.GetOutputPort("robot_trajectory").Eval(context).start_time == 1.5
