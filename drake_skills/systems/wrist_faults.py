"""A tracker that misbehaves: dropouts, stale repeats, NaN, outlier jumps and latency of the live wrist.

:class:`TrackerFaults` (the ``faults:`` node of ``SimConfig``) says how often each
fault happens; :func:`tracker_feed` turns a replayed :class:`~drake_skills.systems.wrist_source.WristTrial`
into what such a tracker delivers, a :class:`TrackerFeed`: at each tick of the tracker
(``period``) a position and the time it was measured (its stamp):

* dropout: no new message for ``dropout_duration``: the receiver keeps the last one (its stamp stops);
* stale repeat: the tracker re-sends its last measurement, stamp and all;
* NaN: the marker is lost for a tick; the position is NaN;
* outlier: the position jumps ``outlier_distance`` metres in a random direction for a
  tick (another person, a reflection);
* latency: every sample arrives ``latency`` seconds after it was measured;
* start glitch: the first ``start_glitch_ticks`` ticks of every trial are ``outlier_distance``
  metres off in one random direction (the tracker finds the wrist in the wrong place before it
  locks on; the normalizer confirms a start only after 4 consistent samples).

Faults start at random ticks (a Poisson process per fault, ``*_rate`` per second,
seeded), so a feed is reproducible. What the controller does with them is the rule of
:func:`drake_skills.systems.normalizer.screen_sample` and of the gating's lost-wrist
timeout (:class:`~drake_skills.systems.decision_rule.DecisionRule` ``lost_timeout``).
"""
# No "from __future__ import annotations": yaml_load_typed reads the real field types.

import math
from dataclasses import dataclass

import numpy as np

#: The fault kinds, as ``drake-skills demo --faults`` names them.
FAULT_KINDS = ("dropout", "stale", "nan", "outlier", "latency", "start")


#: The rates ``drake-skills demo --faults KIND,...`` sets for each kind.
PRESETS = {"dropout": {"dropout_rate": 0.5}, "stale": {"stale_rate": 0.5}, "nan": {"nan_rate": 2.0},
           "outlier": {"outlier_rate": 2.0}, "latency": {"latency": 0.05}, "start": {"start_glitch_ticks": 3}}


def faults_from_spec(spec: str) -> "TrackerFaults":
    """``"nan,outlier"`` (or ``"all"``) as TrackerFaults at the :data:`PRESETS` rates."""
    kinds = FAULT_KINDS if spec.strip() == "all" else [k.strip() for k in spec.split(",") if k.strip()]
    bad = sorted(set(kinds) - set(FAULT_KINDS))
    if bad or not kinds:
        raise ValueError(f"--faults takes a comma-separated list of {', '.join(FAULT_KINDS)} (or all), got {spec!r}")
    fields = {}
    for k in kinds:
        fields.update(PRESETS[k])
    return TrackerFaults(**fields)


@dataclass
class TrackerFaults:
    """How often the simulated wrist tracker misbehaves (all zero: a perfect tracker)."""

    # dropouts per second (no new message for dropout_duration)
    dropout_rate: float = 0.0
    # length of a dropout (s)
    dropout_duration: float = 0.2
    # stale repeats per second (the last measurement re-sent for stale_duration)
    stale_rate: float = 0.0
    # length of a stale repeat (s)
    stale_duration: float = 0.1
    # NaN samples per second (one tick each)
    nan_rate: float = 0.0
    # outlier jumps per second (one tick each)
    outlier_rate: float = 0.0
    # size of an outlier jump (m)
    outlier_distance: float = 1.0
    # delay of every sample (s)
    latency: float = 0.0
    # period of the tracker's samples (s), exact in binary (128 Hz)
    period: float = 1.0 / 128.0
    # ticks at the start of every trial delivered outlier_distance off (one direction per trial)
    start_glitch_ticks: int = 0

    def __post_init__(self):
        for name in ("dropout_rate", "stale_rate", "nan_rate", "outlier_rate", "latency", "outlier_distance"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"TrackerFaults.{name} must be >= 0, got {v!r}")
        for name in ("dropout_duration", "stale_duration", "period"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"TrackerFaults.{name} must be positive, got {v!r}")
        v = self.start_glitch_ticks
        if isinstance(v, bool) or not float(v).is_integer() or v < 0:
            raise ValueError(f"TrackerFaults.start_glitch_ticks must be an integer >= 0, got {v!r}")
        self.start_glitch_ticks = int(v)

    @property
    def any(self) -> bool:
        """Does the tracker misbehave at all?"""
        return any(getattr(self, n) > 0 for n in ("dropout_rate", "stale_rate", "nan_rate", "outlier_rate",
                                                  "latency", "start_glitch_ticks"))


@dataclass(frozen=True, eq=False)
class TrackerFeed:
    """What the tracker delivers, tick by tick (simulation times).

    Attributes
    ----------
    times : array, shape (n,)
        Tick times (s, simulation clock).
    positions : array, shape (n, 3)
        Delivered wrist positions (m); NaN where the marker was lost.
    stamps : array, shape (n,)
        When each delivered position was measured (s); it does not advance during a
        dropout or a stale repeat.
    kinds : array of str, shape (n,)
        The fault of each tick ("" for none).
    """

    times: np.ndarray
    positions: np.ndarray
    stamps: np.ndarray
    kinds: np.ndarray

    def at(self, time: float) -> tuple[np.ndarray, float]:
        """Position (3,) and stamp delivered at simulation ``time`` (the last tick at or before it)."""
        i = int(np.searchsorted(self.times, time + 1e-12, side="right")) - 1
        i = min(max(i, 0), self.times.shape[0] - 1)
        return self.positions[i].copy(), float(self.stamps[i])


def tracker_feed(trial, faults: TrackerFaults, rng, *, margin: float = 2.0) -> TrackerFeed:
    """The feed of a faulty tracker watching ``trial`` (a WristTrial), from its start to ``margin`` s after its end.

    Parameters
    ----------
    trial : WristTrial
    faults : TrackerFaults
    rng : numpy Generator
    margin : float
        Seconds of feed after the trial's last sample (the wrist held still).
    """
    from drake_skills.systems.wrist_source import wrist_at

    if not isinstance(faults, TrackerFaults):
        raise ValueError(f"faults must be TrackerFaults, got {type(faults).__name__}")
    dt = faults.period
    n = int(math.ceil((trial.end_time - trial.start_time + margin) / dt)) + 1
    times = trial.start_time + dt * np.arange(n)
    stamps = times - faults.latency
    positions = np.stack([wrist_at(trial, t) for t in stamps])
    kinds = np.full(n, "", dtype=object)

    def starts(rate):
        return np.flatnonzero(rng.random(n) < rate * dt)

    for kind, rate, length in (("dropout", faults.dropout_rate, faults.dropout_duration),
                               ("stale", faults.stale_rate, faults.stale_duration)):
        for i in starts(rate):
            j = min(n, i + max(1, int(round(length / dt))))
            if i == 0:
                continue
            positions[i:j] = positions[i - 1]
            stamps[i:j] = stamps[i - 1]
            kinds[i:j] = kind
    for i in starts(faults.nan_rate):
        positions[i] = np.nan
        kinds[i] = "nan"
    for i in starts(faults.outlier_rate):
        u = rng.normal(size=3)
        positions[i] = positions[i] + faults.outlier_distance * u / np.linalg.norm(u)
        kinds[i] = "outlier"
    if faults.start_glitch_ticks:
        u = rng.normal(size=3)
        k = min(n, faults.start_glitch_ticks)
        positions[:k] = positions[:k] + faults.outlier_distance * u / np.linalg.norm(u)
        kinds[:k] = "start"
    for a in (times, positions, stamps, kinds):
        a.setflags(write=False)
    return TrackerFeed(times, positions, stamps, kinds)
