"""``LcmConfig``: channels, rates and the simulated bus of the LCM interface (``SimConfig.lcm``)."""
# No "from __future__ import annotations": yaml_load_typed reads the real field types.

from dataclasses import dataclass

import numpy as np


@dataclass
class LcmConfig:
    """How the controller and the (simulated) robot talk over LCM.

    Channel names and the iiwa messages are those of Drake's iiwa driver
    (``drake-iiwa-driver``, ``BuildIiwaControl``); the wrist channel carries
    ``lcmt_drake_signal`` (``drake_skills.systems.wrist_sender``).
    """

    # LCM URL: memq:// is an in-process queue (nothing leaves the process); udpm://... a real bus
    url: str = "memq://"
    # lcmt_iiwa_status from the robot (measured joints, 200 Hz on a real iiwa)
    status_channel: str = "IIWA_STATUS"
    # lcmt_iiwa_command to the robot (joint positions, radians)
    command_channel: str = "IIWA_COMMAND"
    # lcmt_drake_signal from the wrist tracker (p_WH, metres)
    wrist_channel: str = "DRAKE_SKILLS_WRIST"
    # period of the commands (s): the iiwa driver's FRI period (kIiwaLcmStatusPeriod, 5 ms; not exact in binary)
    command_period: float = 0.005
    # period of the simulated robot's status messages (s), as the real driver's
    status_period: float = 0.005
    # period of the simulated tracker's wrist messages (s), exact in binary (128 Hz)
    wrist_period: float = 1.0 / 128.0
    # a status older than this (s) makes the controller hold the commanded position
    stale_timeout: float = 0.1
    # simulated bus only: latency added to every message (status, command, wrist), seconds
    latency: float = 0.0
    # simulated bus only: fraction of wrist messages dropped at random (seeded by SimConfig.seed)
    wrist_drop: float = 0.0
    # drake-skills control: seconds of wall time to wait for the first status and wrist messages
    wait_for_messages: float = 10.0

    def __post_init__(self):
        for name in ("command_period", "status_period", "wrist_period", "stale_timeout", "wait_for_messages"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"LcmConfig.{name} must be positive, got {v!r}")
        if not (np.isfinite(self.latency) and self.latency >= 0):
            raise ValueError(f"LcmConfig.latency must be >= 0, got {self.latency!r}")
        if not 0 <= self.wrist_drop < 1:
            raise ValueError(f"LcmConfig.wrist_drop must be in [0, 1), got {self.wrist_drop!r}")
        channels = [self.status_channel, self.command_channel, self.wrist_channel]
        if len(set(channels)) != 3 or not all(channels):
            raise ValueError(f"LcmConfig: the three channels must be distinct non-empty names, got {channels}")
        if "://" not in self.url:
            raise ValueError(f"LcmConfig.url must be an LCM URL such as memq:// or udpm://..., got {self.url!r}")

    @property
    def impaired(self) -> bool:
        """Does the simulated bus add latency or drop messages?"""
        return self.latency > 0 or self.wrist_drop > 0
