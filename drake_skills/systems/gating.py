"""``SkillGating``: watch the person's motion, then say which skill it is, or "unknown" (Sec. 3.3)."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem, State

from drake_skills.library.incremental import SkillLibrary
from drake_skills.systems.decision_rule import DecisionRule

log = logging.getLogger(__name__)

#: Period of the sampling and decision update (s); exact in binary.
GATING_PERIOD = 1.0 / 64.0


@dataclass(frozen=True, eq=False)
class ObservedMotion:
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
        samples = sample if self.n == 0 else np.vstack([self.samples, sample])
        return ObservedMotion(np.append(self.times, time), samples)


@dataclass(frozen=True, eq=False)
class GatingDecision:
    """The gating's state and output: what was observed and, once decided, the decision.

    Attributes
    ----------
    motion : ObservedMotion
    decided : bool
    component : int or None
        The chosen component id; None while pending and for "unknown".
    responsibilities : dict
        Component id -> p(k | w_h) (Eq. 5) at the decision; empty before.
    time : float
        Simulation time of the decision (NaN before).
    """

    motion: ObservedMotion = field(default_factory=ObservedMotion)
    decided: bool = False
    component: int | None = None
    responsibilities: dict = field(default_factory=dict)
    time: float = float("nan")

    @property
    def status(self) -> str:
        """``"pending"`` (still observing), ``"unknown"`` or ``"skill"``."""
        if not self.decided:
            return "pending"
        return "unknown" if self.component is None else "skill"


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
    if float(np.max(np.linalg.norm(y - y[0], axis=1))) < rule.min_travel:
        return False
    t_end = times[-1]
    if t_end - times[0] < rule.still_duration:
        return False
    window = y[times >= t_end - rule.still_duration - 1e-12]
    return bool(np.all(np.linalg.norm(window - y[-1], axis=1) <= rule.still_radius))


def should_decide(motion: ObservedMotion, rule: DecisionRule) -> bool:
    """Decide now? At ``decision_time`` or ``timeout`` after the first sample, or when the motion is over."""
    if motion.n == 0:
        return False
    elapsed = motion.times[-1] - motion.times[0]
    if rule.decision_time is not None:
        return elapsed >= rule.decision_time - 1e-12
    return elapsed >= rule.timeout - 1e-12 or motion_is_over(motion, rule)


def recognize_motion(library: SkillLibrary, motion: ObservedMotion) -> tuple[int | None, dict]:
    """Which component explains the motion (Eq. 12)?

    Parameters
    ----------
    library : SkillLibrary
        May be empty (then the answer is unknown).
    motion : ObservedMotion
        Samples in the library's normalized units (Eq. 14 applied by the
        normalizer): the library only resamples them.

    Returns
    -------
    component : int or None
        Component id, or None for unknown.
    responsibilities : dict
        Component id -> responsibility.
    """
    if library.n_components == 0 or motion.n < 2:
        return None, {}
    y = motion.samples
    if float(np.max(np.linalg.norm(y - y[0], axis=1))) <= 0.0:
        return None, {}
    rec = library.recognize(y, normalized=True, observed_fraction=1.0)
    resp = {int(k): float(r) for k, r in zip(rec.ids, rec.responsibilities)}
    return (None if rec.component is None else int(rec.component)), resp


def gating_step(state: GatingDecision, time: float, sample: np.ndarray, library: SkillLibrary,
                rule: DecisionRule) -> GatingDecision:
    """One update: record the sample and, when it is time, decide (once)."""
    if state.decided:
        return state
    motion = state.motion.append(time, sample)
    if not should_decide(motion, rule):
        return GatingDecision(motion)
    component, resp = recognize_motion(library, motion)
    log.debug("gating decided %s at t=%.3f after %d samples", component, time, motion.n)
    return GatingDecision(motion, True, component, resp, float(time))


class SkillGating(LeafSystem):
    """Accumulates the normalized wrist and, once the motion is over, recognizes the skill.

    .. pydrake_system::

        name: SkillGating
        input_ports:
        - normalized_wrist
        output_ports:
        - decision

    Every 1/64 s the input is appended to the observed motion (abstract
    state). When the motion is over (:func:`motion_is_over`), at the rule's
    decision time or at its timeout, ``library.recognize`` is called once.
    ``decision`` is the :class:`GatingDecision`: its ``status`` ("pending",
    "unknown", "skill"), the chosen component id (an int, None for unknown),
    the responsibilities and the samples the decision was made on. A context
    reset starts a new trial.

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
        if old.decided:
            return
        new = gating_step(old, context.get_time(), self._wrist.Eval(context), self._library, self._rule)
        state.get_mutable_abstract_state(self._state).set_value(new)

    def _calc_decision(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self.decision(context))
