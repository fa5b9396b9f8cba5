"""Synthetic coupled skills at any number: 3-D wrist paths and 7-joint robot motions.

For measuring the library at scale (``drake-skills eval scale``, ``drake-skills bench
--suite scale``): K skills whose distance is known and whose within-skill scatter is
far below it, so a library that holds at any K should find exactly K components.

* The human path of skill k starts at the origin (in normalized units, so it needs no
  workspace) and is a sum of four sine bumps, ``y_k(z) = sum_j sin(pi z (j + 1) / 2)
  a_kj`` with ``a_kj ~ U(-6, 6)^3``; paths are drawn with rejection until every pair
  is at least ``separation`` apart (RMS over the samples of the path difference).
* A demonstration of skill k adds a smooth deviation,
  ``sin(pi z) e_1 + z e_2`` with ``e_1 ~ N(0, (1.4 scatter)^2 I)``, ``e_2 ~ N(0, scatter^2 I)``.
* The robot (``dim_robot`` joints, radians) moves along a minimum-jerk profile to a
  skill-specific goal with a skill-specific bend, plus ``robot_scatter`` per demonstration.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_skills.data.demonstration import Demonstration

#: Amplitude bound of the sine bumps of a human path (normalized units).
AMPLITUDE = 6.0
#: Number of sine bumps of a human path.
N_BUMPS = 4


def _random_state(random_state) -> np.random.Generator:
    if isinstance(random_state, np.random.Generator):
        return random_state
    return np.random.default_rng(random_state)


@dataclass(frozen=True, eq=False)
class SkillBank:
    """K synthetic skills: their mean human paths and robot motions.

    Attributes
    ----------
    human : array, shape (K, T, 3)
        Mean wrist path of each skill, normalized units, starting at the origin.
    robot_goal : array, shape (K, D_r)
        Final joint positions (radians).
    robot_bend : array, shape (K, D_r)
        Mid-motion deviation of the joints (radians).
    duration : float
        Seconds per demonstration.
    """

    human: np.ndarray
    robot_goal: np.ndarray
    robot_bend: np.ndarray
    duration: float

    @property
    def n_skills(self) -> int:
        return self.human.shape[0]

    @property
    def n_samples(self) -> int:
        return self.human.shape[1]

    def min_separation(self) -> float:
        """Smallest RMS distance between two skills' mean paths (inf for one skill)."""
        if self.n_skills < 2:
            return float("inf")
        X = self.human.reshape(self.n_skills, -1)
        sq = np.sum(X * X, axis=1)
        d2 = (sq[:, None] + sq[None, :] - 2.0 * X @ X.T) / self.n_samples
        np.fill_diagonal(d2, np.inf)
        return float(np.sqrt(max(d2.min(), 0.0)))

    def demo(self, k: int, rng, *, scatter: float = 0.03, robot_scatter: float = 0.02) -> Demonstration:
        """One demonstration of skill ``k``: the skill's paths plus smooth per-demonstration deviations."""
        if not 0 <= int(k) < self.n_skills:
            raise ValueError(f"skill {k} is not in 0..{self.n_skills - 1}")
        rng = _random_state(rng)
        T = self.n_samples
        z = np.linspace(0.0, 1.0, T)
        bump = np.sin(np.pi * z)
        human = self.human[k] + np.outer(bump, rng.normal(0.0, 1.4 * scatter, 3)) \
            + np.outer(z, rng.normal(0.0, scatter, 3))
        s = 10 * z ** 3 - 15 * z ** 4 + 6 * z ** 5
        D_r = self.robot_goal.shape[1]
        goal = self.robot_goal[k] + rng.normal(0.0, robot_scatter, D_r)
        robot = np.outer(s, goal) + np.outer(bump, self.robot_bend[k])
        return Demonstration(t=z * self.duration, human=human, robot=robot, task=str(k), subject="synthetic",
                             name=f"synthetic/{k}")


def skill_bank(n_skills: int, random_state=None, *, separation: float = 1.5, n_samples: int = 100,
               dim_robot: int = 7, duration: float = 1.5, max_tries: int = 200) -> SkillBank:
    """Draw ``n_skills`` skills whose mean human paths are at least ``separation`` apart (RMS).

    Parameters
    ----------
    n_skills : int
        K >= 1.
    random_state : None, int or numpy Generator
    separation : float
        Smallest RMS distance between two mean paths (normalized units).
    n_samples : int
        Samples per path (T).
    dim_robot : int
        D_r, robot joints.
    duration : float
        Seconds per demonstration.
    max_tries : int
        Rejected draws allowed per skill before giving up (ValueError).

    Returns
    -------
    SkillBank
    """
    if isinstance(n_skills, bool) or int(n_skills) != n_skills or n_skills < 1:
        raise ValueError(f"n_skills must be an integer >= 1, got {n_skills!r}")
    if not separation >= 0:
        raise ValueError(f"separation must be >= 0, got {separation!r}")
    if int(n_samples) != n_samples or n_samples < 5:
        raise ValueError(f"n_samples must be an integer >= 5, got {n_samples!r}")
    rng = _random_state(random_state)
    T = int(n_samples)
    z = np.linspace(0.0, 1.0, T)
    B = np.stack([np.sin(np.pi * z * (j + 1) / 2) for j in range(N_BUMPS)], axis=1)  # (T, N_BUMPS)
    paths = np.empty((int(n_skills), T * 3))
    sq = np.empty(int(n_skills))
    n = 0
    tries = 0
    limit = separation ** 2 * T
    while n < n_skills:
        p = (B @ rng.uniform(-AMPLITUDE, AMPLITUDE, (N_BUMPS, 3))).reshape(-1)
        pp = float(p @ p)
        if n and np.min(sq[:n] + pp - 2.0 * paths[:n] @ p) < limit:
            tries += 1
            if tries > max_tries:
                raise ValueError(f"could not place skill {n + 1} of {n_skills} at least {separation} apart "
                                 f"after {max_tries} draws")
            continue
        paths[n], sq[n] = p, pp
        n, tries = n + 1, 0
    goal = rng.uniform(-1.5, 1.5, (int(n_skills), int(dim_robot)))
    bend = rng.uniform(-0.5, 0.5, (int(n_skills), int(dim_robot)))
    return SkillBank(paths.reshape(int(n_skills), T, 3), goal, bend, float(duration))
