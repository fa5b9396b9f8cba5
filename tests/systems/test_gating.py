import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from drake_skills import SkillLibrary
from drake_skills.systems.decision_rule import DecisionRule
from drake_skills.systems.gating import (GatingDecision, ObservedMotion, SkillGating, gating_step, motion_is_over,
                                         recognize_motion, should_decide)
from drake_skills.systems.normalizer import WorkspaceNormalizer
from drake_skills.systems.wrist_source import HumanWristSource, WristTrial

from synthetic import WORKSPACE  # the synthetic demos are in normalized units

RULE = DecisionRule()


def _motion(y, dt=1 / 64):
    y = np.asarray(y, float)
    return ObservedMotion(dt * np.arange(len(y)), y - y[0])


def test_motion_is_over_needs_travel_then_stillness():
    still = np.zeros((40, 3))
    assert not motion_is_over(_motion(still), RULE)  # never moved
    # 0.2 units per tick: never within still_radius (0.05) for still_duration
    moving = np.outer(np.linspace(0, 7.8, 40), [1, 0, 0])
    assert not motion_is_over(_motion(moving), RULE)  # still moving
    ticks = int(np.ceil(RULE.still_duration * 64))  # still for still_duration
    stop = np.vstack([moving, np.repeat(moving[-1:], ticks + 1, axis=0)])
    assert motion_is_over(_motion(stop), RULE)
    assert not motion_is_over(_motion(stop[:-3]), RULE)  # still for 24/64 s < still_duration


def test_decision_time_overrides_stillness():
    rule = DecisionRule(decision_time=0.5)
    moving = np.outer(np.linspace(0, 3, 40), [1, 0, 0])
    assert not should_decide(_motion(moving[:32]), rule)
    assert should_decide(_motion(moving[:33]), rule)


def test_timeout_decides_a_motion_that_never_stops_after_the_timeout_and_not_before():
    rule = DecisionRule(timeout=0.5)
    moving = np.outer(np.linspace(0, 40, 200), [1, 0, 0])  # never still
    assert not any(should_decide(_motion(moving[:n]), rule) for n in range(1, 32))  # 31 samples: 0.47 s
    assert should_decide(_motion(moving[:33]), rule)  # 0.5 s after the first sample
    assert not any(should_decide(_motion(moving[:n]), DecisionRule()) for n in range(1, 200))


def test_gating_decides_at_the_timeout(library, demo):
    y = WORKSPACE.normalize(demo.human)
    wobble = y[-1] + np.outer(np.sin(np.arange(400)), [0.5, 0, 0])  # the hand never comes to rest
    state, rule = GatingDecision(), DecisionRule(timeout=2.0)
    for i, p in enumerate(np.vstack([y, wobble])):
        state = gating_step(state, i / 64, p, library, rule)
        if state.decided:
            break
    assert state.decided and state.time == pytest.approx(2.0)


def test_empty_library_answers_unknown():
    k, resp = recognize_motion(SkillLibrary(), _motion(np.outer(np.linspace(0, 3, 9), [1, 1, 0])))
    assert k is None and resp == {}


def test_recognize_motion_finds_the_demonstrated_skill(library, demo):
    y = WORKSPACE.normalize(demo.human)
    k, resp = recognize_motion(library, _motion(y))
    assert k == library.recognize(demo.human, workspace=WORKSPACE).component
    assert isinstance(k, int) and resp[k] > 0.9


def test_gating_step_decides_once_and_then_freezes(library, demo):
    y = WORKSPACE.normalize(demo.human)
    state = GatingDecision()
    for i, p in enumerate(np.vstack([y, np.repeat(y[-1:], 40, axis=0)])):
        state = gating_step(state, i / 64, p, library, RULE)
        if state.decided:
            break
    assert state.decided and state.status == "skill" and isinstance(state.component, int)
    assert gating_step(state, 99.0, np.ones(3), library, RULE) is state


def test_outputs_pending_then_the_component_after_forced_updates(library, demo):
    gating = SkillGating(library)
    context = gating.CreateDefaultContext()
    port = gating.GetOutputPort("decision")
    assert port.Eval(context).status == "pending" and port.Eval(context).responsibilities == {}
    y = WORKSPACE.normalize(demo.human)
    scratch = context.Clone()
    samples = np.vstack([y[::2], np.repeat(y[-1:], 40, axis=0)])
    for i, p in enumerate(samples):
        context.SetTime(i / 64)
        gating.GetInputPort("normalized_wrist").FixValue(context, p)
        gating.CalcForcedUnrestrictedUpdate(context, scratch.get_mutable_state())
        context.SetAbstractState(0, scratch.get_abstract_state(0).get_value())
    decision = port.Eval(context)
    assert decision.component == library.recognize(demo.human, workspace=WORKSPACE).component
    assert type(decision.component) is int  # an integer id travels, no float to round
    assert sum(decision.responsibilities.values()) == pytest.approx(1.0)
    assert decision.motion.n < len(samples)  # stopped accumulating


def test_replayed_motion_is_decided_in_a_simulation(library, demo):
    builder = DiagramBuilder()
    source = builder.AddSystem(HumanWristSource(WristTrial(demo.t, demo.human)))
    norm = builder.AddSystem(WorkspaceNormalizer(WORKSPACE))
    gating = builder.AddSystem(SkillGating(library))
    builder.Connect(source.GetOutputPort("human_wrist"), norm.GetInputPort("human_wrist"))
    builder.Connect(norm.GetOutputPort("normalized_wrist"), gating.GetInputPort("normalized_wrist"))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(demo.duration + 0.5)
    context = gating.GetMyContextFromRoot(simulator.get_context())
    decision = gating.decision(context)
    assert decision.decided and decision.component == library.recognize(demo.human, workspace=WORKSPACE).component
    assert demo.duration < decision.time < demo.duration + 0.4
