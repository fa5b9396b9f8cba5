"""``WorkspaceNormalizer``: Eq. (14) applied on line to the observed wrist, once for the whole Diagram.

It is also where a misbehaving tracker's samples are screened (:func:`screen_sample`,
settings :class:`SampleRule`): a sample is rejected when it is NaN or inf, when it is
not new (its measurement time has not advanced past the last sample's: a dropout or
a stale repeat), or when it lies farther from the last accepted sample than the wrist
can move in the time between them (``min(max_speed * dt, max_jump) + tolerance``: an
outlier jump; a wrist that jumped for good, e.g. to another person, stays rejected).
A rejected sample is output as NaN, which the gating skips: the observed motion is
bridged over the gap (it is resampled by arc length, so a gap costs nothing), and a
gap longer than the gating's ``lost_timeout`` makes the robot hold
(:func:`drake_skills.systems.gating.gating_step`).

The first sample of a trial has no accepted sample to be checked against, and a
tracker's glitch there would become the start of Eq. (14) and the reference of every
later check (a glitch farther than ``max_jump`` would reject the real wrist for the
whole trial). So a trial's start is **confirmed** (:func:`start_chain`): it is the first
of :data:`CONFIRM_SAMPLES` new samples in a row each within the speed bound of the one
before (longer than the 1-3 frames a glitch lasts); until then the samples are
rejected as ``"unconfirmed"``. Without a speed bound (``rule=None``) the first sample
is the start, as before. Two limits, kept for safety (a wrist that jumped to another
person must not be followed): a glitch that holds still for 4 or more ticks at a trial's
start (62 ms at 64 Hz) becomes the start, and a wrist that moved farther than
``max_jump`` while the tracker lost it stays rejected; either ends the trial "lost" (the
robot holds) after the gating's ``lost_timeout``.
"""
# No "from __future__ import annotations": yaml_load_typed reads SampleRule's real field types (SimConfig.wrist).

from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from drake_skills.data.workspace import Workspace

#: Period of the start-position latch (s); exact in binary.
LATCH_PERIOD = 1.0 / 64.0


@dataclass
class SampleRule:
    """Which wrist samples the controller accepts (``SimConfig.wrist``); metres and seconds."""

    # fastest the wrist is taken to move (m/s); a hand reaching fast peaks near 2 m/s
    max_speed: float = 3.0
    # largest distance accepted from the last accepted sample, however long ago (m)
    max_jump: float = 0.25
    # allowance for tracker noise on top of the speed bound (m)
    tolerance: float = 0.02

    def __post_init__(self):
        for name in ("max_speed", "max_jump", "tolerance"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"SampleRule.{name} must be positive, got {v!r}")


#: New samples in a row, each within the speed bound of the one before, that confirm a
#: trial's start (a tracker's glitch lasts 1-3 frames: ``promp.preprocessing.spike_samples``).
CONFIRM_SAMPLES = 4


def start_chain(p: np.ndarray, stamp: float, chain_last: np.ndarray | None, chain_stamp: float, count: int,
                rule: SampleRule | None) -> int:
    """How many samples in a row, ending with ``p``, move within the speed bound of the one before.

    The start of a trial is confirmed when this reaches :data:`CONFIRM_SAMPLES`
    (without a speed bound, ``rule=None``, at once). ``p`` must be a sample
    :func:`screen_sample` found neither NaN nor stale.

    Parameters
    ----------
    p : array, shape (D,)
        Raw position (m).
    stamp : float
        When it was measured (s).
    chain_last : array, shape (D,), or None
        The last sample of the chain so far (None: no chain yet).
    chain_stamp : float
        Its stamp; a ``p`` with this stamp is that sample (already counted).
    count : int
        Samples in the chain so far.
    rule : SampleRule or None

    Returns
    -------
    int
        The chain's length with ``p``: ``count + 1`` if ``p`` continues it, 1 if it
        starts a new one (a sample that jumped from the chain, or the first),
        ``CONFIRM_SAMPLES`` at once without a rule.
    """
    if rule is None:
        return CONFIRM_SAMPLES
    if chain_last is None or count < 1:
        return 1
    if stamp == chain_stamp:
        return int(count)
    return int(count) + 1 if screen_sample(p, stamp, chain_last, chain_stamp, None, rule) == "" else 1


def screen_sample(p: np.ndarray, stamp: float, last_good: np.ndarray | None, last_good_stamp: float,
                  last_seen_stamp: float | None, rule: SampleRule) -> str:
    """Accept or reject one raw wrist sample; returns "" (accepted) or why not ("nan", "stale", "outlier").

    Parameters
    ----------
    p : array, shape (D,)
        Raw position (m).
    stamp : float
        When it was measured (s).
    last_good : array, shape (D,), or None
        The last accepted sample (None: none yet).
    last_good_stamp : float
        Its stamp.
    last_seen_stamp : float or None
        Stamp of the last sample seen, accepted or not (None: none yet).
    rule : SampleRule or None
        None: no speed bound (positions not in metres); NaN and stale samples are
        still rejected.
    """
    p = np.asarray(p, float)
    if not np.isfinite(p).all() or not np.isfinite(stamp):
        return "nan"
    if last_seen_stamp is not None and stamp <= last_seen_stamp:
        return "stale"
    if last_good is not None and rule is not None:
        bound = min(rule.max_speed * max(stamp - last_good_stamp, 0.0), rule.max_jump) + rule.tolerance
        if float(np.linalg.norm(p - last_good)) > bound:
            return "outlier"
    return ""


def normalized_relative(workspace: Workspace, p: np.ndarray, start_normalized: np.ndarray | None, *,
                        subtract_start: bool = True) -> np.ndarray:
    """Eq. (14) for one sample: ``workspace.normalize(p)`` minus the normalized start position.

    Parameters
    ----------
    workspace : Workspace
    p : array, shape (D,)
        Raw position.
    start_normalized : array, shape (D,), or None
        The normalized start; None (no start seen yet) makes ``p`` its own start,
        so the result is zero.
    subtract_start : bool
        False leaves the start in (a library with ``subtract_start=False``).

    Returns
    -------
    array, shape (D,)
    """
    pn = workspace.normalize(np.asarray(p, float).reshape(1, -1), subtract_start=False)[0]
    if not subtract_start:
        return pn
    if start_normalized is None:
        return np.zeros_like(pn)
    return pn - start_normalized


class WorkspaceNormalizer(LeafSystem):
    """The wrist in the subject's normalized workspace, relative to its start position (Eq. 14).

    .. pydrake_system::

        name: WorkspaceNormalizer
        input_ports:
        - human_wrist
        - wrist_time (only with timestamped=True)
        output_ports:
        - normalized_wrist

    The output is in the library's normalized units, so the systems downstream
    hand it to the library as is (``normalized=True``): the Diagram normalizes
    once. The start position is the first sample of a trial (a context reset)
    that the next :data:`CONFIRM_SAMPLES` - 1 new samples continue within the
    speed bound (:func:`start_chain`; the first sample at all without a
    ``rule``): the chain begins at an initialization event (or, should the input
    only become valid later, at the first periodic update that finds a valid
    sample) and is kept in discrete state. Until the start is confirmed the
    output is NaN (the gating skips it: a delay of 3 ticks, 47 ms).

    Parameters
    ----------
    workspace : Workspace
        The subject's workspace (from calibration).
    subtract_start : bool
        Subtract the start position (the library's ``config.subtract_start``).
    rule : SampleRule, optional
        The speed bound of the screen (see the module docstring), for a wrist in
        metres (the controller passes ``SimConfig.wrist``); None: NaN and stale
        samples only. A rejected sample is output as NaN. The screening state
        advances every 1/64 s (the gating's period).
    timestamped : bool
        Read the measurement time of each sample from ``wrist_time`` (1,), s; without
        it every sample counts as new (no stale detection).
    """

    def __init__(self, workspace: Workspace, *, subtract_start: bool = True, rule: SampleRule | None = None,
                 timestamped: bool = False):
        super().__init__()
        if not isinstance(workspace, Workspace):
            raise ValueError(f"workspace must be a Workspace, got {type(workspace).__name__}")
        self._workspace = workspace
        self._subtract_start = bool(subtract_start)
        if rule is not None and not isinstance(rule, SampleRule):
            raise ValueError(f"rule must be a SampleRule or None, got {type(rule).__name__}")
        self._rule = rule
        dim = self._dim = workspace.dim
        self._wrist = self.DeclareVectorInputPort("human_wrist", dim)
        self._time = self.DeclareVectorInputPort("wrist_time", 1) if timestamped else None
        # [start_normalized (dim); start confirmed; last good raw sample (dim); its stamp; last seen stamp;
        #  has good; has seen; last sample of the start chain (dim); its stamp; the chain's length]
        self._state = self.DeclareDiscreteState(3 * dim + 7)
        self.DeclareInitializationDiscreteUpdateEvent(self._latch)
        self.DeclarePeriodicDiscreteUpdateEvent(LATCH_PERIOD, 0.0, self._update)
        self.DeclareForcedDiscreteUpdateEvent(self._update)
        self._out = self.DeclareVectorOutputPort("normalized_wrist", dim, self._calc_normalized,
                                                 prerequisites_of_calc={self.all_sources_ticket()})

    @property
    def workspace(self) -> Workspace:
        return self._workspace

    @property
    def rule(self) -> SampleRule | None:
        return self._rule

    def _screen(self, context: Context) -> tuple[np.ndarray, float, str, int]:
        """The input sample, its stamp, the verdict against the state and the start chain's length with it.

        The verdict is :func:`screen_sample`'s, or ``"unconfirmed"`` for a sample that
        passes it while the trial's start is not yet confirmed (:func:`start_chain`).
        """
        x = context.get_discrete_state(self._state).get_value()
        D = self._dim
        p = np.asarray(self._wrist.Eval(context), float)
        stamp = float(self._time.Eval(context)[0]) if self._time is not None else context.get_time()
        confirmed = x[2 * D + 3] > 0.5
        good = np.array(x[D + 1:2 * D + 1]) if confirmed else None
        seen = float(x[2 * D + 2]) if x[2 * D + 4] > 0.5 and self._time is not None else None  # no stamps: all new
        verdict = screen_sample(p, stamp, good, float(x[2 * D + 1]), seen, self._rule)
        chain = 0
        if verdict == "" and not confirmed:
            count = int(round(x[3 * D + 6]))
            last = np.array(x[2 * D + 5:3 * D + 5]) if count > 0 else None
            chain = start_chain(p, stamp, last, float(x[3 * D + 5]), count, self._rule)
            if chain < CONFIRM_SAMPLES:
                verdict = "unconfirmed"
        return p, stamp, verdict, chain

    def start(self, context: Context) -> np.ndarray | None:
        """The normalized start position, or None before the trial's start is confirmed."""
        x = context.get_discrete_state(self._state).get_value()
        return None if x[self._dim] < 0.5 else np.array(x[:self._dim])

    def _latch(self, context: Context, discrete_state: DiscreteValues) -> None:
        """At initialization: the first sample of a trial begins the start chain (the screening state starts afresh).

        Without a speed bound it is the start; with one the chain must reach
        :data:`CONFIRM_SAMPLES` (:meth:`_update`).
        """
        x = np.array(context.get_discrete_state(self._state).get_value())
        D = self._dim
        p = np.asarray(self._wrist.Eval(context), float)
        stamp = float(self._time.Eval(context)[0]) if self._time is not None else context.get_time()
        if x[D] >= 0.5 or x[3 * D + 6] > 0.5 or not np.isfinite(p).all() or not np.isfinite(stamp):
            return
        x[:D] = self._workspace.normalize(p.reshape(1, -1), subtract_start=False)[0]
        if self._rule is None:
            x[D] = 1.0
        else:
            x[2 * D + 5:3 * D + 5], x[3 * D + 5], x[3 * D + 6] = p, stamp, 1.0
        discrete_state.get_mutable_vector(self._state).SetFromVector(x)

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        x = np.array(context.get_discrete_state(self._state).get_value())
        D = self._dim
        p, stamp, verdict, chain = self._screen(context)
        if np.isfinite(stamp):
            x[2 * D + 2], x[2 * D + 4] = stamp, 1.0
        if verdict == "unconfirmed" or (verdict == "" and x[2 * D + 3] < 0.5):
            if x[D] < 0.5 and (chain == 1 or x[3 * D + 6] < 0.5):  # a new chain: this sample would be the start
                x[:D] = self._workspace.normalize(p.reshape(1, -1), subtract_start=False)[0]
            x[2 * D + 5:3 * D + 5], x[3 * D + 5], x[3 * D + 6] = p, stamp, float(chain)
        if verdict == "":
            x[D + 1:2 * D + 1], x[2 * D + 1], x[2 * D + 3] = p, stamp, 1.0
            x[D] = 1.0  # the start (the chain's first sample) is confirmed
        discrete_state.get_mutable_vector(self._state).SetFromVector(x)

    def _calc_normalized(self, context: Context, output: BasicVector) -> None:
        p, _, verdict, _ = self._screen(context)
        if verdict:
            output.SetFromVector(np.full(self._dim, np.nan))
            return
        x = context.get_discrete_state(self._state).get_value()
        D = self._dim
        # the start, or the chain's first sample when this sample confirms it (the update runs after this read)
        start = np.array(x[:D]) if x[D] > 0.5 or x[3 * D + 6] > 0.5 else None
        output.SetFromVector(normalized_relative(self._workspace, p, start, subtract_start=self._subtract_start))
