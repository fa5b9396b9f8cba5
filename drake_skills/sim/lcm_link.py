"""``LcmLink``: a simulated network hop between two LCM channels, with latency, random drops and outages.

The station and the controller of ``drake-skills demo --transport lcm`` share one
in-process bus (``memq://``), where a message is delivered at the next step of the
simulation. To test the controller on a worse network, the station publishes on its
own channel names and one link per channel relays to the controller's names (and back
for the command), holding every message for ``latency`` seconds of simulated time and
dropping a fraction of them at random.

A link is part of the simulated world, not of the Diagram's state: it keeps its queue
in the object (as the bus itself does) and relays in a periodic publish event every
``period`` seconds, so a message's arrival is known to within one period.
"""
from __future__ import annotations

import collections
import math

import numpy as np
from pydrake.lcm import DrakeLcm
from pydrake.systems.framework import Context, LeafSystem

#: Default relay period (s), exact in binary (about 1 ms, the plant's step).
LINK_PERIOD = 1.0 / 1024.0


class LcmLink(LeafSystem):
    """Relays ``source`` to ``target`` on ``lcm`` after ``latency`` s, dropping a fraction ``drop``.

    .. pydrake_system::

        name: LcmLink
        input_ports: []
        output_ports: []

    Parameters
    ----------
    lcm : DrakeLcm
    source, target : str
        Channel names (distinct).
    latency : float
        Seconds a message is held (simulated time), >= 0.
    drop : float
        Probability in [0, 1) that a message is dropped.
    seed : int
        Seed of the drops.
    period : float
        Seconds between relay events.
    """

    def __init__(self, lcm: DrakeLcm, source: str, target: str, *, latency: float = 0.0, drop: float = 0.0,
                 seed: int = 0, period: float = LINK_PERIOD):
        super().__init__()
        if source == target:
            raise ValueError(f"LcmLink: source and target must differ, got '{source}' twice")
        if not (math.isfinite(latency) and latency >= 0) or not 0 <= drop < 1 or not period > 0:
            raise ValueError(f"LcmLink: need latency >= 0, 0 <= drop < 1, period > 0; got {latency}, {drop}, {period}")
        self._lcm = lcm
        self.source, self.target = source, target
        self.latency, self.drop = float(latency), float(drop)
        self._rng = np.random.default_rng(seed)
        self._queue: collections.deque = collections.deque()  # (time seen, bytes)
        self._latest: bytes | None = None
        self._now = 0.0
        self.blocked = False
        self.received = self.dropped = self.relayed = 0
        self._subscription = lcm.Subscribe(source, self._on_message)
        self.DeclarePeriodicPublishEvent(period, 0.0, self._relay)
        self.set_name(f"lcm_link({source}->{target})")

    def _on_message(self, data: bytes) -> None:
        self.received += 1
        self._latest = bytes(data)
        if self.blocked or (self.drop > 0 and self._rng.random() < self.drop):
            self.dropped += 1
            return
        self._queue.append((self._now, bytes(data)))

    def _relay(self, context: Context) -> None:
        self._now = context.get_time()
        while self._queue and self._queue[0][0] + self.latency <= self._now + 1e-9:
            self._lcm.Publish(self.target, self._queue.popleft()[1])
            self.relayed += 1

    def prime(self, time: float, *, deliver_latest: bool = True) -> None:
        """Start over at ``time``: forget the queue and, if asked, deliver the newest message now (even a dropped one).

        Used at a trial start, when the simulated world is reset and its current
        messages must be on both sides before the controller initializes.
        """
        self._now = float(time)
        self._queue.clear()
        if deliver_latest and self._latest is not None and not self.blocked:
            self._lcm.Publish(self.target, self._latest)
        self._latest = None
