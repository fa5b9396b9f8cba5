"""The controller as a Diagram that talks to the world only over LCM.

::

    IIWA_STATUS ─▶ LcmSubscriberSystem ─▶ IiwaStatusReceiver
                   (lcmt_iiwa_status)          │ q, v, time
                                               ▼
                                         IiwaCommandGuard ── measured_state [q; v] ──▶ add_controller(...)
                                               ▲      │                              (normalizer, gating,
    DRAKE_SKILLS_WRIST ─▶ LcmSubscriberSystem ─┼─▶ WristSignalReceiver ── wrist ──▶  conditioner, trajectory
                   (lcmt_drake_signal)         │      │                               source, trial monitor)
                                               └──────┼──── desired_state ◀────────────────┘
                                                      │ position (limited; frozen on a stale status)
    IIWA_COMMAND ◀── LcmPublisherSystem ◀── IiwaCommandSender (position only)
                   (lcmt_iiwa_command, every command_period)

The decision logic is :func:`drake_skills.sim.controller.add_controller`, the same as in
the direct simulation; the robot runs its own joint controller on the position
command (there is no inverse-dynamics controller here). Channel names, periods and
the stale timeout are ``SimConfig.lcm`` (:class:`~drake_skills.sim.lcm_config.LcmConfig`).

Trials: the controller's trial systems (``ControllerHandles.trial_systems``) are reset
by :func:`start_trial` when the trial monitor says a trial is over; the LCM
subscribers and the guard keep their state, so the command continues from where the
robot is. :class:`ControllerRunner` does that in a loop (``drake-skills control``).
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np
from drake import lcmt_drake_signal, lcmt_iiwa_command, lcmt_iiwa_status
from pydrake.lcm import DrakeLcm, DrakeLcmInterface
from pydrake.manipulation import IiwaCommandSender, IiwaControlMode, IiwaStatusReceiver
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from pydrake.systems.lcm import LcmInterfaceSystem, LcmPublisherSystem, LcmSubscriberSystem

from drake_skills.data.workspace import Workspace
from drake_skills.library.incremental import SkillLibrary
from drake_skills.sim.config import SimConfig
from drake_skills.sim.controller import ControllerHandles, add_controller
from drake_skills.sim.models import IIWA7_JOINT_LIMITS, IIWA7_VELOCITY_LIMITS, load_scene_config
from drake_skills.systems.iiwa_guard import GuardLimits, IiwaCommandGuard, status_received
from drake_skills.systems.wrist_receiver import WristSignalReceiver

log = logging.getLogger(__name__)


@dataclass
class LcmControllerHandles:
    """The systems of the LCM controller."""

    controller: ControllerHandles
    guard: IiwaCommandGuard
    status_subscriber: LcmSubscriberSystem
    status_receiver: IiwaStatusReceiver
    wrist_subscriber: LcmSubscriberSystem
    wrist_receiver: WristSignalReceiver
    command_sender: IiwaCommandSender
    command_publisher: LcmPublisherSystem
    lcm: DrakeLcmInterface
    #: (channel, message type name) of each subscriber, in the order of :attr:`subscribers`.
    subscribed: tuple[tuple[str, str], ...] = ()

    @property
    def subscribers(self) -> tuple[LcmSubscriberSystem, ...]:
        return (self.status_subscriber, self.wrist_subscriber)


def guard_limits(config: SimConfig) -> GuardLimits:
    """The IIWA7's joint position and speed limits, at the command period and stale timeout of ``config.lcm``."""
    lower, upper = IIWA7_JOINT_LIMITS
    return GuardLimits(lower, upper, IIWA7_VELOCITY_LIMITS, period=config.lcm.command_period,
                       stale_timeout=config.lcm.stale_timeout)


def add_lcm_controller(builder: DiagramBuilder, config: SimConfig, *, library: SkillLibrary, workspace: Workspace,
                       lcm: DrakeLcmInterface, X_WB: RigidTransform) -> LcmControllerHandles:
    """Add the controller with its LCM ends to ``builder`` (the caller adds the ``LcmInterfaceSystem``).

    Parameters
    ----------
    builder : DiagramBuilder
    config : SimConfig
    library : SkillLibrary
    workspace : Workspace
        The subject's workspace (Eq. 14).
    lcm : DrakeLcmInterface
    X_WB : RigidTransform
        Pose of the robot base in the frame of the wrist messages.

    Notes
    -----
    The controller's initialization latches the hold pose and the wrist's start
    from the subscribers' messages, so they must be in the context before it runs
    (:func:`receive_first_messages`, or the station's priming in the demo):
    initializing without a status is an error, never a command to zero.
    """
    cfg = config.lcm
    ctrl = add_controller(builder, config, library=library, workspace=workspace, X_WB=X_WB, inverse_dynamics=False,
                          timestamped_wrist=True)
    status_sub = builder.AddSystem(LcmSubscriberSystem.Make(cfg.status_channel, lcmt_iiwa_status, lcm,
                                                            use_cpp_serializer=True))
    status_sub.set_name("controller_status_subscriber")
    status = builder.AddSystem(IiwaStatusReceiver())
    status.set_name("iiwa_status_receiver")
    wrist_sub = builder.AddSystem(LcmSubscriberSystem.Make(cfg.wrist_channel, lcmt_drake_signal, lcm))
    wrist_sub.set_name("controller_wrist_subscriber")
    guard = builder.AddSystem(IiwaCommandGuard(guard_limits(config), channel=cfg.status_channel))
    guard.set_name("iiwa_command_guard")
    receiver = builder.AddSystem(WristSignalReceiver(channel=cfg.wrist_channel))
    receiver.set_name("wrist_signal_receiver")
    n = guard.limits.n
    sender = builder.AddSystem(IiwaCommandSender(n, IiwaControlMode.kPositionOnly))
    sender.set_name("iiwa_command_sender")
    command_pub = builder.AddSystem(LcmPublisherSystem.Make(cfg.command_channel, lcmt_iiwa_command, lcm,
                                                            cfg.command_period, use_cpp_serializer=True))
    command_pub.set_name("controller_command_publisher")

    builder.Connect(status_sub.get_output_port(), status.get_input_port())
    for port in ("position_measured", "velocity_estimated"):
        builder.Connect(status.GetOutputPort(port), guard.GetInputPort(port))
    builder.Connect(status.GetOutputPort("time_measured"), guard.GetInputPort("status_time"))
    builder.Connect(wrist_sub.get_output_port(), receiver.GetInputPort("lcmt_drake_signal"))
    ctrl.connect_wrist(builder, receiver.GetOutputPort("human_wrist"), receiver.GetOutputPort("wrist_time"))
    ctrl.connect_measured_state(builder, guard.GetOutputPort("measured_state"))
    builder.Connect(ctrl.desired_state, guard.GetInputPort("desired_state"))
    builder.Connect(guard.GetOutputPort("position"), sender.GetInputPort("position"))
    builder.Connect(sender.get_output_port(), command_pub.get_input_port())
    return LcmControllerHandles(ctrl, guard, status_sub, status, wrist_sub, receiver, sender, command_pub, lcm,
                                ((cfg.status_channel, "lcmt_iiwa_status"), (cfg.wrist_channel, "lcmt_drake_signal")))


def build_lcm_controller(config: SimConfig, *, library: SkillLibrary, workspace: Workspace,
                         lcm: DrakeLcmInterface | None = None, X_WB: RigidTransform | None = None
                         ) -> tuple[Diagram, LcmControllerHandles]:
    """The controller alone, for a real robot (``drake-skills control``) or a station elsewhere.

    Parameters
    ----------
    lcm : DrakeLcmInterface, optional
        Default: ``DrakeLcm(config.lcm.url)``.
    X_WB : RigidTransform, optional
        Default: the robot base of the salad scene (``models/salad/scene.yaml``).
    """
    lcm = lcm if lcm is not None else DrakeLcm(config.lcm.url)
    X_WB = X_WB if X_WB is not None else load_scene_config().robot_base.transform()
    builder = DiagramBuilder()
    builder.AddSystem(LcmInterfaceSystem(lcm)).set_name("lcm_interface")
    handles = add_lcm_controller(builder, config, library=library, workspace=workspace, lcm=lcm, X_WB=X_WB)
    diagram = builder.Build()
    diagram.set_name("drake_skills_lcm_controller")
    return diagram, handles


def deliver_received(subscribers, root_context: Context) -> None:
    """Copy each subscriber's newest received message into its state in ``root_context`` now."""
    for sub in subscribers:
        sub.ExecuteForcedEvents(sub.GetMyMutableContextFromRoot(root_context), publish=False)


def receive_first_messages(handles: LcmControllerHandles, root_context: Context, timeout: float) -> None:
    """Pump the bus until every subscriber of the controller has a message (at most ``timeout`` s, wall clock).

    Raises
    ------
    TimeoutError
        Naming the channels that stayed silent and the bus URL.
    """
    deadline = time.monotonic() + timeout
    waiting = list(zip(handles.subscribers, handles.subscribed))
    while True:
        waiting = [(s, c) for s, c in waiting if s.WaitForMessage(0, None, 1e-4) < 1]
        if not waiting:
            deliver_received(handles.subscribers, root_context)
            if _status_is_good(handles, root_context):
                return
            # the newest status has non-finite positions: no hold pose to latch from it; wait for the next
        if time.monotonic() >= deadline:
            break
        handles.lcm.HandleSubscriptions(20)
    if waiting:
        names = ", ".join(f"'{channel}' ({kind})" for _, (channel, kind) in waiting)
        raise TimeoutError(f"no message within {timeout:g} s on {names} of {handles.lcm.get_lcm_url()}: are the "
                           f"robot driver (or a simulated station) and the wrist tracker publishing there?")
    raise TimeoutError(f"no status with finite joint positions within {timeout:g} s on '{handles.subscribed[0][0]}' "
                       f"of {handles.lcm.get_lcm_url()} (the ones received had NaN or inf positions)")


def _status_is_good(handles: LcmControllerHandles, root_context: Context) -> bool:
    """Does the newest status delivered to the guard have finite positions (:func:`status_received`)?"""
    g = handles.guard
    ctx = g.GetMyContextFromRoot(root_context)
    q = np.asarray(g.GetInputPort("position_measured").Eval(ctx))
    return status_received(q, float(g.GetInputPort("status_time").Eval(ctx)[0]))


def start_trial(root_context: Context, handles: ControllerHandles) -> None:
    """Reset the controller's trial systems in ``root_context``; the caller then initializes the simulator.

    The LCM subscribers and the command guard are left as they are, so the next
    trial latches its hold pose from the newest status and the command continues
    from where it was.
    """
    for system in handles.trial_systems:
        system.SetDefaultContext(system.GetMyMutableContextFromRoot(root_context))


@dataclass
class ControlTrial:
    """One trial of :class:`ControllerRunner`."""

    #: 0-based index.
    trial: int
    #: "skill <id>", "unknown", or "pending" (the run stopped before a decision).
    decision: str
    #: Chosen component id (None for unknown or pending).
    component: int | None
    #: Controller time of the trial start and of the decision (s; NaN if none).
    start_time: float
    decision_time: float
    end_time: float
    #: The command guard froze the command (stale status) during the trial.
    held_for_stale_status: bool
    responsibilities: dict = field(default_factory=dict)


class ControllerRunner:
    """Runs the LCM controller trial after trial: observe, decide, execute or hold, start over.

    Parameters
    ----------
    diagram : Diagram
        From :func:`build_lcm_controller`.
    handles : LcmControllerHandles
    config : SimConfig
        ``log_period`` is the granularity at which a trial's end is noticed.
    realtime_rate : float
        1.0 on a real robot (the simulator's clock paced to the wall clock); 0 runs as fast as possible.
    """

    def __init__(self, diagram: Diagram, handles: LcmControllerHandles, config: SimConfig, *,
                 realtime_rate: float = 1.0):
        self.diagram, self.handles, self.config = diagram, handles, config
        self.simulator = Simulator(diagram)
        self.simulator.set_target_realtime_rate(realtime_rate)
        self.context = self.simulator.get_mutable_context()
        self.trials: list[ControlTrial] = []
        self._started = False
        self._trial_start = 0.0
        self._stale_events0 = 0

    @property
    def time(self) -> float:
        return self.context.get_time()

    def _guard_state(self):
        g = self.handles.guard
        return g.guard_state(g.GetMyContextFromRoot(self.context))

    def _record(self, t_end: float) -> ControlTrial:
        c = self.handles.controller
        decision = c.gating.decision(c.gating.GetMyContextFromRoot(self.context))
        what = decision.status if decision.status != "skill" else f"skill {decision.component}"
        trial = ControlTrial(len(self.trials), what, decision.component, self._trial_start,
                             float(decision.time) if decision.decided else math.nan, t_end,
                             self._guard_state().stale_events > self._stale_events0,
                             dict(decision.responsibilities))
        self.trials.append(trial)
        return trial

    def start(self) -> None:
        """Wait (up to ``config.lcm.wait_for_messages`` s) for the first status and wrist messages, then initialize."""
        receive_first_messages(self.handles, self.context, self.config.lcm.wait_for_messages)
        self.simulator.Initialize()
        self._started = True
        self._trial_start = self.time
        self._stale_events0 = self._guard_state().stale_events

    def advance_to(self, t: float) -> list[ControlTrial]:
        """Run until controller time ``t``; returns the trials that ended meanwhile."""
        if not self._started:
            self.start()
        c = self.handles.controller
        status_port, monitor_ctx = c.trial_status, c.trial_monitor.GetMyContextFromRoot(self.context)
        done = []
        while self.time < t - 1e-12:
            self.simulator.AdvanceTo(min(self.time + self.config.log_period, t))
            status = status_port.Eval(monitor_ctx)
            if status.done(self.time):
                trial = self._record(self.time)
                log.info("trial %d: %s (decided at %.2f s)", trial.trial, trial.decision, trial.decision_time)
                done.append(trial)
                start_trial(self.context, c)
                self.simulator.Initialize()
                self._trial_start = self.time
                self._stale_events0 = self._guard_state().stale_events
        return done

    def stop(self) -> ControlTrial | None:
        """Record the unfinished trial (if it has started) and return it."""
        if not self._started:
            return None
        return self._record(self.time)


def commanded_positions(handles: LcmControllerHandles, root_context: Context) -> np.ndarray:
    """The guard's current position command (7,) in ``root_context``."""
    g = handles.guard
    return np.array(g.GetOutputPort("position").Eval(g.GetMyContextFromRoot(root_context)))
