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


def _decision(demo, component, time=1.0, final=True):
    status = "skill" if component is not None else "unknown"
    return GatingDecision(_motion(demo), component, final, status, time)


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


def test_reconditions_on_the_growing_prefix_and_once_on_the_whole_motion(library, demo):
    """Same component while the person moves: revisions on longer prefixes, same start; then the final one."""
    k = library.recognize(demo.human, workspace=WORKSPACE, observed_fraction=1.0).component
    motion = _motion(demo)
    state = Conditioning()
    starts, revisions, phases = [], [], []
    for i, n in enumerate(range(40, motion.n, 10)):
        prefix = ObservedMotion(motion.times[:n], motion.samples[:n])
        t = 1.0 + i * 0.125
        state = conditioning_step(state, GatingDecision(prefix, k, False, "skill", 1.0), library, t)
        starts.append(state.trajectory.start_time)
        revisions.append(state.trajectory.revision)
        phases.append(state.trajectory.phase)
    assert set(starts) == {1.0} and revisions == list(range(len(revisions)))
    assert all(0 < p <= 1 for p in phases) and phases[-1] > phases[0]  # more of the motion seen
    # not again within RECONDITION_PERIOD, nor without new samples
    assert conditioning_step(state, GatingDecision(prefix, k, False, "skill", 1.0), library, t + 0.01) is state
    final = conditioning_step(state, _decision(demo, k), library, t + 0.5)
    assert final.final and final.trajectory.phase == 1.0 and final.trajectory.revision == revisions[-1] + 1
    assert conditioning_step(final, _decision(demo, k), library, t + 1.0) is final


def test_a_switch_starts_a_new_trajectory_and_giving_up_withdraws_it(library, demo):
    ids = [c.id for c in library.components]
    motion = _motion(demo)
    a = conditioning_step(Conditioning(), GatingDecision(motion, ids[0], False, "skill", 1.0), library, 1.0)
    b = conditioning_step(a, GatingDecision(motion, ids[1], False, "skill", 2.0), library, 2.0)
    assert b.component == ids[1] and b.trajectory.start_time == 2.0 and b.trajectory.revision == 0
    gone = conditioning_step(b, GatingDecision(motion, None, False, "pending", 2.5), library, 2.5)
    assert gone.component is None and gone.trajectory is None and not gone.final


def test_a_commit_read_after_a_false_start_is_conditioned_on_the_motion_from_its_restart(library, demo):
    """The gating's last answer naming the committed skill read the motion from sample 29 (a false start before it):
    the conditioner conditions on the samples from there on, as predict_robot does on the motion alone (1e-9)."""
    from drake_skills.systems.gating import Belief, gating_step
    from drake_skills.systems.decision_rule import DecisionRule

    z = np.sin(np.linspace(0.0, np.pi, 30))[:, None]
    fs = demo.human[0] + z * np.array([1.0, -4.0, 2.0])
    human = np.vstack([fs, demo.human[1:]])
    t = (demo.t[1] - demo.t[0]) * np.arange(len(human))
    rec = library.recognize(human, workspace=WORKSPACE)
    assert rec.status == "skill" and rec.restart == 29
    # gating_step records the restart of the answer it commits on
    state = GatingDecision(ObservedMotion(np.zeros(0), np.zeros((0, 3))))
    rule = DecisionRule(confirmations=1)
    y = WORKSPACE.normalize(human)
    for ti, yi in zip(t, y):
        state = gating_step(state, ti, yi, library, rule)
    assert state.component == rec.component and state.restart == 29
    traj = condition_robot(library, rec.component, ObservedMotion(t, y), 0.0, restart=state.restart)
    mean, _ = library.predict_robot(human[29:], workspace=WORKSPACE, component=rec.component)
    np.testing.assert_allclose(traj.mean, mean, atol=1e-9)
    # a decision whose last answer naming the committed skill read the whole motion has restart 0
    b = Belief(1.0, "skill", rec.component, 1.0, 1.0, (), 0)
    assert GatingDecision(ObservedMotion(t, y), rec.component, beliefs=(b,)).restart == 0
    assert GatingDecision(ObservedMotion(t, y), None, beliefs=(Belief(1.0, "skill", 3, 1.0, 1.0, (), 5),)).restart == 0


def test_the_decision_restart_is_that_of_the_last_answer_naming_the_committed_skill():
    from drake_skills.systems.gating import Belief

    m = ObservedMotion(np.arange(3.0), np.zeros((3, 3)))
    beliefs = (Belief(1.0, "skill", 2, 1.0, 0.5, (), 11), Belief(2.0, "skill", 3, 1.0, 0.5, (), 22),
               Belief(3.0, "skill", 2, 1.0, 0.6, (), 33), Belief(4.0, "undecided", 2, 0.6, 0.7, (), 44),
               Belief(5.0, "skill", 3, 1.0, 0.8, (), 55))
    assert GatingDecision(m, 2, beliefs=beliefs).restart == 33      # the last "skill" answer naming 2
    assert GatingDecision(m, 3, beliefs=beliefs).restart == 55
    assert GatingDecision(m, 4, beliefs=beliefs).restart == 0       # no answer named it


def test_conditioning_step_conditions_on_the_motion_from_the_decisions_restart(library, demo):
    """The conditioner's update passes the gating's restart on (the motion with a false start before it)."""
    from drake_skills.systems.gating import Belief

    z = np.sin(np.linspace(0.0, np.pi, 30))[:, None]
    human = np.vstack([demo.human[0] + z * np.array([1.0, -4.0, 2.0]), demo.human[1:]])
    t = (demo.t[1] - demo.t[0]) * np.arange(len(human))
    rec = library.recognize(human, workspace=WORKSPACE, observed_fraction=1.0)
    k, i = rec.component, rec.restart
    assert i == 29
    decision = GatingDecision(ObservedMotion(t, WORKSPACE.normalize(human)), k, True, "skill", 1.0,
                              beliefs=(Belief(1.0, "skill", k, 1.0, 1.0, (), i),))
    state = conditioning_step(Conditioning(), decision, library, 1.0)
    mean, _ = library.predict_robot(human[i:], 1.0, workspace=WORKSPACE, component=k)
    np.testing.assert_allclose(state.trajectory.mean, mean, atol=1e-9)
