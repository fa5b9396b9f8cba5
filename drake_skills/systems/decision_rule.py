"""``DecisionRule``: when the gating decides, and the YAML schema of ``SimConfig.decision``."""
# No "from __future__ import annotations": yaml_load_typed reads the real field types.

from dataclasses import dataclass
from typing import Optional

import numpy as np


@dataclass
class DecisionRule:
    """When the gating answers: while the person moves (anticipation) and when the motion is over.

    All distances are in normalized workspace units (Eq. 14: the workspace
    spans [0, 10]), so one setting carries across subjects. The gating keeps
    its own copy, so changing a rule after building a system changes nothing.
    """

    # the wrist must first get this far from its start position
    min_travel: float = 1.0
    # ... and then stay within still_radius of its last position for this long (s)
    still_duration: float = 0.4
    # radius of "still"
    still_radius: float = 0.05
    # decide at this time after the first sample (s) whatever the motion does; null: when it is over
    decision_time: Optional[float] = None
    # decide at the latest this long after the first sample (s), motion over or not
    timeout: float = 10.0
    # re-decide from the growing prefix while the person moves, commit as soon as the answer
    # is a skill (false: decide once, when the motion is over)
    anticipate: bool = True
    # seconds between two re-decisions while the person moves (exact in binary)
    redecide_period: float = 0.0625
    # consecutive equal answers needed to commit to a skill, to switch to another one, or to
    # give it up ("unknown")
    confirmations: int = 2
    # no acceptable wrist sample for longer than this (s; NaN, stale, outliers: see
    # drake_skills.systems.normalizer) and the wrist is lost: the robot holds
    lost_timeout: float = 0.5
    # the wrist at rest while the committed skill's estimated phase is below this: a pause,
    # perhaps, not the end; a whole-motion answer then that names another skill is not
    # trusted ("undecided": the robot holds and asks) -- the whole-motion test assumes a
    # complete motion, and a prefix taken for one can look like another skill
    end_phase: float = 0.8

    def __post_init__(self):
        for name in ("min_travel", "still_duration", "still_radius", "timeout", "redecide_period", "lost_timeout"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"DecisionRule.{name} must be positive, got {v!r}")
        if not (np.isfinite(self.end_phase) and 0.0 <= self.end_phase <= 1.0):
            raise ValueError(f"DecisionRule.end_phase must be in [0, 1], got {self.end_phase!r}")
        if isinstance(self.confirmations, bool) or int(self.confirmations) != self.confirmations \
                or self.confirmations < 1:
            raise ValueError(f"DecisionRule.confirmations must be an integer >= 1, got {self.confirmations!r}")
        self.confirmations = int(self.confirmations)
        if self.decision_time is not None and not self.decision_time > 0:
            raise ValueError(f"DecisionRule.decision_time must be positive or None, got {self.decision_time!r}")
