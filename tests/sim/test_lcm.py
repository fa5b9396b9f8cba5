"""The controller over LCM against the simulated station, on the in-process bus memq:// only.

Tolerances: decisions (skill id or unknown) must be the same as the direct Diagram's on every
trial; the flange at the handover within 0.5 cm of the direct run's (the goal of issue 14;
observed: <= 0.3 cm). Commands within the joint limits exactly and within the speed limits
to 1e-9 rad/s.
"""
from dataclasses import replace

import numpy as np
import pytest
from drake import lcmt_iiwa_command
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.lcm import LcmInterfaceSystem

from drake_skills import SkillLibrary
from drake_skills.scenario.salad import generate_subject
from drake_skills.sim.config import SimConfig
from drake_skills.sim.demo import CollaborationSim
from drake_skills.sim.lcm_controller import ControllerRunner, build_lcm_controller
from drake_skills.sim.lcm_demo import LcmCollaborationSim, build_lcm_diagram
from drake_skills.sim.lcm_station import add_station
from drake_skills.sim.models import HOME_Q, IIWA7_JOINT_LIMITS, IIWA7_VELOCITY_LIMITS
from drake_skills.systems.wrist_source import WristTrial

TAUGHT = ("tomato", "standup", "bowl", "dressing")
#: A skill and an untaught task (unknown): held-out demonstrations (index 4). make demo's 20 trials are
#: compared by hand (README, "On a real robot"): a test runs a few.
TRIALS = (("tomato", 4), ("board", 4))
HANDOVER_TOLERANCE_CM = 0.5


@pytest.fixture(scope="module")
def subject():
    return generate_subject(1, n_demos=5, seed=0)


def _taught(cls, subject, config=None, **kw):
    sim = cls(config or SimConfig(), SkillLibrary(), subject.workspace(), **kw)
    for k in range(4):
        for task in TAUGHT:
            sim.teach(subject.by_task(task)[k])
    return sim


def _run(sim, subject):
    out = []
    for i, (task, k) in enumerate(TRIALS):
        demo = subject.by_task(task)[k]
        outcome, log = sim.run_trial(demo)
        out.append(sim.evaluate_trial(i, demo, outcome, log, task_known=task in TAUGHT))
    return out


def _commands(lcm, channel="IIWA_COMMAND"):
    """Every command published on ``channel``: a list of (utime, positions)."""
    seen = []
    lcm.Subscribe(channel, lambda data: seen.append(
        (lambda m: (m.utime, np.array(m.joint_position)))(lcmt_iiwa_command.decode(data))))
    return seen


def _check_limits(commands, period, trials=1):
    """Positions inside the joint limits; speeds between consecutive commands of a trial under the speed limits.

    A trial starts with the harness's hold command at the home pose beside the controller's
    first (same utime); between trials the simulated robot is put back home (a gap in utime).
    """
    q = np.array([c[1] for c in commands])
    lower, upper = IIWA7_JOINT_LIMITS
    assert (q >= lower).all() and (q <= upper).all()
    dt = np.diff(np.array([c[0] for c in commands])) * 1e-6
    steady = np.isclose(dt, period, atol=1e-6)
    assert np.sum(~steady & (dt > period)) <= trials - 1, "one command per period within a trial"
    speed = np.abs(np.diff(q, axis=0))[steady] / period
    assert (speed <= IIWA7_VELOCITY_LIMITS + 1e-9).all(), speed.max(axis=0)
    return speed.max()


@pytest.fixture(scope="module")
def direct(subject):
    return _run(_taught(CollaborationSim, subject), subject)


def test_over_memq_the_controller_decides_as_the_direct_diagram_and_hands_over_within_0_5_cm(subject, direct):
    sim = _taught(LcmCollaborationSim, subject)
    assert sim.parts.lcm.get_lcm_url() == "memq://" and sim.parts.links == ()
    commands = _commands(sim.parts.lcm)
    results = _run(sim, subject)
    assert [r.component for r in results] == [r.component for r in direct]
    assert [r.component is not None for r in direct] == [True, False]  # skill, unknown
    for lcm_result, direct_result in zip(results, direct):
        assert lcm_result.correct and direct_result.correct
        if direct_result.component is not None:
            assert abs(lcm_result.flange_error_cm - direct_result.flange_error_cm) < HANDOVER_TOLERANCE_CM
            assert lcm_result.flange_error_cm < 5.0
        else:  # unknown: the robot held still, as in the direct Diagram
            assert lcm_result.max_displacement_rad < 1e-3
    _check_limits(commands, sim.config.lcm.command_period, trials=len(TRIALS))


def test_with_5_percent_of_wrist_messages_dropped_and_20_ms_latency_the_controller_decides_the_same(subject, direct):
    config = SimConfig(lcm=replace(SimConfig().lcm, latency=0.02, wrist_drop=0.05))
    sim = _taught(LcmCollaborationSim, subject, config)
    commands = _commands(sim.parts.lcm)
    results = _run(sim, subject)
    assert [r.component for r in results] == [r.component for r in direct]
    wrist = next(link for link in sim.parts.links if link.target == "DRAKE_SKILLS_WRIST")
    assert 0.03 < wrist.dropped / wrist.received < 0.07, (wrist.dropped, wrist.received)  # ~5 % were dropped
    delays = [r.decision_delay - d.decision_delay for r, d in zip(results, direct)]
    assert max(abs(x) for x in delays) < 0.25, delays  # the decisions came at about the same time
    for lcm_result, direct_result in zip(results, direct):
        if direct_result.component is not None:
            assert abs(lcm_result.flange_error_cm - direct_result.flange_error_cm) < HANDOVER_TOLERANCE_CM
    assert len(commands) > 100 and all(r.within_limits for r in results)
    _check_limits(commands, config.lcm.command_period, trials=len(TRIALS))


def test_a_stale_status_makes_the_controller_hold_position(subject):
    """The status link goes silent while the robot executes a skill: 100 ms later the command freezes."""
    config = SimConfig(lcm=replace(SimConfig().lcm, latency=1 / 1024))  # links on the bus, no drops
    sim = _taught(LcmCollaborationSim, subject, config)
    demo = subject.by_task("tomato")[4]
    commands = _commands(sim.parts.lcm)
    sim._start_trial(demo, 0.0)
    h, ctx = sim.handles, sim.context
    source_ctx = h.trajectory_source.GetMyContextFromRoot(ctx)
    simulator = sim.simulator
    while h.trajectory_source.plan(source_ctx) is None:  # until the skill is decided and planned
        simulator.AdvanceTo(ctx.get_time() + 1 / 32)
    plan = h.trajectory_source.plan(source_ctx)
    t_cut = plan.start_time + 0.3 * (plan.end_time - plan.start_time)
    simulator.AdvanceTo(t_cut)
    status_link = next(link for link in sim.parts.links if link.target == "IIWA_STATUS")
    status_link.blocked = True
    simulator.AdvanceTo(t_cut + 1.1)
    guard = sim.parts.controller.guard
    state = guard.guard_state(guard.GetMyContextFromRoot(ctx))
    assert state.holding and state.stale_events == 1
    t_hold = state.arrival_time + config.lcm.stale_timeout
    # the last status got through the link (1/1024 s) and was seen at the guard's next update (5 ms)
    assert t_cut - 0.01 < state.arrival_time <= t_cut + config.lcm.command_period + 2 / 1024
    q = np.array([c[1] for c in commands])
    t = np.array([c[0] for c in commands]) * 1e-6
    before, after = q[t < t_cut], q[t > t_hold + 2 * config.lcm.command_period]
    assert np.abs(before[-1] - before[-20]).max() > 1e-3  # it was moving before the status went silent
    assert len(after) > 50 and np.abs(after - after[0]).max() == 0.0  # ...and holds still after
    desired = h.trajectory_source.GetOutputPort("desired_state").Eval(source_ctx)[:7]
    assert np.abs(desired - after[-1]).max() > 0.05  # the plan went on without the robot
    plant_ctx = h.plant.GetMyContextFromRoot(ctx)
    assert np.abs(h.plant.GetVelocities(plant_ctx, h.iiwa)).max() < 0.01  # the simulated robot stopped...
    assert np.abs(h.plant.GetPositions(plant_ctx, h.iiwa) - after[-1]).max() < 0.01  # ...at the held command
    _check_limits(commands, config.lcm.command_period)


def test_the_two_halves_meet_only_on_the_bus(subject):
    """Apart from the recording's decision colour, no wire crosses between station and controller."""
    from drake_skills.sim.diagram import make_meshcat

    config = SimConfig()
    diagram, handles, parts = build_lcm_diagram(config, library=SkillLibrary(), workspace=subject.workspace(),
                                                meshcat=make_meshcat())
    controller_names = {s.get_name() for s in (
        parts.controller.guard, parts.controller.status_subscriber, parts.controller.status_receiver,
        parts.controller.wrist_subscriber, parts.controller.wrist_receiver, parts.controller.command_sender,
        parts.controller.command_publisher, *parts.controller.controller.trial_systems)}
    crossing = []
    for (dst, _), (src, _) in diagram.connection_map().items():
        if (src.get_name() in controller_names) != (dst.get_name() in controller_names):
            crossing.append((src.get_name(), dst.get_name()))
    assert crossing == [("skill_gating", "wrist_marker")], crossing


def test_the_controller_alone_runs_trials_against_a_station_in_another_simulator(subject):
    """Two Diagrams, two Simulators, one memq:// bus, advanced in turn every 1/128 s (as two processes would)."""
    config = SimConfig()
    lcm = DrakeLcm("memq://")
    builder = DiagramBuilder()
    builder.AddSystem(LcmInterfaceSystem(lcm))
    station = add_station(builder, config, lcm)
    station_diagram = builder.Build()
    station_sim = Simulator(station_diagram)
    demo = subject.by_task("standup")[4]
    sctx = station_sim.get_mutable_context()
    station.wrist_source.SetTrial(station.wrist_source.GetMyContextFromRoot(sctx),
                                  WristTrial(demo.t, demo.human, 0.25))
    library = _taught(CollaborationSim, subject).library
    diagram, handles = build_lcm_controller(config, library=library, workspace=subject.workspace(), lcm=lcm)
    runner = ControllerRunner(diagram, handles, config, realtime_rate=0.0)
    station_sim.Initialize()
    station_sim.AdvanceTo(0.01)  # the robot driver and the tracker publish first
    runner.start()
    finished = []
    t = 0.01
    while not finished and t < demo.duration + 8.0:
        t += 1 / 128
        station_sim.AdvanceTo(t)
        finished += runner.advance_to(t)
    assert [f.decision for f in finished] == ["skill 1"] and not finished[0].held_for_stale_status
    q = station.plant.GetPositions(station.plant.GetMyContextFromRoot(sctx), station.iiwa)
    assert np.abs(q - HOME_Q).max() > 0.3  # the station's robot executed the skill
    # the next trial started: observing again, from where the robot is
    c = handles.controller
    assert c.gating.decision(c.gating.GetMyContextFromRoot(runner.context)).status == "pending"
    np.testing.assert_allclose(c.trajectory_source.hold_pose(c.trajectory_source.GetMyContextFromRoot(
        runner.context)), q, atol=0.02)


def test_the_controller_refuses_to_start_on_a_silent_bus(subject):
    config = SimConfig(lcm=replace(SimConfig().lcm, wait_for_messages=0.05))
    diagram, handles = build_lcm_controller(config, library=SkillLibrary(), workspace=subject.workspace(),
                                            lcm=DrakeLcm("memq://"))
    runner = ControllerRunner(diagram, handles, config, realtime_rate=0.0)
    with pytest.raises(TimeoutError, match="'IIWA_STATUS' \\(lcmt_iiwa_status\\), 'DRAKE_SKILLS_WRIST'"):
        runner.start()


def test_the_lcm_settings_are_read_from_the_config_and_validated(tmp_path):
    from drake_skills.sim.config import load_config

    path = tmp_path / "sim.yaml"
    path.write_text("lcm:\n  latency: 0.02\n  wrist_channel: TRACKER\n")
    lcm = load_config(path).lcm
    assert (lcm.latency, lcm.wrist_channel, lcm.status_channel, lcm.url) == (0.02, "TRACKER", "IIWA_STATUS", "memq://")
    assert lcm.impaired
    path.write_text("lcm:\n  wrist_drop: 1.5\n")
    with pytest.raises(ValueError, match="sim.yaml.*wrist_drop"):
        load_config(path)
    path.write_text("lcm:\n  command_channel: IIWA_STATUS\n")
    with pytest.raises(ValueError, match="distinct"):
        load_config(path)
