"""The salad scenario's building blocks: constants, the subject types, and the wrist-path helpers.

Shared by the two subject models of :mod:`drake_skills.scenario.salad` (``"classic"``:
one task geometry scaled per person) and :mod:`drake_skills.scenario.salad_styles`
(``"styled"``: people who differ in how they move).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from drake_skills.data.workspace import Workspace
from drake_skills.data.demonstration import Demonstration
from drake_skills.sim.models import load_scene_config

#: The five collaborative tasks of the paper, in a fixed order (seeds depend on it).
TASKS = ("board", "tomato", "bowl", "dressing", "standup")
#: Sampling rate of the motion capture system, Hz.
RATE_HZ = 150.0
#: 1-based indices of the sloppy subjects.
SLOPPY_SUBJECTS = (3, 7)
#: Height of the table top, metres (world); the wrist stays 1.5 cm above it or higher.
TABLE_TOP_Z = 0.75

# Relative reach duration per task (standing up and reaching to the shelf take longer).
_TASK_DURATION = {"board": 0.9, "tomato": 1.0, "bowl": 1.0, "dressing": 1.15, "standup": 1.35}
# Random streams (second seed word after the subject index).
_STREAM_SUBJECT, _STREAM_DEMO, _STREAM_CALIBRATION = 0, 1, 2


@dataclass(eq=False)
class Subject:
    """One simulated person.

    Attributes
    ----------
    name : str
        ``"subject1"`` .. ``"subject10"``.
    arm_length : float
        Shoulder to wrist, metres.
    index : int
        1-based subject number.
    reach : float
        Arm length plus torso lean: the calibration radius, metres.
    workspace_scale : float
        Scale of the subject's reaches relative to the nominal subject.
    shoulder : array, shape (3,)
        Right shoulder position while seated, metres (world).
    rest : array, shape (3,)
        Mean wrist rest position (start of every motion), metres (world).
    duration : float
        Mean reach duration, seconds (scaled per task).
    profile_skew : float
        Skew of the speed profile (0: symmetric minimum jerk; > 0: early peak).
    curvature : float
        Path bulge as a fraction of the reach length.
    curvature_angle : float
        Direction of the bulge about the path, radians (0: up).
    noise : float
        Amplitude of the smooth tremor/tracking noise, metres.
    jitter : float
        Trial-to-trial via-point jitter (standard deviation), metres.
    task_offsets : dict of str to array, shape (3,)
        The subject's personal offset of each task's goal, metres.
    sloppy : bool
        Large trial-to-trial variation with two alternating path styles.
    style : SubjectStyle or None
        How the person moves (:mod:`drake_skills.scenario.salad_styles`); None for the
        classic subject model.
    """

    name: str
    arm_length: float
    index: int
    reach: float
    workspace_scale: float
    shoulder: np.ndarray
    rest: np.ndarray
    duration: float
    profile_skew: float
    curvature: float
    curvature_angle: float
    noise: float
    jitter: float
    task_offsets: dict = field(default_factory=dict)
    sloppy: bool = False
    style: Any = None

    def calibration_box(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounding box (lower, upper), shape (3,) each, swept by the calibration half circles."""
        lo = np.array([self.shoulder[0], self.shoulder[1] - self.reach, _calibration_z(self)])
        hi = np.array([self.shoulder[0] + self.reach, self.shoulder[1] + self.reach,
                       _calibration_z(self) + self.reach])
        return lo, hi


@dataclass(eq=False)
class SubjectData:
    """A subject with its calibration motions and demonstrations.

    Attributes
    ----------
    subject : Subject
    calibration : list of array, shape (T_i, 3)
        The x-y and z-y half circles, in this order.
    demos : list of Demonstration
        Ordered by task (in ``TASKS`` order), then by demonstration index.
    """

    subject: Subject
    calibration: list
    demos: list = field(default_factory=list)

    def workspace(self, z_factor: float | None = 0.9) -> Workspace:
        """The subject's workspace from the calibration motions (Sec. 4.2.2)."""
        return Workspace.from_calibration(self.calibration, z_factor=z_factor)

    def by_task(self, task: str) -> list[Demonstration]:
        """The demonstrations of one task."""
        return [d for d in self.demos if d.task == task]


# --------------------------------------------------------------------------- helpers
def _rng(seed: int, index: int, *stream: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(index), *map(int, stream)]))


def _calibration_z(subject: Subject) -> float:
    # the x-y half circle slides on the table; the z-y one starts there
    return TABLE_TOP_Z + 0.015


def min_jerk(u: np.ndarray) -> np.ndarray:
    """Minimum-jerk profile ``10u^3 - 15u^4 + 6u^5`` on u clipped to [0, 1].

    Parameters
    ----------
    u : array, shape (T,)

    Returns
    -------
    s : array, shape (T,)
        0 at u <= 0, 1 at u >= 1, zero velocity and acceleration at both ends.
    """
    u = np.clip(u, 0.0, 1.0)
    return u ** 3 * (10.0 - 15.0 * u + 6.0 * u * u)


def _skewed_profile(u: np.ndarray, skew: float) -> np.ndarray:
    """Minimum jerk after a smooth time warp; ``skew > 0`` moves the speed peak earlier."""
    u = np.clip(u, 0.0, 1.0)
    if abs(skew) > 1e-9:
        u = (1.0 - np.exp(-skew * u)) / (1.0 - np.exp(-skew))
    return min_jerk(u)


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    return v / n if n > 1e-12 else v


def _check_subject(index: int, seed: int) -> None:
    """Raise ValueError unless ``index`` is 1-based and ``seed`` non-negative."""
    if int(index) < 1:
        raise ValueError(f"subject index is 1-based, got {index!r}")
    if int(seed) < 0:
        raise ValueError(f"seed must be non-negative, got {seed!r}")


def _draw_body(cfg, rng: np.random.Generator) -> tuple[float, float, float]:
    """Arm length (m), torso lean and reach scale of a subject, drawn from ``rng`` (three draws, in this order)."""
    arm = float(rng.uniform(0.54, 0.68))
    lean = float(cfg.lean * rng.uniform(0.85, 1.15))
    scale = arm / cfg.arm_length * float(rng.uniform(0.92, 1.08))
    return arm, lean, scale


@functools.lru_cache(maxsize=1)
def _scene():
    return load_scene_config()


def _bezier(ctrl: np.ndarray, n: int) -> np.ndarray:
    """Cubic Bezier curve through control points ``ctrl`` (4, 3), sampled at n points."""
    s = np.linspace(0, 1, n)[:, None]
    return ((1 - s) ** 3 * ctrl[0] + 3 * (1 - s) ** 2 * s * ctrl[1]
            + 3 * (1 - s) * s ** 2 * ctrl[2] + s ** 3 * ctrl[3])


@dataclass(eq=False)
class ReachPlan:
    """A planned wrist motion: a path timed by a skewed minimum-jerk profile, then a hold.

    Attributes
    ----------
    path : array, shape (M, 3)
        Densely sampled path, metres (world).
    arc : array, shape (M,)
        Arc length along ``path`` from 0.
    goal : array, shape (3,)
        Noise-free end of the reach.
    T_move, T_hold : float
        Reach duration and (minimum) hold at the goal, seconds.
    skew : float
        Speed-profile skew (see :func:`min_jerk`).
    noise : array, shape (3, 3, 3)
        Frequencies, phases and amplitudes of the smooth noise (3 sinusoids x 3 axes).
    """

    path: np.ndarray
    arc: np.ndarray
    goal: np.ndarray
    T_move: float
    T_hold: float
    skew: float
    noise: np.ndarray

    def position(self, t: np.ndarray) -> np.ndarray:
        """Wrist positions (T, 3) at times t (T,), with the smooth noise, without sensor noise."""
        t = np.asarray(t, float)
        sa = self.arc[-1] * _skewed_profile(t / self.T_move, self.skew)
        y = np.stack([np.interp(sa, self.arc, self.path[:, k]) for k in range(3)], axis=1)
        f, ph, a = self.noise
        n = np.einsum("ka,tka->ta", a, np.sin(2 * np.pi * f[None] * t[:, None, None] + ph[None]))
        fade = 0.5 * (1 - np.cos(np.pi * np.clip(t / 0.4, 0, 1)))  # the start is the rest position
        return y + n * fade[:, None]

