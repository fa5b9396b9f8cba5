"""``DecisionRule``: when the gating decides, and the YAML schema of ``SimConfig.decision``."""
# No "from __future__ import annotations": yaml_load_typed reads the real field types.

from dataclasses import dataclass
from typing import Optional

import numpy as np


@dataclass
class DecisionRule:
    """When is the person's motion over?

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

    def __post_init__(self):
        for name in ("min_travel", "still_duration", "still_radius", "timeout"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"DecisionRule.{name} must be positive, got {v!r}")
        if self.decision_time is not None and not self.decision_time > 0:
            raise ValueError(f"DecisionRule.decision_time must be positive or None, got {self.decision_time!r}")
