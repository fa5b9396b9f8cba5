"""``build_diagram``: the skill library as a controller of a simulated IIWA7 in the salad scene.

::

    HumanWristSource ─▶ WorkspaceNormalizer ─▶ SkillGating ─▶ InteractionProMPConditioner
                                                  │ decision           │ robot_trajectory, conditioning
                                                  └─▶ TrialMonitor ◀───┤  (trial_status: phase, end time)
    plant state ─▶ JointTrajectorySource ◀─────────────────────────────┘
                        │ desired state, acceleration
                        ▼
               InverseDynamicsController ─▶ MultibodyPlant (IIWA7 + scene) ─▶ MeshcatVisualizer
                  (own iiwa-only plant)

The wrist is normalized once (Eq. 14, in the normalizer, as the library's config
asks); the gating and the conditioner hand the normalized samples to the library,
which only resamples them. The decision travels as a
:class:`~drake_skills.systems.gating.GatingDecision` (the component id an int), and
the end of a trial is the ``trial_status`` output of the
:class:`~drake_skills.systems.trial_monitor.TrialMonitor`.

The person is never a body of the plant: the wrist is drawn in meshcat by
:class:`~drake_skills.sim.wrist_marker.WristMarker`.  This module is the only
place that calls ``Connect`` for the direct Diagram; the controller's own wiring is
:func:`drake_skills.sim.controller.add_controller`, shared with the LCM controller.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import (CollisionFilterDeclaration, GeometrySet, Meshcat, MeshcatParams, Role, SceneGraph)
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, MultibodyPlant
from pydrake.multibody.tree import BodyIndex, Frame, ModelInstanceIndex
from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import Diagram, DiagramBuilder, OutputPort
from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams

from drake_skills.library.incremental import SkillLibrary
from drake_skills.data.workspace import Workspace
from drake_skills.sim.config import SimConfig
from drake_skills.sim.controller import add_controller
from drake_skills.sim.models import FLANGE_FRAME, HOME_Q, SceneConfig, add_salad_scene, load_scene_config
from drake_skills.sim.wrist_marker import WristMarker
from drake_skills.systems.conditioner import InteractionProMPConditioner
from drake_skills.systems.gating import SkillGating
from drake_skills.systems.normalizer import WorkspaceNormalizer
from drake_skills.systems.trajectory_source import JointTrajectorySource
from drake_skills.systems.trial_monitor import TrialMonitor
from drake_skills.systems.wrist_source import HumanWristSource


@dataclass
class DiagramHandles:
    """The systems of the diagram a caller needs to reach into its context."""

    plant: MultibodyPlant
    scene_graph: SceneGraph
    #: The IIWA7 model instance of ``plant``.
    iiwa: ModelInstanceIndex
    #: Its tool flange frame E.
    flange: Frame
    #: The iiwa-only plant of the controller.
    controller_plant: MultibodyPlant
    controller: InverseDynamicsController
    wrist_source: HumanWristSource
    normalizer: WorkspaceNormalizer
    gating: SkillGating
    conditioner: InteractionProMPConditioner
    trajectory_source: JointTrajectorySource
    trial_monitor: TrialMonitor
    visualizer: MeshcatVisualizer | None = None
    wrist_marker: WristMarker | None = None
    meshcat: Meshcat | None = None


def make_meshcat() -> Meshcat:
    """A Meshcat server on localhost only (first free port from 7000)."""
    return Meshcat(MeshcatParams(host="localhost", port=None))


def _filter_robot_contact(plant: MultibodyPlant, scene_graph: SceneGraph, iiwa: ModelInstanceIndex, *,
                          with_scene: bool) -> None:
    """No contact among the robot's own links and, unless ``with_scene``, with the welded scene.

    The primitive geometry of links two apart (e.g. 5 and 7) overlaps at
    ordinary poses, and Drake only filters parent-child pairs; the
    demonstrations' inverse kinematics does not avoid the objects either.
    """
    robot = GeometrySet()
    scene = GeometrySet()
    for body_index in range(plant.num_bodies()):
        body = plant.get_body(BodyIndex(body_index))
        ids = plant.GetCollisionGeometriesForBody(body)
        if not ids:
            continue
        (robot if body.model_instance() == iiwa else scene).Add(ids)
    declaration = CollisionFilterDeclaration().ExcludeWithin(robot)
    if not with_scene:
        declaration.ExcludeBetween(robot, scene)
    scene_graph.collision_filter_manager().Apply(declaration)


def add_salad_plant(builder: DiagramBuilder, config: SimConfig) -> tuple[MultibodyPlant, SceneGraph,
                                                                          ModelInstanceIndex, SceneConfig]:
    """Add the discrete MultibodyPlant with the IIWA7 (at ``HOME_Q``) in the salad scene.

    Returns
    -------
    plant, scene_graph, iiwa, scene
        ``scene`` is the :class:`~drake_skills.sim.models.SceneConfig` it was built from.
    """
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=config.time_step)
    scene = load_scene_config()
    models = add_salad_scene(plant, Parser(plant), scene)
    iiwa = models["iiwa"]
    plant.Finalize()
    plant.SetDefaultPositions(iiwa, HOME_Q)
    _filter_robot_contact(plant, scene_graph, iiwa, with_scene=config.robot_scene_contact)
    return plant, scene_graph, iiwa, scene


def add_visualization(builder: DiagramBuilder, config: SimConfig, scene_graph: SceneGraph, meshcat: Meshcat,
                      scene: SceneConfig, *, wrist: OutputPort, decision: OutputPort
                      ) -> tuple[MeshcatVisualizer, WristMarker]:
    """Draw the scene, the wrist (from ``wrist``, p_WH) and the decision colour (from ``decision``) in meshcat."""
    params = MeshcatVisualizerParams()
    params.publish_period = config.meshcat.publish_period
    params.role = Role.kIllustration
    params.delete_on_initialization_event = False  # one diagram, many trials, one recording
    visualizer = MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, params)
    meshcat.SetCameraPose(np.asarray(config.meshcat.camera_position, float),
                          np.asarray(config.meshcat.camera_target, float))
    marker = builder.AddSystem(WristMarker(meshcat, config.meshcat.publish_period, config.meshcat.wrist_radius,
                                           p_WL=scene.robot_base.transform().translation() + [0, 0.25, 0.75]))
    marker.set_name("wrist_marker")
    builder.Connect(wrist, marker.GetInputPort("human_wrist"))
    builder.Connect(decision, marker.GetInputPort("decision"))
    return visualizer, marker


def configure_simulator(simulator: Simulator, config: SimConfig) -> Simulator:
    """Give ``simulator`` the integrator of ``config.integrator`` (:class:`~drake_skills.sim.config.SimConfig`).

    The Diagram's continuous state is the controller's PID integral (and, over LCM, the simulated
    driver's torque filter); the plant is discrete. "explicit_euler" and "runge_kutta2" integrate it
    in fixed steps of ``config.time_step``; "drake_default" leaves Drake's error-controlled
    integrator, which evaluates the controller about three times per plant step. Returns ``simulator``.
    """
    if config.integrator != "drake_default":
        ResetIntegratorFromFlags(simulator, config.integrator, config.time_step)
    return simulator


def build_diagram(config: SimConfig, *, library: SkillLibrary, workspace: Workspace,
                  meshcat: Meshcat | None = None) -> tuple[Diagram, DiagramHandles]:
    """Build the closed loop: replayed wrist -> skill library -> controller -> IIWA7 plant.

    Parameters
    ----------
    config : SimConfig
    library : SkillLibrary
        Read at every decision, so teaching it between trials needs no rebuild.
    workspace : Workspace
        The subject's workspace (Eq. 14).
    meshcat : Meshcat, optional
        Draw the scene, the wrist and the decision colour.

    Returns
    -------
    diagram : Diagram
    handles : DiagramHandles

    A ``Simulator`` of your own gets Drake's default integrator: pass it to
    :func:`configure_simulator` for ``config.integrator`` (what ``CollaborationSim`` does).
    """
    builder = DiagramBuilder()
    plant, scene_graph, iiwa, scene = add_salad_plant(builder, config)
    wrist = builder.AddSystem(HumanWristSource())
    wrist.set_name("human_wrist_source")
    ctrl = add_controller(builder, config, library=library, workspace=workspace, X_WB=scene.robot_base.transform(),
                          timestamped_wrist=True)
    ctrl.connect_wrist(builder, wrist.GetOutputPort("human_wrist"), wrist.GetOutputPort("wrist_time"))
    ctrl.connect_measured_state(builder, plant.get_state_output_port(iiwa))
    builder.Connect(ctrl.actuation, plant.get_actuation_input_port(iiwa))

    visualizer = marker = None
    if meshcat is not None:
        visualizer, marker = add_visualization(builder, config, scene_graph, meshcat, scene,
                                               wrist=wrist.GetOutputPort("human_wrist"), decision=ctrl.decision)

    diagram = builder.Build()
    diagram.set_name("drake_skills_collaboration")
    handles = DiagramHandles(plant, scene_graph, iiwa, plant.GetFrameByName(FLANGE_FRAME, iiwa),
                             ctrl.controller_plant, ctrl.controller, wrist, ctrl.normalizer, ctrl.gating,
                             ctrl.conditioner, ctrl.trajectory_source, ctrl.trial_monitor, visualizer, marker, meshcat)
    return diagram, handles
