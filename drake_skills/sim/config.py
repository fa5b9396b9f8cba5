"""``SimConfig``: the one config tree of a run, read from YAML with Drake's ``yaml_load_typed``.

::

    SimConfig              the simulated collaboration (this module)
      library: LibraryConfig   the skill library (drake_skills.library.config)
      decision: DecisionRule   when the gating decides (drake_skills.systems.decision_rule)
      controller, meshcat      gains and drawing
      lcm: LcmConfig           channels, rates and the simulated bus (drake_skills.sim.lcm_config)

Every node is a dataclass that is its own schema (a comment on every field) and
validates itself in ``__post_init__``. :func:`load_config` reads a file in either of
two forms: a ``SimConfig`` document (library settings under ``library:``), or a
document of ``LibraryConfig`` fields alone (the rest keeps its defaults).
"""
# No "from __future__ import annotations": yaml_load_typed reads the real field types.

from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Optional, Union

import math

import numpy as np
import yaml
from pydrake.common.yaml import yaml_load, yaml_load_typed

from drake_skills._checks import validated
from drake_skills.library.config import LibraryConfig
from drake_skills.sim.lcm_config import LcmConfig
from drake_skills.systems.decision_rule import DecisionRule
from drake_skills.systems.normalizer import SampleRule
from drake_skills.systems.wrist_faults import TrackerFaults

#: Subject models of the simulated salad scenario (drake_skills.scenario.salad), the default first.
SUBJECT_MODELS = ("styled", "classic")
#: SimConfig.integrator: how the Diagram's continuous state is integrated between the plant's steps.
INTEGRATORS = ("explicit_euler", "runge_kutta2", "drake_default")


@dataclass
class ControllerConfig:
    """Gains of the inverse-dynamics controller (same for every joint)."""

    # proportional gain (1/s^2)
    kp: float = 100.0
    # integral gain (1/s^3)
    ki: float = 1.0
    # derivative gain (1/s)
    kd: float = 20.0

    def __post_init__(self):
        # a negative gain pushes the arm away from its command (a cold review ran kp = -100 to the end)
        for name in ("kp", "kd"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"ControllerConfig.{name} must be positive and finite, got {v!r}")
        if not (np.isfinite(self.ki) and self.ki >= 0):
            raise ValueError(f"ControllerConfig.ki must be >= 0 and finite, got {self.ki!r}")


@dataclass
class MeshcatConfig:
    """What meshcat shows and records."""

    # period of the scene and wrist drawing (s), exact in binary
    publish_period: float = 1.0 / 32.0
    # frames per second of the recording
    frames_per_second: float = 32.0
    # radius of the sphere drawn at the person's wrist (m)
    wrist_radius: float = 0.035
    # camera position, metres (world): behind and right of the seated person, framing the table
    camera_position: list[float] = field(default_factory=lambda: [-1.45, -1.05, 1.55])
    # point the camera looks at, metres (world): above the table, between the person and the robot
    camera_target: list[float] = field(default_factory=lambda: [-0.2, 0.15, 0.9])

    def __post_init__(self):
        for name in ("publish_period", "frames_per_second", "wrist_radius"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"MeshcatConfig.{name} must be positive and finite, got {v!r}")
        for name in ("camera_position", "camera_target"):
            v = np.asarray(getattr(self, name), float)
            if v.shape != (3,) or not np.isfinite(v).all():
                raise ValueError(f"MeshcatConfig.{name} must be three finite numbers (metres), got {getattr(self, name)!r}")


@dataclass
class SimConfig:
    """Everything a simulated collaboration needs beyond the subject's data."""

    # random seed (trial order, subject generation)
    seed: int = 0
    # time step of the discrete MultibodyPlant (s)
    time_step: float = 1e-3
    # integrator of the Diagram's continuous state, the controller's PID integral (and, over LCM, the simulated
    # driver's torque filter; the plant is discrete): "explicit_euler" or "runge_kutta2" in fixed steps of
    # time_step, or "drake_default" (Drake's error-controlled third-order Runge-Kutta, which evaluates the
    # controller about three times per plant step: the full Diagram runs about 1.2x slower, with the same
    # trials; BENCHMARKS.md, "Closed loop"). sim.diagram.configure_simulator applies it to a Simulator.
    integrator: str = "explicit_euler"
    # the skill library the robot starts with (empty) and teaches
    library: LibraryConfig = field(default_factory=LibraryConfig)
    # when the gating decides
    decision: DecisionRule = field(default_factory=DecisionRule)
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
    # how the simulated people move: "styled" (styles per person) or "classic" (one geometry, scaled)
    subject_model: str = SUBJECT_MODELS[0]
    # demonstrations generated per task for the subject (the trial pool)
    demos_per_task: int = 15
    # shrink factor of the calibrated workspace along z (Sec. 4.2.2)
    z_factor: float = 0.9
    # the LCM interface (drake-skills demo --transport lcm, drake-skills control)
    lcm: LcmConfig = field(default_factory=LcmConfig)
    # which wrist samples the controller accepts (drake_skills.systems.normalizer)
    wrist: SampleRule = field(default_factory=SampleRule)
    # a misbehaving simulated wrist tracker (drake_skills.systems.wrist_faults; default: perfect)
    faults: TrackerFaults = field(default_factory=TrackerFaults)

    def __post_init__(self):
        for name, kind in (("library", LibraryConfig), ("decision", DecisionRule), ("controller", ControllerConfig),
                           ("meshcat", MeshcatConfig), ("lcm", LcmConfig), ("wrist", SampleRule),
                           ("faults", TrackerFaults)):
            if not isinstance(getattr(self, name), kind):
                raise ValueError(f"SimConfig.{name} must be a {kind.__name__}, "
                                 f"got {type(getattr(self, name)).__name__}")
        for name in ("time_step", "settle_time", "log_period"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"SimConfig.{name} must be positive and finite, got {v!r}")
        if not (np.isfinite(self.unknown_hold_time) and self.unknown_hold_time >= 0):
            raise ValueError(f"SimConfig.unknown_hold_time must be >= 0, got {self.unknown_hold_time!r}")
        if isinstance(self.subject, bool) or int(self.subject) != self.subject or self.subject < 1:
            raise ValueError(f"SimConfig.subject is a 1-based index, got {self.subject!r}")
        if self.integrator not in INTEGRATORS:
            raise ValueError(f"SimConfig.integrator must be one of {INTEGRATORS}, got {self.integrator!r}")
        if self.subject_model not in SUBJECT_MODELS:
            raise ValueError(f"SimConfig.subject_model must be one of {SUBJECT_MODELS}, got {self.subject_model!r}")
        if self.trials < 1 or self.n_steps < 2 or self.demos_per_task < 1:
            raise ValueError("SimConfig: trials and demos_per_task must be >= 1 and n_steps >= 2")
        if not 0 < self.z_factor <= 1:
            raise ValueError(f"SimConfig.z_factor must be in (0, 1], got {self.z_factor!r}")


def _field_types(schema) -> dict:
    """Field name -> type of a config dataclass (its annotations, as ``yaml_load_typed`` reads them)."""
    import typing

    return typing.get_type_hints(schema)


_BOOL_WORDS = {"true", "false", "yes", "no", "on", "off"}


def _whole(value) -> bool:
    try:
        x = float(value)
    except (TypeError, ValueError):
        return False
    return math.isfinite(x) and x == int(x)


def _parses(kind, value) -> bool:
    try:
        kind(value)
    except (TypeError, ValueError):
        return False
    return True


def _check_node(node, schema, where: str) -> None:
    """Check the shape of a YAML mapping against a config dataclass before Drake's loader reads it.

    ``yaml_load_typed`` stops on a node of the wrong kind with an ``AssertionError`` that names
    neither the field nor the file (a section given as a number, a number given as text); this
    names the field. Unknown keys are left to the loader, which names them.
    """
    import dataclasses
    import typing

    types = _field_types(schema)
    for key, value in node.items():
        if key not in types:
            continue
        kind = types[key]
        name = f"{where}{key}"
        optional = False
        if typing.get_origin(kind) is Union:
            args = [a for a in typing.get_args(kind) if a is not type(None)]
            optional = len(args) < len(typing.get_args(kind))
            if len(args) != 1:
                continue
            kind = args[0]
        if value is None:
            if optional:
                continue
            raise ValueError(f"'{name}' has no value (write one, or leave the key out for the default)")
        if dataclasses.is_dataclass(kind):
            if not isinstance(value, dict):
                raise ValueError(f"'{name}' must be a mapping of {kind.__name__} fields, got {value!r}")
            _check_node(value, kind, name + ".")
        elif kind is bool:  # what Drake's loader reads as a bool: true/false (and yes/no, on/off), quoted or not
            if not (isinstance(value, bool) or isinstance(value, str) and value.lower() in _BOOL_WORDS):
                raise ValueError(f"'{name}' must be true or false, got {value!r}")
        elif kind is int:  # 100, 100.0 and '100' are the integer 100 to the loader
            if isinstance(value, bool) or not isinstance(value, (int, float, str)) or not _whole(value):
                raise ValueError(f"'{name}' must be an integer, got {value!r}")
        elif typing.get_origin(kind) in (list, tuple):
            if not isinstance(value, (list, tuple)):
                raise ValueError(f"'{name}' must be a list, got {value!r}")
        elif kind is float:  # text the loader reads as a number is one (YAML 1.1 reads 1e-9 as text)
            if isinstance(value, bool) or not isinstance(value, (int, float, str)) or not _parses(float, value):
                raise ValueError(f"'{name}' must be a number, got {value!r}")
        elif kind is str:
            if not isinstance(value, str):
                raise ValueError(f"'{name}' must be text, got {value!r}")


def load_config(path: Union[str, Path, None] = None, *, defaults: Optional[SimConfig] = None) -> SimConfig:
    """Read a :class:`SimConfig` from YAML; missing fields keep their defaults.

    The document is either a ``SimConfig`` (library settings under ``library:``) or
    ``LibraryConfig`` fields alone, which then become ``SimConfig.library``. Every
    node is validated as if built in Python.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        For an unknown field, a value of the wrong type or an invalid setting;
        the message names the file.
    """
    defaults = defaults if defaults is not None else SimConfig()
    if path is None:
        return validated(defaults)
    path = Path(path)
    where = f"config '{path}'"
    if not path.is_file():
        raise FileNotFoundError(f"{where} " + ("is a directory, not a YAML file" if path.is_dir() else "does not exist"))
    try:
        root = yaml_load(filename=str(path))
        if root is None:
            raise ValueError("the file is empty: write SimConfig fields, or LibraryConfig fields alone")
        if not isinstance(root, dict):
            raise ValueError(f"the document is a {type(root).__name__}, not a mapping of fields")
        library_fields = {f.name for f in fields(LibraryConfig)}
        _check_node(root, LibraryConfig if root and set(root) <= library_fields else SimConfig, "")
        if root and set(root) <= library_fields:
            # the loader assigns fields of (a copy of) its defaults: start from changeable copies, as a
            # library's config is sealed
            library = yaml_load_typed(schema=LibraryConfig, filename=str(path), defaults=replace(defaults.library))
            return validated(SimConfig(**{f.name: getattr(defaults, f.name) for f in fields(SimConfig)
                                          if f.name != "library"}, library=library))
        misplaced = sorted(set(root) & library_fields)
        if misplaced:
            raise ValueError(f"LibraryConfig fields {misplaced} must go under 'library:' next to SimConfig fields")
        return validated(yaml_load_typed(schema=SimConfig, filename=str(path),
                                         defaults=replace(defaults, library=replace(defaults.library))))
    except yaml.YAMLError as exc:  # not YAML at all (a tab indent, an unclosed bracket, ...)
        raise ValueError(f"{where} is not valid YAML: {' '.join(str(exc).split())}") from None
    except (RuntimeError, ValueError, TypeError) as exc:
        raise ValueError(f"{where}: {exc}") from None


def load_library_config(path: Union[str, Path, None] = None) -> LibraryConfig:
    """The :class:`LibraryConfig` of a ``--config`` file (either form of :func:`load_config`)."""
    return load_config(path).library
