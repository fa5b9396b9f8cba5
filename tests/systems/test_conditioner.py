import logging

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.common.value import AbstractValue
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource

from drake_skills.systems.conditioner import (ConditionedTrajectory, Conditioning, InteractionProMPConditioner,
                                              condition_robot, conditioning_step)
from drake_skills.systems.gating import GatingDecision, ObservedMotion
from drake_skills.systems.trajectory_source import JointTrajectorySource

from synthetic import WORKSPACE  # the synthetic demos are in normalized units


def _motion(demo):
    y = WORKSPACE.normalize(demo.human)
    return ObservedMotion(demo.t.copy(), y)


def _decision(demo, component, time=1.0):
    return GatingDecision(_motion(demo), True, component, {}, time)


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
    for decision in (GatingDecision(_motion(demo)), _decision(demo, None)):
        cond.GetInputPort("decision").FixValue(context, decision)
        _step(cond, context)
        assert cond.GetOutputPort("robot_trajectory").Eval(context) is None
        assert cond.GetOutputPort("conditioning").Eval(context).component is None


def test_conditions_once_per_decision(library, demo, monkeypatch):
    cond = InteractionProMPConditioner(library)
    context = cond.CreateDefaultContext()
    k = library.recognize(demo.human, workspace=WORKSPACE).component
    cond.GetInputPort("decision").FixValue(context, _decision(demo, k))
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


def test_a_deleted_component_is_logged_and_gives_no_trajectory_so_the_robot_holds(library, demo, caplog):
    """The gating chose a component that is gone by the time of conditioning (deleted meanwhile)."""
    gone = max(c.id for c in library.components) + 100
    with caplog.at_level(logging.WARNING, logger="drake_skills.systems.conditioner"):
        result = conditioning_step(Conditioning(), _decision(demo, gone), library, 1.0)
    assert result.component == gone and result.trajectory is None and result.failed
    assert f"cannot condition component {gone}" in caplog.text
    assert conditioning_step(result, _decision(demo, gone), library, 2.0) is result  # tried once per trial

    # in a diagram: the trajectory source keeps the robot at its hold pose
    n = 7
    lower, upper, q_hold = -np.full(n, 3.0), np.full(n, 3.0), np.linspace(-0.3, 0.3, n)
    builder = DiagramBuilder()
    decision = builder.AddSystem(ConstantValueSource(AbstractValue.Make(_decision(demo, gone, time=0.0))))
    cond = builder.AddSystem(InteractionProMPConditioner(library))
    source = builder.AddSystem(JointTrajectorySource(lower, upper, q_hold))
    measured = builder.AddSystem(ConstantVectorSource(np.concatenate([q_hold, np.zeros(n)])))
    builder.Connect(decision.get_output_port(), cond.GetInputPort("decision"))
    builder.Connect(cond.GetOutputPort("robot_trajectory"), source.GetInputPort("robot_trajectory"))
    builder.Connect(measured.get_output_port(), source.GetInputPort("measured_state"))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    with caplog.at_level(logging.WARNING, logger="drake_skills.systems.conditioner"):
        simulator.AdvanceTo(0.5)
    ctx = simulator.get_context()
    assert cond.conditioning(cond.GetMyContextFromRoot(ctx)).failed
    desired = source.GetOutputPort("desired_state").Eval(source.GetMyContextFromRoot(ctx))
    np.testing.assert_array_equal(desired, np.concatenate([q_hold, np.zeros(n)]))
    assert caplog.text.count("cannot condition component") == 2  # the step above, then the diagram, once


def test_the_library_gets_normalized_samples_and_no_workspace(library, demo, monkeypatch):
    seen = {}
    original = library.predict_robot
    monkeypatch.setattr(library, "predict_robot", lambda *a, **kw: seen.update(kw) or original(*a, **kw))
    k = library.recognize(demo.human, workspace=WORKSPACE).component
    condition_robot(library, k, _motion(demo), 0.0)
    assert seen["normalized"] is True and seen.get("workspace") is None
