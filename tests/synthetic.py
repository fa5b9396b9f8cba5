"""Synthetic coupled demonstrations for tests (fast, no Drake); importable as `synthetic`."""
import numpy as np


from drake_skills import Demonstration
from drake_skills.data.workspace import Workspace

#: The synthetic demos are in normalized units already: this workspace maps them to themselves (up to rounding).
WORKSPACE = Workspace(np.zeros(3), np.full(3, 10.0))
#: Goal of each synthetic skill in normalized units (the workspace is [0, 10]).
GOALS = np.array([[6.0, 2.0, 1.0], [1.0, 6.0, 3.0], [-4.0, 3.0, 4.0], [2.0, -5.0, 2.0]])


def synthetic_demo(task: int, rng, *, T: int = 120, noise: float = 0.15, robot: bool = True, scale: float = 1.0):
    """A minimum-jerk reach to GOALS[task] with a task-specific bend; robot joints follow the goal."""
    t = np.linspace(0.0, 1.2 * scale, T)
    z = t / t[-1]
    s = 10 * z ** 3 - 15 * z ** 4 + 6 * z ** 5
    goal = GOALS[task] + rng.normal(0, noise, 3)
    bend = np.outer(np.sin(np.pi * z), [0.0, 0.0, 1.5 * (task % 2) - 0.5])
    human = np.outer(s, goal) + bend + rng.normal(0, 0.005, (T, 3))
    q = None
    if robot:
        q = np.outer(s, np.r_[0.1 * goal, 0.05 * goal[:2], 0.3 * task, -0.2]) + 0.001 * rng.standard_normal((T, 7))
    return Demonstration(t=t, human=human, robot=q, task=str(task), name=f"synthetic_{task}")
