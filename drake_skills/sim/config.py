"""``SimConfig``: the YAML schema of the simulated collaboration (diagram, decision, meshcat, trials)."""
# No "from __future__ import annotations": yaml_load_typed reads the real field types.

from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from pydrake.common.yaml import yaml_load_typed

from drake_skills.systems.gating import DecisionRule


@dataclass
class DecisionConfig:
    """When the gating decides (normalized workspace units, Eq. 14: the workspace spans [0, 10])."""

    # the wrist must first move this far from its start
    min_travel: float = 1.0
    # ... then stay within still_radius of its last position for this long (s)
    still_duration: float = 0.4
    # radius of "still"
    still_radius: float = 0.05
    # decide this long after the trial start whatever the wrist does (s); null: when it stops
    decision_time: Optional[float] = None
    # decide at the latest this long after the trial start (s)
    timeout: float = 10.0

    def rule(self) -> DecisionRule:
        """The gating's :class:`DecisionRule`."""
        return DecisionRule(self.min_travel, self.still_duration, self.still_radius, self.decision_time,
                            self.timeout)


@dataclass
class ControllerConfig:
    """Gains of the inverse-dynamics controller (same for every joint)."""

    # proportional gain (1/s^2)
    kp: float = 100.0
    # integral gain (1/s^3)
    ki: float = 1.0
    # derivative gain (1/s)
    kd: float = 20.0


@dataclass
class MeshcatConfig:
    """What meshcat shows and records."""

    # period of the scene and wrist drawing (s), exact in binary
    publish_period: float = 1.0 / 32.0
    # frames per second of the recording
    frames_per_second: float = 32.0
    # radius of the sphere drawn at the person's wrist (m)
    wrist_radius: float = 0.035
    # camera position, metres (world): behind and left of the seated person
    camera_position: list[float] = field(default_factory=lambda: [-1.9, -1.7, 1.9])
    # point the camera looks at, metres (world): above the table centre
    camera_target: list[float] = field(default_factory=lambda: [0.0, 0.1, 0.9])


@dataclass
class SimConfig:
    """Everything the simulated collaboration needs beyond the library and the subject."""

    # random seed (trial order, subject generation)
    seed: int = 0
    # time step of the discrete MultibodyPlant (s)
    time_step: float = 1e-3
    # when the gating decides
    decision: DecisionConfig = field(default_factory=DecisionConfig)
    # inverse-dynamics controller gains
    controller: ControllerConfig = field(default_factory=ControllerConfig)
    # meshcat drawing and recording
    meshcat: MeshcatConfig = field(default_factory=MeshcatConfig)
    # samples of the conditioned robot trajectory (knots of the joint plan)
    n_steps: int = 100
    # let the robot collide with the (welded) scene objects
    robot_scene_contact: bool = False
    # simulated time after the conditioned trajectory ends, to let the arm settle (s)
    settle_time: float = 0.5
    # simulated time the robot holds still after an "unknown" decision (s)
    unknown_hold_time: float = 0.5
    # period at which a trial's joints are logged (tracking error, limits) (s), exact in binary
    log_period: float = 1.0 / 32.0
    # number of trials of the demo
    trials: int = 20
    # 1-based index of the simulated subject (drake_skills.scenario.salad)
    subject: int = 1
    # demonstrations generated per task for the subject (the trial pool)
    demos_per_task: int = 15
    # shrink factor of the calibrated workspace along z (Sec. 4.2.2)
    z_factor: float = 0.9

    def __post_init__(self):
        for name in ("time_step", "settle_time", "log_period"):
            if not getattr(self, name) > 0:
                raise ValueError(f"SimConfig.{name} must be positive, got {getattr(self, name)!r}")
        if self.unknown_hold_time < 0:
            raise ValueError(f"SimConfig.unknown_hold_time must be >= 0, got {self.unknown_hold_time!r}")
        if isinstance(self.subject, bool) or int(self.subject) != self.subject or self.subject < 1:
            raise ValueError(f"SimConfig.subject is a 1-based index, got {self.subject!r}")
        if self.trials < 1 or self.n_steps < 2 or self.demos_per_task < 1:
            raise ValueError("SimConfig: trials and demos_per_task must be >= 1 and n_steps >= 2")


def load_sim_config(path: str | Path | None = None, *, defaults: SimConfig | None = None) -> SimConfig:
    """Read a :class:`SimConfig` from YAML (missing fields keep their defaults)."""
    defaults = defaults if defaults is not None else SimConfig()
    if path is None:
        return defaults
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"simulation config '{path}' does not exist")
    try:
        cfg = yaml_load_typed(schema=SimConfig, filename=str(path), defaults=defaults)
    except RuntimeError as exc:
        raise ValueError(f"simulation config '{path}': {exc}") from None
    cfg.__post_init__()
    return cfg
