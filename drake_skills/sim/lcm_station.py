"""``add_station``: a simulated stand-in for the hardware, speaking the iiwa driver's LCM messages.

::

    IIWA_COMMAND ─▶ LcmSubscriberSystem ─▶ IiwaCommandReceiver ─▶ SimIiwaDriver ─▶ MultibodyPlant (IIWA7 + scene)
                    (lcmt_iiwa_command)      (position only)     (inverse dynamics     │
                                                                  on position commands) │ state
    IIWA_STATUS ◀── LcmPublisherSystem ◀── IiwaStatusSender ◀──────────────────────────┘
                    (lcmt_iiwa_status, every status_period)
    DRAKE_SKILLS_WRIST ◀── LcmPublisherSystem ◀── WristSignalSender ◀── HumanWristSource (replayed person)
                    (lcmt_drake_signal, every wrist_period)

This is Drake's ``BuildIiwaControl`` wiring (the same pydrake systems, the same
sign convention for torques in the status), built by hand so that the channel
names follow ``SimConfig.lcm`` (``BuildIiwaControl`` fixes them to ``IIWA_*``).
The robot runs in position mode, as ``DrakeFRIPositionDriver`` does on a real iiwa:
the commanded positions are differentiated into desired velocities (5 ms) and
tracked by an inverse-dynamics controller with the gains of ``SimConfig.controller``
(kp; kd = 2 sqrt(kp), ki = 1, the driver's choices, which are also our defaults).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from drake import lcmt_drake_signal, lcmt_iiwa_command, lcmt_iiwa_status
from pydrake.geometry import SceneGraph
from pydrake.lcm import DrakeLcmInterface
from pydrake.manipulation import IiwaCommandReceiver, IiwaControlMode, IiwaDriver, IiwaStatusSender, SimIiwaDriver
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.lcm import LcmPublisherSystem, LcmSubscriberSystem
from pydrake.systems.primitives import Demultiplexer, Gain

from drake_skills.sim.config import SimConfig
from drake_skills.sim.diagram import add_salad_plant
from drake_skills.sim.models import SceneConfig, make_iiwa7_plant
from drake_skills.systems.wrist_sender import WristSignalSender
from drake_skills.systems.wrist_source import HumanWristSource


@dataclass
class StationChannels:
    """The channel names the station speaks on."""

    status: str
    command: str
    wrist: str


@dataclass
class StationHandles:
    """The systems of the simulated station."""

    plant: MultibodyPlant
    scene_graph: SceneGraph
    iiwa: ModelInstanceIndex
    scene: SceneConfig
    #: The robot's own model in its driver (welded at the base).
    driver_plant: MultibodyPlant
    wrist_source: HumanWristSource
    command_subscriber: LcmSubscriberSystem
    command_receiver: IiwaCommandReceiver
    driver: SimIiwaDriver
    status_publisher: LcmPublisherSystem
    wrist_publisher: LcmPublisherSystem
    channels: StationChannels


def hold_command(q: np.ndarray, time: float) -> lcmt_iiwa_command:
    """A position-only ``lcmt_iiwa_command`` for joint positions ``q`` (rad) at ``time`` (s)."""
    msg = lcmt_iiwa_command()
    msg.utime = int(round(1e6 * time))
    msg.num_joints = len(q)
    msg.joint_position = [float(x) for x in q]
    msg.num_torques = 0
    msg.joint_torque = []
    return msg


def add_station(builder: DiagramBuilder, config: SimConfig, lcm: DrakeLcmInterface,
                channels: StationChannels | None = None) -> StationHandles:
    """Add the IIWA7 in the salad scene, its simulated driver and the simulated person's tracker.

    Parameters
    ----------
    builder : DiagramBuilder
    config : SimConfig
        ``time_step``, ``controller.kp``, ``lcm`` (periods, default channels).
    lcm : DrakeLcmInterface
        The bus; the caller adds an ``LcmInterfaceSystem`` for it to the builder.
    channels : StationChannels, optional
        Default: the channels of ``config.lcm``.

    Returns
    -------
    StationHandles
    """
    cfg = config.lcm
    channels = channels or StationChannels(cfg.status_channel, cfg.command_channel, cfg.wrist_channel)
    plant, scene_graph, iiwa, scene = add_salad_plant(builder, config)
    driver_plant = make_iiwa7_plant(scene.robot_base.transform())
    n = driver_plant.num_positions()

    driver_config = IiwaDriver()
    driver_config.control_mode = "position_only"
    driver_config.desired_kp_gains = np.full(n, config.controller.kp)
    driver_config.lcm_status_period = cfg.status_period
    driver = SimIiwaDriver.AddToBuilder(builder, plant, iiwa, driver_config, driver_plant)

    command_sub = builder.AddSystem(LcmSubscriberSystem.Make(channels.command, lcmt_iiwa_command, lcm,
                                                             use_cpp_serializer=True))
    command_sub.set_name("station_command_subscriber")
    receiver = builder.AddSystem(IiwaCommandReceiver(n, IiwaControlMode.kPositionOnly))
    receiver.set_name("iiwa_command_receiver")
    demux = builder.AddSystem(Demultiplexer(2 * n, n))
    builder.Connect(command_sub.get_output_port(), receiver.get_message_input_port())
    builder.Connect(plant.get_state_output_port(iiwa), demux.get_input_port())
    builder.Connect(demux.get_output_port(0), receiver.get_position_measured_input_port())
    builder.Connect(receiver.get_commanded_position_output_port(), driver.GetInputPort("position"))

    status_sender = builder.AddSystem(IiwaStatusSender(n))
    status_sender.set_name("iiwa_status_sender")
    status_pub = builder.AddSystem(LcmPublisherSystem.Make(channels.status, lcmt_iiwa_status, lcm,
                                                           cfg.status_period, use_cpp_serializer=True))
    status_pub.set_name("station_status_publisher")
    builder.Connect(status_sender.get_output_port(), status_pub.get_input_port())
    for port in ("position_commanded", "position_measured", "velocity_estimated", "torque_external"):
        builder.Connect(driver.GetOutputPort(port), status_sender.GetInputPort(port))
    for port in ("torque_commanded", "torque_measured"):  # the iiwa reports torques with the other sign
        flip = builder.AddSystem(Gain(-1.0, n))
        builder.Connect(driver.GetOutputPort(port), flip.get_input_port())
        builder.Connect(flip.get_output_port(), status_sender.GetInputPort(port))

    wrist = builder.AddSystem(HumanWristSource())
    wrist.set_name("human_wrist_source")
    sender = builder.AddSystem(WristSignalSender())
    sender.set_name("wrist_signal_sender")
    wrist_pub = builder.AddSystem(LcmPublisherSystem.Make(channels.wrist, lcmt_drake_signal, lcm, cfg.wrist_period))
    wrist_pub.set_name("station_wrist_publisher")
    builder.Connect(wrist.GetOutputPort("human_wrist"), sender.GetInputPort("human_wrist"))
    builder.Connect(sender.GetOutputPort("lcmt_drake_signal"), wrist_pub.get_input_port())
    return StationHandles(plant, scene_graph, iiwa, scene, driver_plant, wrist, command_sub, receiver, driver,
                          status_pub, wrist_pub, channels)
