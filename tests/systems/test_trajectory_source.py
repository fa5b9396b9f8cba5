import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from drake_skills.systems.conditioner import ConditionedTrajectory, InteractionProMPConditioner
from drake_skills.systems.gating import SkillGating
from drake_skills.systems.normalizer import WorkspaceNormalizer
from drake_skills.systems.trajectory_source import (JointTrajectorySource, build_plan, desired_at, plan_knots,
                                                     tail_of, trajectory_clock)
from drake_skills.systems.wrist_source import HumanWristSource, WristTrial

from synthetic import WORKSPACE

LOWER, UPPER = -np.full(7, 2.0), np.full(7, 2.0)
HOME = np.array([0.0, 0.3, 0.0, -1.2, 0.0, 0.6, 0.0])


def _traj(start_time=1.0, end=None):
    s = np.linspace(0, 1, 50)[:, None]
    end = np.array([0.5, 0.8, -0.4, -0.5, 0.3, 1.0, 0.2]) if end is None else end
    mean = HOME + (end - HOME) * (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5) + 0.05
    return ConditionedTrajectory(3, mean, np.zeros_like(mean), 2.0, start_time)


def test_plan_starts_at_the_held_pose_and_ends_at_the_mean():
    traj = _traj()
    times, q = plan_knots(traj, HOME, LOWER, UPPER)
    np.testing.assert_allclose(q[0], HOME)
    np.testing.assert_allclose(q[-1], traj.mean[-1])
    # 2 s of trajectory, its first and last 0.25 s played at half speed on average
    assert times[0] == 1.0 and times[-1] == 3.0 + 2 * tail_of(2.0) == 3.5
    plan = build_plan(traj, HOME, LOWER, UPPER)
    q0, v0, _ = desired_at(plan, HOME, 1.0)
    np.testing.assert_allclose(q0, HOME, atol=1e-12)
    np.testing.assert_allclose(v0, 0.0, atol=1e-12)
    q1, v1, a1 = desired_at(plan, HOME, 10.0)
    np.testing.assert_allclose(q1, traj.mean[-1])
    assert not v1.any() and not a1.any()
    # held before the start
    np.testing.assert_allclose(desired_at(plan, HOME, 0.5)[0], HOME)


def test_plan_respects_joint_limits():
    traj = _traj(end=np.full(7, 3.0))
    plan = build_plan(traj, HOME, LOWER, UPPER)
    qs = np.stack([desired_at(plan, HOME, t)[0] for t in np.linspace(0.9, 3.1, 500)])
    assert (qs <= UPPER).all() and (qs >= LOWER).all()


def test_plan_velocity_is_the_derivative_of_position():
    plan = build_plan(_traj(), HOME, LOWER, UPPER)
    t, h = 1.7, 1e-6
    dq = (desired_at(plan, HOME, t + h)[0] - desired_at(plan, HOME, t - h)[0]) / (2 * h)
    np.testing.assert_allclose(desired_at(plan, HOME, t)[1], dq, atol=1e-5)


def test_holds_the_measured_pose_until_a_trajectory_arrives():
    source = JointTrajectorySource(LOWER, UPPER, HOME)
    simulator = Simulator(source)
    context = simulator.get_mutable_context()
    q_meas = HOME + 0.1
    source.GetInputPort("measured_state").FixValue(context, np.concatenate([q_meas, np.zeros(7)]))
    source.GetInputPort("robot_trajectory").FixValue(context, None)
    simulator.Initialize()
    simulator.AdvanceTo(0.5)
    np.testing.assert_allclose(source.GetOutputPort("desired_state").Eval(context), np.r_[q_meas, np.zeros(7)])
    np.testing.assert_allclose(source.GetOutputPort("desired_acceleration").Eval(context), 0.0)
    # a trajectory starting at 1 s is picked up by the next update and played
    source.GetInputPort("robot_trajectory").FixValue(context, _traj(start_time=1.0))
    simulator.AdvanceTo(2.0)
    plan = source.plan(context)
    assert plan is not None and plan.start_time == 1.0
    np.testing.assert_allclose(source.GetOutputPort("desired_state").Eval(context)[:7], plan.q.value(2.0)[:, 0])
    simulator.AdvanceTo(4.0)
    np.testing.assert_allclose(source.GetOutputPort("desired_state").Eval(context)[:7], plan.q.value(3.5)[:, 0])
    np.testing.assert_allclose(source.GetOutputPort("desired_state").Eval(context)[:7][0], 0.55)  # knots shifted


def test_whole_chain_turns_a_replayed_motion_into_a_joint_plan(library, demo):
    ws = WORKSPACE
    builder = DiagramBuilder()
    wrist = builder.AddSystem(HumanWristSource(WristTrial(demo.t, demo.human)))
    norm = builder.AddSystem(WorkspaceNormalizer(ws))
    gating = builder.AddSystem(SkillGating(library))
    cond = builder.AddSystem(InteractionProMPConditioner(library))
    source = builder.AddSystem(JointTrajectorySource(LOWER, UPPER, np.zeros(7)))
    builder.Connect(wrist.GetOutputPort("human_wrist"), norm.GetInputPort("human_wrist"))
    builder.Connect(norm.GetOutputPort("normalized_wrist"), gating.GetInputPort("normalized_wrist"))
    builder.Connect(gating.GetOutputPort("decision"), cond.GetInputPort("decision"))
    builder.Connect(cond.GetOutputPort("robot_trajectory"), source.GetInputPort("robot_trajectory"))
    builder.ExportInput(source.GetInputPort("measured_state"), "measured_state")
    diagram = builder.Build()
    simulator = Simulator(diagram)
    root = simulator.get_mutable_context()
    diagram.GetInputPort("measured_state").FixValue(root, np.zeros(14))
    simulator.AdvanceTo(demo.duration + 3.0)
    ctx = source.GetMyContextFromRoot(root)
    plan = source.plan(ctx)
    assert plan is not None
    k = library.recognize(demo.human, workspace=ws).component
    assert plan.source.component == k
    mean, _ = library.predict_robot(demo.human, workspace=ws, component=k)
    q_end = source.GetOutputPort("desired_state").Eval(ctx)[:7]
    np.testing.assert_allclose(q_end, plan.source.mean[-1], atol=1e-12)
    # decided a little before the wrist fully stopped: close to the prediction from the whole motion
    np.testing.assert_allclose(q_end, mean[-1], atol=0.01)


def _speed_limits():
    return np.full(7, 1.5)


def test_a_replan_blends_in_with_continuous_position_and_velocity_within_limits():
    from drake_skills.systems.trajectory_source import blend_plan, peak_speed_ratio

    first = build_plan(_traj(1.0), HOME, LOWER, UPPER)
    now = 1.8  # mid-motion: moving
    q0, v0, _ = desired_at(first, HOME, now)
    assert np.abs(v0).max() > 0.1
    other = _traj(1.0, end=np.array([-0.6, 0.2, 0.5, -1.0, -0.3, 0.2, -0.4]))  # a different answer
    plan = blend_plan(other, now, q0, v0, LOWER, UPPER, _speed_limits())
    q1, v1, _ = desired_at(plan, HOME, now)
    np.testing.assert_allclose(q1, q0, atol=1e-9)
    np.testing.assert_allclose(v1, v0, atol=1e-6)
    # no jump just after the switch: positions move at most v_max dt in dt = 1 ms
    q2, _, _ = desired_at(plan, HOME, now + 1e-3)
    assert np.abs(q2 - q1).max() <= 1.5 * 1e-3 + 1e-6
    assert peak_speed_ratio(plan, _speed_limits()) <= 1.0 + 1e-6
    ts = np.linspace(plan.start_time, plan.end_time, 300)
    qs = np.stack([desired_at(plan, HOME, t)[0] for t in ts])
    assert (qs >= LOWER).all() and (qs <= UPPER).all()
    np.testing.assert_allclose(desired_at(plan, HOME, plan.end_time + 1)[0], other.mean[-1], atol=1e-6)


def test_a_blend_that_would_be_too_fast_is_slowed_down():
    from drake_skills.systems.trajectory_source import blend_plan, peak_speed_ratio

    far = _traj(1.0, end=np.array([1.8, -1.8, 1.8, -1.8, 1.8, -1.8, 1.8]))
    slow = np.full(7, 0.5)
    plan = blend_plan(far, 1.0, HOME, np.zeros(7), LOWER, UPPER, slow)
    assert peak_speed_ratio(plan, slow) <= 1.0 + 1e-6
    assert plan.end_time > far.end_time  # stretched


def test_a_withdrawn_trajectory_stops_the_robot_smoothly_and_holds():
    from drake_skills.systems.trajectory_source import STOP_TIME, stop_plan

    first = build_plan(_traj(1.0), HOME, LOWER, UPPER)
    q0, v0, _ = desired_at(first, HOME, 1.8)
    stop = stop_plan(1.8, q0, v0, LOWER, UPPER)
    q1, v1, _ = desired_at(stop, HOME, 1.8)
    np.testing.assert_allclose(q1, q0, atol=1e-9)
    np.testing.assert_allclose(v1, v0, atol=1e-6)
    qe, ve, _ = desired_at(stop, HOME, 1.8 + STOP_TIME)
    np.testing.assert_allclose(ve, 0.0, atol=1e-9)
    np.testing.assert_allclose(qe, q0 + 0.5 * STOP_TIME * v0, atol=1e-6)  # stops v0 T / 2 further on
    # the source system does it when its input goes back to None
    source = JointTrajectorySource(LOWER, UPPER, HOME)
    ctx = source.CreateDefaultContext()
    port = source.GetInputPort("robot_trajectory")
    source.GetInputPort("measured_state").FixValue(ctx, np.concatenate([HOME, np.zeros(7)]))
    scratch = ctx.Clone()

    def step(t, value):
        ctx.SetTime(t)
        port.FixValue(ctx, value)
        source.CalcForcedUnrestrictedUpdate(ctx, scratch.get_mutable_state())
        ctx.SetAbstractState(0, scratch.get_abstract_state(0).get_value())

    step(1.0, _traj(1.0))
    step(1.8, None)
    assert source.plan(ctx).source is None
    ctx.SetTime(1.8 + STOP_TIME + 0.1)
    np.testing.assert_allclose(source.GetOutputPort("desired_state").Eval(ctx)[7:], 0.0, atol=1e-9)


def _moving_traj(start_time=1.0, speed=0.2):
    """A conditioned mean that still moves at its first and last samples (as real ones do: 0.06-0.19 rad/s)."""
    s = np.linspace(0, 1, 50)[:, None]
    mean = HOME + 2.0 * speed * s * np.array([1.0, -0.5, 0.8, 0.3, -1.0, 0.6, 0.4])
    return ConditionedTrajectory(3, mean, np.zeros_like(mean), 2.0, start_time)


def _accel(plan, t):
    return np.abs(desired_at(plan, HOME, t)[2]).max()


def test_the_clock_starts_and_ends_at_rest_and_covers_the_trajectory():
    D, T = 2.0, tail_of(2.0)
    r = np.linspace(0.0, D + 2 * T, 20001)
    tau = trajectory_clock(r, D, T)
    rate = np.gradient(tau, r)
    assert tau[0] == 0.0 and abs(tau[-1] - D) < 1e-12 and (np.diff(tau) >= 0).all()
    assert rate[0] < 1e-6 and rate[-1] < 1e-6 and abs(rate.max() - 1.0) < 1e-9
    assert np.abs(np.diff(rate)).max() < 1e-3   # no step in the clock's speed (its acceleration is bounded)


def test_a_plan_of_a_moving_mean_starts_and_ends_at_rest_without_an_acceleration_spike():
    # a cold review found every plan stopping within one knot interval: 10-53 rad/s^2 in its last 50 ms
    from drake_skills.systems.trajectory_source import blend_plan

    traj = _moving_traj()
    first = build_plan(traj, traj.mean[0], LOWER, UPPER)
    q0, v0, _ = desired_at(first, HOME, 1.5)
    for plan in (first, blend_plan(traj, 1.5, q0, v0, LOWER, UPPER)):
        end = plan.end_time
        np.testing.assert_allclose(desired_at(plan, HOME, end)[0], traj.mean[-1], atol=1e-9)  # the handover pose
        np.testing.assert_allclose(desired_at(plan, HOME, end - 1e-6)[1], 0.0, atol=1e-4)
        # 0.4 rad/s over the trajectory: slowing to rest in 0.5 s takes ~1.2 rad/s^2, not 0.2 / 0.04 s
        assert max(_accel(plan, t) for t in np.linspace(end - 0.05, end - 1e-6, 50)) < 0.5
        assert max(_accel(plan, t) for t in np.linspace(plan.start_time, end, 400)) < 2.5
    assert max(_accel(first, t) for t in np.linspace(1.0, 1.05, 50)) < 0.5   # and it starts gently


def test_the_first_plan_starts_when_the_source_sees_it_from_rest_without_a_jump():
    # the conditioner stamps its start at its own update; the source sees it up to 1/64 s later
    source = JointTrajectorySource(LOWER, UPPER, HOME)
    ctx = source.CreateDefaultContext()
    source.GetInputPort("measured_state").FixValue(ctx, np.concatenate([HOME, np.zeros(7)]))
    source.GetInputPort("robot_trajectory").FixValue(ctx, _moving_traj(start_time=1.0))
    scratch = ctx.Clone()
    ctx.SetTime(1.0 + 1.0 / 64.0)
    source.CalcForcedUnrestrictedUpdate(ctx, scratch.get_mutable_state())
    ctx.SetAbstractState(0, scratch.get_abstract_state(0).get_value())
    plan = source.plan(ctx)
    assert plan.start_time == 1.0 + 1.0 / 64.0
    q, v, _ = desired_at(plan, HOME, plan.start_time)
    np.testing.assert_allclose(q, HOME, atol=1e-12)
    np.testing.assert_allclose(v, 0.0, atol=1e-12)
    q1, _, _ = desired_at(plan, HOME, plan.start_time + 1e-3)
    assert np.abs(q1 - HOME).max() < 1e-5   # 1 ms later: no jump (it was 2.7 mrad in 0.5 ms)


def test_the_first_plan_respects_the_velocity_limits_from_a_far_pose():
    # on a real robot a trial starts where the last one left it; the first plan was not speed checked
    from drake_skills.systems.trajectory_source import peak_speed_ratio

    slow = np.full(7, 0.5)
    far = HOME + np.array([1.2, -1.0, 1.2, -0.5, 1.2, -1.0, 1.2]) * 0.8
    unlimited = build_plan(_traj(1.0), far, LOWER, UPPER)
    assert peak_speed_ratio(unlimited, slow) > 1.5
    plan = build_plan(_traj(1.0), far, LOWER, UPPER, slow)
    assert peak_speed_ratio(plan, slow) <= 1.0 + 1e-6
    assert plan.end_time > unlimited.end_time   # slowed down, same path
    np.testing.assert_allclose(desired_at(plan, HOME, plan.end_time)[0], _traj(1.0).mean[-1], atol=1e-9)
    np.testing.assert_allclose(desired_at(plan, HOME, plan.start_time)[0], far, atol=1e-9)


def test_a_replan_given_the_running_acceleration_continues_it():
    # re-plans every 1/8 s while the conditioner re-conditions: each was an acceleration (torque) step
    # of 8-10 rad/s^2 in the closed loop (cold review); with a0 the blend starts with the command's own
    from drake_skills.systems.trajectory_source import blend_plan

    first = build_plan(_traj(1.0), HOME, LOWER, UPPER)
    now = 1.6
    q0, v0, a0 = desired_at(first, HOME, now)
    assert np.abs(a0).max() > 0.5
    other = _traj(1.0, end=np.array([-0.6, 0.2, 0.5, -1.0, -0.3, 0.2, -0.4]))
    without = blend_plan(other, now, q0, v0, LOWER, UPPER, _speed_limits())
    plan = blend_plan(other, now, q0, v0, LOWER, UPPER, _speed_limits(), a0=a0)
    q1, v1, a1 = desired_at(plan, HOME, now)
    np.testing.assert_allclose(q1, q0, atol=1e-9)
    np.testing.assert_allclose(v1, v0, atol=1e-6)
    step = np.abs(a1 - a0).max()
    assert step < 0.1 * np.abs(desired_at(without, HOME, now)[2] - a0).max(), step
    assert step < 0.5, step   # rad/s^2 (measured 0.04, against 5.2 without a0)


def test_a_mean_sample_on_a_clock_boundary_gives_no_repeated_knot():
    # 2.475 s = 99 x 0.025: a one-demonstration component of 100 frames at 40 Hz; a sample within
    # rounding of 2 tail repeated a knot's time and Drake refused the spline (review of the change)
    rng = np.random.default_rng(0)
    mean = HOME + 0.5 * np.sin(np.linspace(0, 3, 100))[:, None] * rng.uniform(-1, 1, 7)
    # every duration that puts one of the 100 samples on 2 tail = 0.5 s (42 cases with 6 start times
    # repeated a knot before the fix; 2.4750000000000005 = 0.25 / (1 - 89 / 99) among them)
    durations = [0.25 / (1 - i / 99) for i in range(1, 99) if 0.25 / (1 - i / 99) > 1.667]
    for duration in durations:
        for start in (0.0, 1.0, 2.0, 5.0, 17.25, 100.0):
            traj = ConditionedTrajectory(0, mean, 0 * mean, duration, start)
            times, _ = plan_knots(traj, HOME, LOWER, UPPER, start=start)
            assert np.diff(times).min() > 1e-9, (duration, start)
    for duration in (durations[0], 0.25 / (1 - 89 / 99)):
        build_plan(ConditionedTrajectory(0, mean, 0 * mean, duration, 17.25), HOME, LOWER, UPPER, start=17.25)


def test_a_blend_slowed_down_from_a_strong_acceleration_stays_short_and_inside_the_limits():
    # the acceleration bump's velocity grows with the stretch: with a0 >= 4 rad/s^2 the loop ran to
    # a 240 s plan 0.28 rad past the joint limits; a slowed-down blend now drops the bump
    from drake_skills.systems.trajectory_source import blend_plan, peak_speed_ratio

    lower, upper = np.radians([-170, -120, -170, -120, -170, -120, -175]), np.radians([170, 120, 170, 120, 170, 120, 175])
    vmax = np.radians([85, 85, 100, 75, 130, 135, 135])
    q0 = HOME.copy()
    s = np.linspace(0, 1, 60)[:, None]
    traj = ConditionedTrajectory(0, q0 + 1.5 * s, 0 * (q0 + s), 1.0, 0.0)   # faster than vmax: stretched
    plan = blend_plan(traj, 0.5, q0, 0.8 * vmax, lower, upper, vmax, a0=np.full(7, 10.0))
    assert plan.end_time - 0.5 < 5.0
    assert peak_speed_ratio(plan, vmax) <= 1.0 + 1e-6
    qs = plan.q.vector_values(np.linspace(plan.start_time, plan.end_time, 5000))
    assert (qs <= upper[:, None] + 1e-9).all() and (qs >= lower[:, None] - 1e-9).all()


def test_the_first_plan_starts_exactly_at_a_hold_pose_inside_the_margin():
    near = HOME.copy()
    near[1] = UPPER[1] - 0.005   # inside the 0.02 margin: the first knot was clipped (a 0.015 rad step)
    plan = build_plan(_traj(1.0), near, LOWER, UPPER)
    q, v, _ = desired_at(plan, HOME, plan.start_time)
    np.testing.assert_allclose(q, near, atol=1e-12)
    np.testing.assert_allclose(v, 0.0, atol=1e-12)
