"""Model loading: the IIWA7 and the salad scene, from ``models/`` (never downloaded).

``models/package.xml`` declares the package ``drake_skills_models``; every URL here is
``package://drake_skills_models/...``. All poses of the scene (objects, robot base,
the person's seat, shoulder and resting wrist, per-task grasp poses) live in one file,
``models/salad/scene.yaml``, whose schema is :class:`SceneConfig`.

Frames (monogram notation): W world (floor, z up, table centred at the origin), B the
robot base (``iiwa_link_0``), E the flange (``iiwa_link_ee``), O an object.
"""
# No "from __future__ import annotations": yaml_load_typed reads the real field types.

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.common.yaml import yaml_load_typed
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex

#: Name of the package declared by ``models/package.xml``.
PACKAGE_NAME = "drake_skills_models"
#: URL of the KUKA LBR iiwa 7 R800 model.
IIWA7_URL = f"package://{PACKAGE_NAME}/iiwa7/iiwa7.sdf"
#: Base link (welded to the world) and tool flange frame of the IIWA7.
IIWA7_BASE_FRAME = "iiwa_link_0"
FLANGE_FRAME = "iiwa_link_ee"
IIWA7_JOINT_NAMES = tuple(f"iiwa_joint_{i}" for i in range(1, 8))
#: Joint position limits (lower, upper), shape (7,) each, radians (datasheet).
IIWA7_JOINT_LIMITS = (np.deg2rad([-170.0, -120.0, -170.0, -120.0, -170.0, -120.0, -175.0]),
                      np.deg2rad([170.0, 120.0, 170.0, 120.0, 170.0, 120.0, 175.0]))
#: Joint speed limits, shape (7,), rad/s (datasheet).
IIWA7_VELOCITY_LIMITS = np.deg2rad([98.0, 98.0, 100.0, 130.0, 140.0, 180.0, 180.0])
#: Joint torque limits, shape (7,), N m (datasheet).
IIWA7_TORQUE_LIMITS = np.array([176.0, 176.0, 110.0, 110.0, 110.0, 40.0, 40.0])
#: Flange height above the base at q = 0 (0.34 + 0.40 + 0.40 + 0.126 m).
IIWA7_HEIGHT = 1.266
#: Home configuration, shape (7,), radians: elbow bent, flange in front of the base
#: (along the base's +x) at about table height + 0.35 m.
HOME_Q = np.array([0.0, 0.45, 0.0, -1.65, 0.0, 1.05, 0.0])

for _a in IIWA7_JOINT_LIMITS + (IIWA7_VELOCITY_LIMITS, IIWA7_TORQUE_LIMITS, HOME_Q):
    _a.setflags(write=False)


# --------------------------------------------------------------------------- config schema
@dataclass
class Pose:
    """A pose X_WF as position and roll-pitch-yaw (Drake's ``RollPitchYaw``: R = Rz Ry Rx)."""

    # position in metres
    xyz: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    # roll, pitch, yaw in degrees
    rpy_deg: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])

    def transform(self) -> RigidTransform:
        """The pose as a ``RigidTransform``."""
        if len(self.xyz) != 3 or len(self.rpy_deg) != 3:
            raise ValueError(f"pose needs 3 coordinates and 3 angles, got xyz={self.xyz} rpy_deg={self.rpy_deg}")
        return RigidTransform(RollPitchYaw(np.deg2rad(self.rpy_deg)), np.asarray(self.xyz, float))


@dataclass
class SceneObject:
    """A static object of the scene, welded to the world."""

    # model file, relative to models/ (e.g. "salad/tomato.sdf")
    sdf: str = ""
    # pose X_WO of the model's body frame (its origin is the object's bottom centre)
    pose: Pose = field(default_factory=Pose)


@dataclass
class PersonConfig:
    """The seated person (drawn in meshcat, never a body of the plant); the nominal subject."""

    # centre of the chair seat, metres (world)
    seat: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    # right shoulder of the nominal subject, metres (world)
    shoulder: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    # where the right wrist rests (on the table edge) before every task, metres (world)
    wrist_rest: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    # shoulder-to-wrist length of the nominal subject, metres
    arm_length: float = 0.60
    # how far the nominal subject reaches by leaning the torso, metres
    lean: float = 0.25
    # the hand's first move, shared by every task: lift off the table edge (offset, metres)
    lift: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])


@dataclass
class TaskConfig:
    """One collaborative task: where the person reaches, what the robot grasps and hands over."""

    # scene object the robot fetches ("" for standup)
    object: str = ""
    # the classic subjects' final wrist position for the nominal subject, metres (world)
    reach: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    # what a styled subject's hand goes for: the object where it stands (its grasp point
    # for the knife), metres (world); a reach stops short of it at the subject's stretch.
    # Empty for standup (the motion is the person's own)
    target: list[float] = field(default_factory=list)
    # flange pose X_WE where the robot grasps the object (for standup: a ready pose)
    grasp: Pose = field(default_factory=Pose)
    # handover flange position = final wrist + handover_distance along the horizontal
    # direction from the wrist toward the robot base + [0, 0, handover_dz]
    handover_distance: float = 0.18
    handover_dz: float = 0.0
    # handover flange orientation: its z axis (the approach axis) points horizontally from
    # the robot base toward the handover point, tilted down by this angle (90 = straight
    # down, 0 = horizontal); rotation about the axis is free
    handover_tilt_deg: float = 90.0
    # tolerance of the approach axis, degrees
    handover_tolerance_deg: float = 20.0


@dataclass
class SceneConfig:
    """Schema of ``models/salad/scene.yaml``."""

    # pose X_WB of the IIWA7 base (iiwa_link_0), welded to the world
    robot_base: Pose = field(default_factory=Pose)
    # static objects by name
    objects: dict[str, SceneObject] = field(default_factory=dict)
    # the seated person and the nominal subject's body
    person: PersonConfig = field(default_factory=PersonConfig)
    # the five tasks by name (board, tomato, bowl, dressing, standup)
    tasks: dict[str, TaskConfig] = field(default_factory=dict)
    # handover points are kept within this horizontal distance band from the robot base
    # (metres): the robot brings the object as close to the hand as it can reach
    handover_radius: list[float] = field(default_factory=lambda: [0.42, 0.72])


# --------------------------------------------------------------------------- loading
def models_dir() -> Path:
    """The repository's ``models/`` directory (found relative to this file)."""
    d = Path(__file__).resolve().parents[2] / "models"
    if not (d / "package.xml").is_file():
        raise FileNotFoundError(f"models directory with package.xml not found at '{d}'")
    return d


def scene_config_path() -> Path:
    """Path of ``models/salad/scene.yaml``."""
    return models_dir() / "salad" / "scene.yaml"


def load_scene_config(path: str | Path | None = None) -> SceneConfig:
    """Load the salad scene configuration.

    Parameters
    ----------
    path : str or Path, optional
        YAML file in the :class:`SceneConfig` schema; default ``models/salad/scene.yaml``.
    """
    path = Path(path) if path is not None else scene_config_path()
    if not path.is_file():
        raise FileNotFoundError(f"scene config '{path}' " + ("is a directory, not a YAML file" if path.is_dir() else "does not exist"))
    try:
        cfg = yaml_load_typed(schema=SceneConfig, filename=str(path))
    except RuntimeError as exc:
        raise ValueError(f"scene config '{path}': {exc}") from None
    for name, task in cfg.tasks.items():
        if task.object and task.object not in cfg.objects:
            raise ValueError(f"scene config '{path}': task {name!r} names unknown object {task.object!r}")
    return cfg


def add_package(parser: Parser) -> None:
    """Register ``models/package.xml`` (package ``drake_skills_models``) in the parser's package map."""
    pm = parser.package_map()
    if not pm.Contains(PACKAGE_NAME):
        pm.AddPackageXml(str(models_dir() / "package.xml"))


def add_iiwa7(plant: MultibodyPlant, parser: Parser | None = None, X_WB: RigidTransform | None = None,
              *, name: str = "iiwa7") -> ModelInstanceIndex:
    """Add the IIWA7 and weld its base to the world.

    Parameters
    ----------
    plant : MultibodyPlant
        Not yet finalized.
    parser : Parser, optional
        Parser of ``plant`` (default: a new one).
    X_WB : RigidTransform, optional
        Base pose; default the robot base of ``scene.yaml``.
    name : str
        Model instance name.

    Returns
    -------
    ModelInstanceIndex
    """
    parser = parser if parser is not None else Parser(plant)
    add_package(parser)
    if X_WB is None:
        X_WB = load_scene_config().robot_base.transform()
    parser.SetAutoRenaming(True)
    (model,) = parser.AddModels(url=IIWA7_URL)
    if name != plant.GetModelInstanceName(model):
        plant.RenameModelInstance(model, name)
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(IIWA7_BASE_FRAME, model), X_WB)
    return model


def add_salad_scene(plant: MultibodyPlant, parser: Parser, config: SceneConfig | None = None, *,
                    include_robot: bool = True) -> dict[str, ModelInstanceIndex]:
    """Add the salad scene of the paper's Fig. 5(a): static objects welded to the world.

    Parameters
    ----------
    plant : MultibodyPlant
        Not yet finalized.
    parser : Parser
        Parser of ``plant``.
    config : SceneConfig, optional
        Default :func:`load_scene_config`.
    include_robot : bool
        Also add the IIWA7 at ``config.robot_base`` (key ``"iiwa"``).

    Returns
    -------
    dict of str to ModelInstanceIndex
        One entry per object name of the config (and ``"iiwa"``).
    """
    config = config if config is not None else load_scene_config()
    add_package(parser)
    parser.SetAutoRenaming(True)
    out: dict[str, ModelInstanceIndex] = {}
    for name, obj in config.objects.items():
        (model,) = parser.AddModels(url=f"package://{PACKAGE_NAME}/{obj.sdf}")
        plant.RenameModelInstance(model, name)
        bodies = plant.GetBodyIndices(model)
        if len(bodies) != 1:
            raise ValueError(f"scene object {name!r} ({obj.sdf}) must have exactly one link, has {len(bodies)}")
        plant.WeldFrames(plant.world_frame(), plant.get_body(bodies[0]).body_frame(), obj.pose.transform())
        out[name] = model
    if include_robot:
        out["iiwa"] = add_iiwa7(plant, parser, config.robot_base.transform())
    return out


def make_iiwa7_plant(X_WB: RigidTransform | None = None, *, time_step: float = 0.0) -> MultibodyPlant:
    """A finalized plant holding only the IIWA7 (for inverse kinematics and control).

    Parameters
    ----------
    X_WB : RigidTransform, optional
        Base pose; default the robot base of ``scene.yaml``.
    time_step : float
        Plant time step (0 for continuous).
    """
    plant = MultibodyPlant(time_step)
    add_iiwa7(plant, Parser(plant), X_WB)
    plant.Finalize()
    return plant


class FlangeKinematics:
    """Forward kinematics of the IIWA7 flange, ``p_WE`` (3,) at joints ``q`` (7,), on its own plant.

    Parameters
    ----------
    X_WB : RigidTransform, optional
        Base pose; default the robot base of ``scene.yaml``.

    A copy sent to another process (pickled) builds its own plant there.
    """

    def __init__(self, X_WB: RigidTransform | None = None):
        self._X_WB = X_WB
        self._plant = make_iiwa7_plant(X_WB)
        self._context = self._plant.CreateDefaultContext()
        self._frame = self._plant.GetFrameByName(FLANGE_FRAME)

    def __call__(self, q) -> np.ndarray:
        self._plant.SetPositions(self._context, np.asarray(q, float))
        return np.array(self._plant.CalcRelativeTransform(self._context, self._plant.world_frame(),
                                                          self._frame).translation())

    def __reduce__(self):
        return (FlangeKinematics, (self._X_WB,))
