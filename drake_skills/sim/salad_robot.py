"""The IIWA7 of the salad scene: inverse kinematics to the grasp and handover poses.

Solved on a plant holding only the robot (:func:`~drake_skills.sim.models.make_iiwa7_plant`
at the base pose of ``models/salad/scene.yaml``). Grasp poses are fixed per task
(``tasks.<name>.grasp`` of the scene) and solved once; the handover pose follows the
person's final wrist position (``handover_distance`` toward the robot base), seeded with
the grasp solution. The demonstrations of :mod:`drake_skills.scenario.salad` are made
from these solutions.
"""
from __future__ import annotations

import functools
import logging

import numpy as np
from pydrake.math import RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import Solve

from drake_skills.sim.models import FLANGE_FRAME, HOME_Q, IIWA7_JOINT_LIMITS, SceneConfig, load_scene_config, \
    make_iiwa7_plant

log = logging.getLogger(__name__)


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    return v / n if n > 1e-12 else v


class SaladRobot:
    """Inverse kinematics of the IIWA7 alone, with cached grasp solutions.

    Parameters
    ----------
    scene : SceneConfig
        Robot base, grasp poses and handover settings per task.
    """

    def __init__(self, scene: SceneConfig):
        self.scene = scene
        self.plant = make_iiwa7_plant(scene.robot_base.transform())
        self.flange = self.plant.GetFrameByName(FLANGE_FRAME)
        self.home = np.array(HOME_Q)
        self.base_xyz = np.asarray(scene.robot_base.xyz, float)
        self._grasp: dict[str, np.ndarray] = {}

    @property
    def tasks(self) -> tuple[str, ...]:
        """The task names of the scene."""
        return tuple(self.scene.tasks)

    def _task(self, task: str):
        if task not in self.scene.tasks:
            raise ValueError(f"unknown task {task!r}; tasks are {self.tasks}")
        return self.scene.tasks[task]

    def solve(self, p_WE: np.ndarray, *, pos_tol: float, seed: np.ndarray, R_WE=None,
              axis_W: np.ndarray | None = None, theta_bound: float) -> np.ndarray | None:
        """Joint angles (7,) putting the flange at p_WE (3,), or None if IK fails.

        Orientation: either the full rotation ``R_WE`` within ``theta_bound``, or only the
        flange z axis within ``theta_bound`` of the unit vector ``axis_W`` (3,).
        """
        ik = InverseKinematics(self.plant)
        W = self.plant.world_frame()
        ik.AddPositionConstraint(self.flange, np.zeros(3), W, p_WE - pos_tol, p_WE + pos_tol)
        if R_WE is not None:
            ik.AddOrientationConstraint(W, R_WE, self.flange, RotationMatrix(), theta_bound)
        else:
            ik.AddAngleBetweenVectorsConstraint(W, axis_W, self.flange, np.array([0.0, 0.0, 1.0]),
                                                0.0, theta_bound)
        # keep 2 degrees off the joint limits (the SDF rounds them to 6 decimals, and a
        # real controller needs room to track)
        lower, upper = IIWA7_JOINT_LIMITS
        margin = np.deg2rad(2.0)
        ik.prog().AddBoundingBoxConstraint(lower + margin, upper - margin, ik.q())
        # stay close to the seed: no jumps between IK branches
        ik.prog().AddQuadraticErrorCost(np.eye(7), seed, ik.q())
        result = Solve(ik.prog(), seed)
        if not result.is_success():
            return None
        return np.asarray(result.GetSolution(ik.q()), float)

    def grasp(self, task: str) -> np.ndarray:
        """Cached joint angles (7,) of the task's grasp pose (2 mm, 2 degrees)."""
        if task not in self._grasp:
            X = self._task(task).grasp.transform()
            q = self.solve(X.translation(), R_WE=X.rotation(), theta_bound=np.deg2rad(2.0), pos_tol=0.002,
                           seed=self.home)
            if q is None:
                raise RuntimeError(f"inverse kinematics found no solution for the grasp pose of task {task!r}")
            self._grasp[task] = q
        return self._grasp[task]

    def handover_position(self, task: str, wrist: np.ndarray) -> np.ndarray:
        """Flange position (3,) of the handover for a final wrist position (3,)."""
        tcfg = self._task(task)
        toward = self.base_xyz - wrist
        toward[2] = 0.0
        p = wrist + tcfg.handover_distance * _unit(toward) + np.array([0.0, 0.0, tcfg.handover_dz])
        # keep the wrist centre (joint 6, 0.126 m behind the flange along the approach axis)
        # in the band of horizontal distances the robot reaches comfortably
        r_min, r_max = self.scene.handover_radius
        back = 0.126 * np.cos(np.deg2rad(tcfg.handover_tilt_deg))
        d = p[:2] - self.base_xyz[:2]
        r = float(np.linalg.norm(d))
        p[:2] = self.base_xyz[:2] + d / r * np.clip(r, r_min + back, r_max + back)
        return p

    def handover_axis(self, task: str, p_WE: np.ndarray) -> np.ndarray:
        """Unit approach axis (3,) of the flange at the handover point p_WE (3,)."""
        tilt = np.deg2rad(self._task(task).handover_tilt_deg)
        h = _unit(np.array([p_WE[0] - self.base_xyz[0], p_WE[1] - self.base_xyz[1], 0.0]))
        return np.cos(tilt) * h + np.array([0.0, 0.0, -np.sin(tilt)])

    def handover(self, task: str, wrist: np.ndarray) -> np.ndarray:
        """Joint angles (7,) handing over near the final wrist position (3,), seeded by the grasp."""
        tcfg = self._task(task)
        p = self.handover_position(task, wrist)
        axis = self.handover_axis(task, p)
        theta = np.deg2rad(tcfg.handover_tolerance_deg)
        q_grasp = self.grasp(task)
        for tol_scale, seed in ((1.0, q_grasp), (2.0, q_grasp), (2.0, self.home)):
            q = self.solve(p, axis_W=axis, theta_bound=min(tol_scale * theta, np.pi / 2),
                           pos_tol=0.005 * tol_scale, seed=seed)
            if q is not None:
                if tol_scale > 1.0:
                    log.debug("handover IK of %s needed relaxed tolerances at %s", task, p)
                return q
        raise RuntimeError(f"inverse kinematics found no handover for task {task!r} at {np.round(p, 3).tolist()}")


@functools.lru_cache(maxsize=1)
def salad_robot() -> SaladRobot:
    """The robot of ``models/salad/scene.yaml`` (built once per process; grasp solutions are cached)."""
    return SaladRobot(load_scene_config())


def grasp_configuration(task: str) -> np.ndarray:
    """IIWA7 joint angles, shape (7,), of the task's grasp pose (IK solved once, cached)."""
    return salad_robot().grasp(task).copy()


def handover_position(task: str, wrist) -> np.ndarray:
    """Flange position (3,) of the handover for the person's final wrist position (3,)."""
    return salad_robot().handover_position(task, np.asarray(wrist, float))
