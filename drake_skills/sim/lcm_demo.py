"""The teaching session over LCM: the controller Diagram and the simulated station on one bus.

::

    ┌ station (drake_skills.sim.lcm_station) ┐   IIWA_STATUS          ┌ controller (drake_skills.sim.lcm_controller) ┐
    │ IIWA7 plant + scene, SimIiwaDriver,    │ ─────────────────────▶ │ guard, wrist receiver, add_controller(...),   │
    │ replayed person's wrist                │   DRAKE_SKILLS_WRIST   │ IiwaCommandSender                              │
    │                                        │ ─────────────────────▶ │                                                │
    │                                        │ ◀───────────────────── │                                                │
    └────────────────────────────────────────┘   IIWA_COMMAND         └────────────────────────────────────────────────┘
                          (optional LcmLink per channel: latency, drops)

Both halves are in one Diagram (one Simulator, one clock) and share one
``DrakeLcm`` pumped by an ``LcmInterfaceSystem``; they are connected only through
the bus, except for one drawing wire: the meshcat marker of the wrist takes its
colour from the controller's decision, so the recording looks as the direct one.
:class:`LcmCollaborationSim` runs the same trials as
:class:`~drake_skills.sim.demo.CollaborationSim`, with the same scoring.

At a trial start the simulated world is reset as in the direct simulation (the
robot at home, the person's wrist at the start of the motion) and its current
messages are put on the bus and delivered before the controller initializes: the
station's status and wrist and, standing in for the robot's own hold after it was
put back home, a command to hold the home pose.
"""
from __future__ import annotations

from dataclasses import dataclass

from pydrake.geometry import Meshcat
from pydrake.lcm import DrakeLcm
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.lcm import LcmInterfaceSystem

from drake_skills.data.demonstration import Demonstration
from drake_skills.data.workspace import Workspace
from drake_skills.library.incremental import SkillLibrary
from drake_skills.sim.config import SimConfig
from drake_skills.sim.demo import CollaborationSim
from drake_skills.sim.diagram import DiagramHandles, add_visualization
from drake_skills.sim.lcm_controller import LcmControllerHandles, add_lcm_controller, deliver_received
from drake_skills.sim.lcm_link import LcmLink
from drake_skills.sim.lcm_station import StationChannels, StationHandles, add_station, hold_command
from drake_skills.sim.models import FLANGE_FRAME, HOME_Q
from drake_skills.systems.wrist_source import WristTrial

#: Suffix of the station's channel names when links stand between it and the controller.
STATION_SUFFIX = "_STATION"


@dataclass
class LcmDiagramParts:
    """The two halves, the bus and the links of :func:`build_lcm_diagram`."""

    station: StationHandles
    controller: LcmControllerHandles
    lcm: DrakeLcm
    #: Empty on a perfect bus; else status and wrist (station -> controller), command (controller -> station).
    links: tuple[LcmLink, ...]


def build_lcm_diagram(config: SimConfig, *, library: SkillLibrary, workspace: Workspace,
                      meshcat: Meshcat | None = None, lcm: DrakeLcm | None = None
                      ) -> tuple[Diagram, DiagramHandles, LcmDiagramParts]:
    """The simulated station and the LCM controller on one bus (``config.lcm``).

    With ``config.lcm.latency`` or ``wrist_drop`` set, the station speaks on its own
    channel names (suffix :data:`STATION_SUFFIX`) and an :class:`LcmLink` per channel
    relays between them and the controller's names.

    Returns
    -------
    diagram : Diagram
    handles : DiagramHandles
        As :func:`~drake_skills.sim.diagram.build_diagram`'s (plant and wrist of the
        station, systems of the controller; ``controller`` is None: the robot's
        driver tracks the positions).
    parts : LcmDiagramParts
    """
    cfg = config.lcm
    lcm = lcm if lcm is not None else DrakeLcm(cfg.url)
    builder = DiagramBuilder()
    builder.AddSystem(LcmInterfaceSystem(lcm)).set_name("lcm_interface")
    names = StationChannels(cfg.status_channel, cfg.command_channel, cfg.wrist_channel)
    if cfg.impaired:
        names = StationChannels(*(c + STATION_SUFFIX for c in (names.status, names.command, names.wrist)))
    station = add_station(builder, config, lcm, names)
    ctrl = add_lcm_controller(builder, config, library=library, workspace=workspace, lcm=lcm,
                              X_WB=station.scene.robot_base.transform())
    links = ()
    if cfg.impaired:
        links = (LcmLink(lcm, names.status, cfg.status_channel, latency=cfg.latency, seed=config.seed),
                 LcmLink(lcm, names.wrist, cfg.wrist_channel, latency=cfg.latency, drop=cfg.wrist_drop,
                         seed=config.seed + 1),
                 LcmLink(lcm, cfg.command_channel, names.command, latency=cfg.latency, seed=config.seed + 2))
        for link in links:
            builder.AddSystem(link)
    visualizer = marker = None
    if meshcat is not None:
        visualizer, marker = add_visualization(builder, config, station.scene_graph, meshcat, station.scene,
                                               wrist=station.wrist_source.GetOutputPort("human_wrist"),
                                               decision=ctrl.controller.decision)  # drawing only
    diagram = builder.Build()
    diagram.set_name("drake_skills_collaboration_over_lcm")
    c = ctrl.controller
    handles = DiagramHandles(station.plant, station.scene_graph, station.iiwa,
                             station.plant.GetFrameByName(FLANGE_FRAME, station.iiwa), c.controller_plant, None,
                             station.wrist_source, c.normalizer, c.gating, c.conditioner, c.trajectory_source,
                             c.trial_monitor, visualizer, marker, meshcat)
    return diagram, handles, LcmDiagramParts(station, ctrl, lcm, links)


class LcmCollaborationSim(CollaborationSim):
    """:class:`~drake_skills.sim.demo.CollaborationSim` with the two halves talking over LCM.

    Parameters
    ----------
    config : SimConfig
        ``config.lcm`` sets the bus.
    library, workspace, meshcat
        As for :class:`~drake_skills.sim.demo.CollaborationSim`.
    lcm : DrakeLcm, optional
        Default: a new ``DrakeLcm(config.lcm.url)``.
    """

    def __init__(self, config: SimConfig, library: SkillLibrary, workspace: Workspace,
                 meshcat: Meshcat | None = None, *, lcm: DrakeLcm | None = None):
        self._lcm = lcm
        super().__init__(config, library, workspace, meshcat)

    def _build(self, meshcat):
        diagram, handles, self.parts = build_lcm_diagram(self.config, library=self.library,
                                                         workspace=self.workspace, meshcat=meshcat, lcm=self._lcm)
        return diagram, handles

    def _start_trial(self, demo: Demonstration, t0: float) -> None:
        h, ctx, parts = self.handles, self.context, self.parts
        station = parts.station
        self.diagram.SetDefaultContext(ctx)  # the world and the controller start over, as in the direct Diagram
        ctx.SetTime(t0)
        h.wrist_source.SetTrial(h.wrist_source.GetMyContextFromRoot(ctx), WristTrial(demo.t, demo.human, t0))
        for publisher in (station.status_publisher, station.wrist_publisher):
            publisher.ForcedPublish(publisher.GetMyContextFromRoot(ctx))
        parts.lcm.Publish(station.channels.command, hold_command(HOME_Q, t0).encode())
        parts.lcm.HandleSubscriptions(0)
        for link in parts.links:  # the command link holds the last trial's commands: forget them
            link.prime(t0, deliver_latest=link.target != station.channels.command)
        parts.lcm.HandleSubscriptions(0)
        deliver_received((station.command_subscriber,) + parts.controller.subscribers, ctx)
        self.simulator.Initialize()
