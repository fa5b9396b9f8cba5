"""``SkillGating``: watch the person's motion, then say which skill it is, or "unknown" (Sec. 3.3)."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.common.value import AbstractValue

from drake_skills.systems.shared import Shared
from pydrake.systems.framework import Context, LeafSystem, State

from drake_skills.library.incremental import SkillLibrary
from drake_skills.library.views import StillMotionError
from drake_skills.systems.decision_rule import DecisionRule

log = logging.getLogger(__name__)

#: Period of the sampling and decision update (s); exact in binary.
GATING_PERIOD = 1.0 / 64.0


@dataclass(frozen=True, eq=False)
class ObservedMotion(Shared):
    """The wrist samples seen since the trial start.

    Attributes
    ----------
    times : array, shape (n,)
        Simulation times of the samples (s).
    samples : array, shape (n, D)
        Normalized wrist positions relative to the start (Eq. 14).
    """

    times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    samples: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    @property
    def n(self) -> int:
        return int(self.times.shape[0])

    def append(self, time: float, sample: np.ndarray) -> "ObservedMotion":
        """A new motion with one more sample (this one is not modified)."""
        sample = np.asarray(sample, float).reshape(1, -1)
        samples = sample.copy() if self.n == 0 else np.vstack([self.samples, sample])
        times = np.append(self.times, time)
        samples.setflags(write=False)  # shared between copies of the state (see Shared)
        times.setflags(write=False)
        return ObservedMotion(times, samples)


@dataclass(frozen=True)
class Belief(Shared):
    """One re-decision: what the library said about the motion so far.

    Attributes
    ----------
    time : float
        Simulation time (s).
    status : str
        "skill", "undecided" or "unknown" (:class:`~drake_skills.library.views.Recognition`).
    best : int or None
        The most probable component among those that explain the motion.
    confidence : float
        Its posterior probability.
    phase : float
        Its estimated fraction observed (NaN when unknown).
    posterior : tuple of (int, float)
        (component id, p(k | motion)) for the components that explain the motion.
    restart : int
        The sample the library read the motion from (``Recognition.restart``: after a false
        start); 0: the whole motion.
    """

    time: float
    status: str
    best: int | None
    confidence: float
    phase: float
    posterior: tuple = ()
    restart: int = 0


@dataclass(frozen=True, eq=False)
class GatingDecision(Shared):
    """The gating's state and output: what was observed, what the robot acts on, and why.

    Attributes
    ----------
    motion : ObservedMotion
    component : int or None
        The skill the robot executes now: set when the gating commits (the same skill
        answered ``confirmations`` times in a row), changed when the answers switch to
        another skill, None while nothing is committed or after giving up.
    final : bool
        The motion is over (or timed out) and the last answer is given.
    status : str
        "pending" while observing with nothing committed, "skill" while a skill is
        committed, and at the end the final answer: "skill", "undecided" or "unknown";
        "lost" when no acceptable wrist sample came for longer than the rule's
        ``lost_timeout`` (also after a final answer): the robot holds.
    time : float
        Simulation time the current ``component`` was set (commit or revision) or, when
        final without a skill, of the final answer (NaN before).
    commit_time : float
        When the robot first committed in this trial (NaN if never).
    revisions : int
        How often the committed skill was changed or given up.
    commits : tuple of int
        The skills committed, in order.
    beliefs : tuple of Belief
        Every re-decision of the trial, in order (for plots and the recording).
    responsibilities : dict
        Component id -> p(k | w_h) (Eq. 5) at the last answer.
    last_check : float
        Time of the last re-decision (NaN before).
    streak : tuple (answer, count)
        The last answer (a component id, "unknown" or "undecided") and how often in a row.
    gap_start : float
        Time of the first of the samples rejected in a row since the last acceptable
        (finite) one (NaN when the last sample was acceptable).
    rejected : int
        Samples skipped because they were not acceptable (NaN from the normalizer's screen).
    """

    motion: ObservedMotion = field(default_factory=ObservedMotion)
    component: int | None = None
    final: bool = False
    status: str = "pending"
    time: float = float("nan")
    commit_time: float = float("nan")
    revisions: int = 0
    commits: tuple = ()
    beliefs: tuple = ()
    responsibilities: dict = field(default_factory=dict)
    last_check: float = float("nan")
    streak: tuple = (None, 0)
    gap_start: float = float("nan")
    rejected: int = 0

    @property
    def decided(self) -> bool:
        """The final answer is given (the motion is over)."""
        return self.final

    @property
    def belief(self) -> Belief | None:
        """The last re-decision, or None."""
        return self.beliefs[-1] if self.beliefs else None

    @property
    def restart(self) -> int:
        """The sample the committed skill read the motion from (the last answer that named it; 0: whole)."""
        if self.component is None:
            return 0
        b = next((x for x in reversed(self.beliefs) if x.status == "skill" and x.best == self.component), None)
        return 0 if b is None else b.restart


def motion_is_over(motion: ObservedMotion, rule: DecisionRule) -> bool:
    """Has the wrist moved (``min_travel``) and then stayed still (``still_duration``)?

    Parameters
    ----------
    motion : ObservedMotion
        Samples relative to the start position (the first sample is ~0).
    rule : DecisionRule
    """
    if motion.n < 2:
        return False
    times, y = motion.times, motion.samples
    if _travel(motion) < rule.min_travel:
        return False
    t_end = times[-1]
    if t_end - times[0] < rule.still_duration:
        return False
    window = y[times >= t_end - rule.still_duration - 1e-12]
    return bool(np.all(np.linalg.norm(window - y[-1], axis=1) <= rule.still_radius))


def _travel(motion: ObservedMotion) -> float:
    y = motion.samples
    return float(np.max(np.linalg.norm(y - y[0], axis=1))) if motion.n else 0.0


def should_decide(motion: ObservedMotion, rule: DecisionRule) -> bool:
    """Give the final answer now? At ``decision_time`` or ``timeout`` after the first sample, or when the motion is over."""
    if motion.n == 0:
        return False
    elapsed = motion.times[-1] - motion.times[0]
    if rule.decision_time is not None:
        return elapsed >= rule.decision_time - 1e-12
    return elapsed >= rule.timeout - 1e-12 or motion_is_over(motion, rule)


def should_redecide(state: GatingDecision, motion: ObservedMotion, time: float, rule: DecisionRule) -> bool:
    """Re-decide from the prefix now? With anticipation, every ``redecide_period`` once the wrist has moved."""
    if not rule.anticipate or state.final or motion.n < 2:
        return False
    if not np.isnan(state.last_check) and time - state.last_check < rule.redecide_period - 1e-9:
        return False
    return _travel(motion) >= rule.min_travel


def recognize_motion(library: SkillLibrary, motion: ObservedMotion, *, whole: bool):
    """The library's answer (a :class:`~drake_skills.library.views.Recognition`) for the motion so far.

    Parameters
    ----------
    library : SkillLibrary
        May be empty (then the answer is unknown).
    motion : ObservedMotion
        Samples in the library's normalized units (Eq. 14 applied by the normalizer):
        the library only resamples them.
    whole : bool
        The motion is complete (its weights are tested, ``observed_fraction=1``);
        otherwise it is a prefix whose phase the library estimates.

    Returns
    -------
    Recognition or None
        None when there is nothing to recognize (empty library, no motion, or a noisy wrist whose
        path, walked as the library walks it, has no length: :class:`~drake_skills.library.views.StillMotionError`).
    """
    if library.n_components == 0 or motion.n < 2 or _travel(motion) <= 0.0:
        return None
    try:
        return library.recognize(motion.samples, normalized=True, observed_fraction=1.0 if whole else None)
    except StillMotionError:  # a noisy wrist that never left the walk's tolerance of its mean: no motion yet
        return None


def _paused(state: GatingDecision, motion: ObservedMotion, rule: DecisionRule) -> bool:
    """At rest before the time-out while the last re-decision that named the committed skill put it short of ``rule.end_phase``?

    The last such re-decision, not the last one: one "undecided" during the rest must not
    turn the rule off.
    """
    if rule.decision_time is not None or state.component is None:
        return False
    b = next((x for x in reversed(state.beliefs) if x.status == "skill" and x.best == state.component), None)
    if b is None:
        return False
    elapsed = motion.times[-1] - motion.times[0]
    return elapsed < rule.timeout - 1e-12 and np.isfinite(b.phase) and b.phase < rule.end_phase


def _belief(time: float, rec) -> Belief:
    if rec is None:
        return Belief(float(time), "unknown", None, 0.0, float("nan"))
    post = tuple((int(k), float(p)) for k, p in zip(rec.ids, rec.posterior) if p > 0)
    return Belief(float(time), rec.status, rec.best, rec.confidence, rec.phase, post, int(rec.restart or 0))


def _answer(b: Belief):
    return b.best if b.status == "skill" else b.status


def gating_step(state: GatingDecision, time: float, sample: np.ndarray, library: SkillLibrary,
                rule: DecisionRule) -> GatingDecision:
    """One update: record the sample, re-decide from the prefix when it is time, and answer finally at the end.

    While the person moves (``rule.anticipate``), every ``redecide_period`` the
    library recognizes the prefix (phase estimated); the gating commits to a skill
    once it has been the answer ``confirmations`` times in a row, switches to
    another skill the same way, and gives a committed skill up after as many
    "unknown" answers ("undecided" changes nothing: wait for more of the motion).
    When the motion is over (or at the timeout) the whole motion is recognized once
    (``observed_fraction=1``, the test learning uses) and that answer is final: a
    skill is executed, "unknown" or "undecided" makes the robot hold.
    """
    t = float(time)
    sample = np.asarray(sample, float)
    if not np.isfinite(sample).all():  # rejected by the normalizer's screen: bridge the gap, or give up
        if state.status == "lost":
            return state
        gap = t if np.isnan(state.gap_start) else state.gap_start
        if t - gap > rule.lost_timeout + 1e-9:
            log.debug("gating: wrist lost at t=%.3f (no acceptable sample since %.3f)", t, gap)
            return replace(state, component=None, final=True, status="lost", time=t, gap_start=gap,
                           rejected=state.rejected + 1, revisions=state.revisions + (state.component is not None))
        return replace(state, gap_start=gap, rejected=state.rejected + 1)
    if not np.isnan(state.gap_start):
        state = replace(state, gap_start=float("nan"))  # the gap is bridged
    if state.final:  # the answer is given; the wrist is still watched (a lost wrist makes the robot hold)
        return state
    motion = state.motion.append(time, sample)
    if should_decide(motion, rule):
        rec = recognize_motion(library, motion, whole=True)
        b = _belief(t, rec)
        comp = b.best if b.status == "skill" else None
        if comp is not None and state.component is not None and comp != state.component \
                and _paused(state, motion, rule):
            log.debug("gating: at rest with %d at phase %.2f, the whole-motion answer %d is not trusted",
                      state.component, state.belief.phase, comp)
            b = replace(b, status="undecided", best=None)
            comp = None
        changed = comp != state.component
        revisions = state.revisions + (1 if changed and state.component is not None else 0)
        commits = state.commits + ((comp,) if comp is not None and changed else ())
        commit_time = state.commit_time if not np.isnan(state.commit_time) or comp is None else t
        resp = {} if rec is None else {int(k): float(r) for k, r in zip(rec.ids, rec.responsibilities)}
        log.debug("gating final %s (%s) at t=%.3f after %d samples", b.status, comp, t, motion.n)
        return GatingDecision(motion, comp, True, b.status, t if changed or comp is None else state.time,
                              commit_time, revisions, commits, state.beliefs + (b,), resp, t, (_answer(b), 1))
    if not should_redecide(state, motion, t, rule):
        return replace(state, motion=motion)
    rec = recognize_motion(library, motion, whole=False)
    b = _belief(t, rec)
    ans = _answer(b)
    count = state.streak[1] + 1 if state.streak[0] == ans else 1
    resp = {} if rec is None else {int(k): float(r) for k, r in zip(rec.ids, rec.responsibilities)}
    new = replace(state, motion=motion, beliefs=state.beliefs + (b,), responsibilities=resp, last_check=t,
                  streak=(ans, count))
    if count < rule.confirmations:
        return new
    if isinstance(ans, int) and ans != state.component:
        first = state.component is None and np.isnan(state.commit_time)
        log.debug("gating %s %d at t=%.3f (phase %.2f)", "commits to" if first else "switches to", ans, t, b.phase)
        return replace(new, component=ans, status="skill", time=t, commits=state.commits + (ans,),
                       commit_time=t if np.isnan(state.commit_time) else state.commit_time,
                       revisions=state.revisions + (0 if state.component is None else 1))
    if ans == "unknown" and state.component is not None:
        log.debug("gating gives up %d at t=%.3f", state.component, t)
        return replace(new, component=None, status="pending", time=t, revisions=state.revisions + 1)
    return new


class SkillGating(LeafSystem):
    """Accumulates the normalized wrist, answers while the person moves, and finally when the motion is over.

    .. pydrake_system::

        name: SkillGating
        input_ports:
        - normalized_wrist
        output_ports:
        - decision

    Every 1/64 s the input is appended to the observed motion (abstract
    state); every ``rule.redecide_period`` the prefix is recognized and the
    committed skill set, changed or given up (:func:`gating_step`); when the
    motion is over (:func:`motion_is_over`), at the rule's decision time or at
    its timeout, the whole motion is recognized once more and the answer is
    final. ``decision`` is the :class:`GatingDecision`: the committed component
    (an int, or None), ``status``, ``final``, the history of beliefs and the
    samples. A context reset starts a new trial.

    Parameters
    ----------
    library : SkillLibrary
        Read at decision time, so it may grow between trials.
    rule : DecisionRule, optional
    dim : int
        Dimension of the wrist.
    """

    def __init__(self, library: SkillLibrary, rule: DecisionRule | None = None, *, dim: int = 3):
        super().__init__()
        if not isinstance(library, SkillLibrary):
            raise ValueError(f"library must be a SkillLibrary, got {type(library).__name__}")
        if rule is not None and not isinstance(rule, DecisionRule):
            raise ValueError(f"rule must be a DecisionRule, got {type(rule).__name__}")
        self._library = library
        self._rule = replace(rule) if rule is not None else DecisionRule()  # our own copy
        self._wrist = self.DeclareVectorInputPort("normalized_wrist", dim)
        self._state = self.DeclareAbstractState(AbstractValue.Make(GatingDecision(
            ObservedMotion(np.zeros(0), np.zeros((0, dim))))))
        self.DeclarePeriodicUnrestrictedUpdateEvent(GATING_PERIOD, 0.0, self._update)
        self.DeclareForcedUnrestrictedUpdateEvent(self._update)
        self._decision = self.DeclareAbstractOutputPort(
            "decision", lambda: AbstractValue.Make(GatingDecision()), self._calc_decision,
            prerequisites_of_calc={self.abstract_state_ticket(self._state)})

    @property
    def library(self) -> SkillLibrary:
        return self._library

    @property
    def rule(self) -> DecisionRule:
        return self._rule

    def decision(self, context: Context) -> GatingDecision:
        """The gating state in ``context`` (this system's context)."""
        return context.get_abstract_state(self._state).get_value()

    def _update(self, context: Context, state: State) -> None:
        old = self.decision(context)
        if old.status == "lost":
            return
        new = gating_step(old, context.get_time(), self._wrist.Eval(context), self._library, self._rule)
        state.get_mutable_abstract_state(self._state).set_value(new)

    def _calc_decision(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self.decision(context))
