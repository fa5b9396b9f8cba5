"""``add_controller``: the skill-library controller, wired once for every Diagram that runs it.

::

    human_wrist ─▶ WorkspaceNormalizer ─▶ SkillGating ─▶ InteractionProMPConditioner
                                              │ decision        │ robot_trajectory, conditioning
                                              └─▶ TrialMonitor ◀┤  (trial_status)
    measured_state ─▶ JointTrajectorySource ◀───────────────────┘
           │               │ desired_state, desired_acceleration
           └──────────▶ InverseDynamicsController (optional) ─▶ actuation

The direct simulation (:func:`drake_skills.sim.diagram.build_diagram`) feeds it the
replayed wrist and the plant's state and sends ``actuation`` to the plant; the LCM
controller (:mod:`drake_skills.sim.lcm_controller`) feeds it received messages and
sends ``desired_state`` to the robot as a position command. Both call this function,
so the decision logic is the same object graph in both.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import DiagramBuilder, InputPort, OutputPort

from drake_skills.data.workspace import Workspace
from drake_skills.library.incremental import SkillLibrary
from drake_skills.sim.config import SimConfig
from drake_skills.sim.models import HOME_Q, IIWA7_JOINT_LIMITS, IIWA7_VELOCITY_LIMITS, make_iiwa7_plant
from drake_skills.systems.conditioner import InteractionProMPConditioner
from drake_skills.systems.gating import SkillGating
from drake_skills.systems.normalizer import WorkspaceNormalizer
from drake_skills.systems.trajectory_source import JointTrajectorySource
from drake_skills.systems.trial_monitor import TrialMonitor


@dataclass
class ControllerHandles:
    """The controller's systems and its named inputs and outputs.

    Inputs are tuples of ports because one signal feeds several systems; connect
    them with :meth:`connect_wrist` and :meth:`connect_measured_state`.
    """

    #: The iiwa-only plant of the inverse-dynamics controller (and of forward kinematics).
    controller_plant: MultibodyPlant
    normalizer: WorkspaceNormalizer
    gating: SkillGating
    conditioner: InteractionProMPConditioner
    trajectory_source: JointTrajectorySource
    trial_monitor: TrialMonitor
    #: None when built with ``inverse_dynamics=False`` (the robot runs its own joint controller).
    controller: InverseDynamicsController | None
    #: p_WH (3,) in metres, world frame.
    wrist_inputs: tuple[InputPort, ...]
    #: [q; v] (14,) of the IIWA7, radians and rad/s.
    measured_state_inputs: tuple[InputPort, ...]
    #: [q; v] (14,) the robot should follow.
    desired_state: OutputPort
    #: (7,) rad/s^2.
    desired_acceleration: OutputPort
    #: Joint torques (7,) of the inverse-dynamics controller (None without it).
    actuation: OutputPort | None
    #: The gating's ``GatingDecision``.
    decision: OutputPort
    #: The trial monitor's ``TrialStatus``.
    trial_status: OutputPort

    @property
    def trial_systems(self) -> tuple:
        """The systems whose state is one trial's (a context reset of them starts a new trial)."""
        systems = (self.normalizer, self.gating, self.conditioner, self.trajectory_source, self.trial_monitor)
        return systems + ((self.controller,) if self.controller is not None else ())

    def connect_wrist(self, builder: DiagramBuilder, port: OutputPort) -> None:
        """Feed the wrist position p_WH (3,) from ``port``."""
        for p in self.wrist_inputs:
            builder.Connect(port, p)

    def connect_measured_state(self, builder: DiagramBuilder, port: OutputPort) -> None:
        """Feed the measured robot state [q; v] (14,) from ``port``."""
        for p in self.measured_state_inputs:
            builder.Connect(port, p)


def add_controller(builder: DiagramBuilder, config: SimConfig, *, library: SkillLibrary, workspace: Workspace,
                   X_WB: RigidTransform, inverse_dynamics: bool = True) -> ControllerHandles:
    """Add the skill-library controller to ``builder`` and wire it inside.

    Parameters
    ----------
    builder : DiagramBuilder
    config : SimConfig
        ``decision``, ``n_steps``, ``settle_time``, ``unknown_hold_time`` and ``controller`` gains.
    library : SkillLibrary
        Read at every decision, so teaching it between trials needs no rebuild.
    workspace : Workspace
        The subject's workspace (Eq. 14).
    X_WB : RigidTransform
        Pose of the robot base in the world (the controller plant is welded there).
    inverse_dynamics : bool
        Add the inverse-dynamics controller (joint torques out); False for a robot
        that takes position commands and runs its own joint controller.

    Returns
    -------
    ControllerHandles
    """
    controller_plant = make_iiwa7_plant(X_WB)
    controller = None
    if inverse_dynamics:
        n = controller_plant.num_positions()
        gains = config.controller
        controller = builder.AddSystem(InverseDynamicsController(
            controller_plant, kp=np.full(n, gains.kp), ki=np.full(n, gains.ki), kd=np.full(n, gains.kd),
            has_reference_acceleration=True))
        controller.set_name("inverse_dynamics_controller")

    lower, upper = IIWA7_JOINT_LIMITS
    normalizer = builder.AddSystem(WorkspaceNormalizer(workspace, subtract_start=library.config.subtract_start))
    gating = builder.AddSystem(SkillGating(library, config.decision, dim=workspace.dim))
    conditioner = builder.AddSystem(InteractionProMPConditioner(library, n_steps=config.n_steps))
    source = builder.AddSystem(JointTrajectorySource(lower, upper, HOME_Q, IIWA7_VELOCITY_LIMITS))
    monitor = builder.AddSystem(TrialMonitor(settle_time=config.settle_time,
                                             unknown_hold_time=config.unknown_hold_time))
    for system, name in ((normalizer, "workspace_normalizer"), (gating, "skill_gating"),
                         (conditioner, "interaction_promp_conditioner"), (source, "joint_trajectory_source"),
                         (monitor, "trial_monitor")):
        system.set_name(name)

    builder.Connect(normalizer.GetOutputPort("normalized_wrist"), gating.GetInputPort("normalized_wrist"))
    builder.Connect(gating.GetOutputPort("decision"), conditioner.GetInputPort("decision"))
    builder.Connect(gating.GetOutputPort("decision"), monitor.GetInputPort("decision"))
    builder.Connect(conditioner.GetOutputPort("conditioning"), monitor.GetInputPort("conditioning"))
    builder.Connect(conditioner.GetOutputPort("robot_trajectory"), source.GetInputPort("robot_trajectory"))
    measured = (source.GetInputPort("measured_state"),)
    actuation = None
    if controller is not None:
        builder.Connect(source.GetOutputPort("desired_state"), controller.get_input_port_desired_state())
        builder.Connect(source.GetOutputPort("desired_acceleration"),
                        controller.get_input_port_desired_acceleration())
        measured += (controller.get_input_port_estimated_state(),)
        actuation = controller.get_output_port_control()
    return ControllerHandles(controller_plant, normalizer, gating, conditioner, source, monitor, controller,
                             wrist_inputs=(normalizer.GetInputPort("human_wrist"),), measured_state_inputs=measured,
                             desired_state=source.GetOutputPort("desired_state"),
                             desired_acceleration=source.GetOutputPort("desired_acceleration"),
                             actuation=actuation, decision=gating.GetOutputPort("decision"),
                             trial_status=monitor.GetOutputPort("trial_status"))
