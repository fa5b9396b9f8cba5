"""``SkillGating``: watch the person's motion, then say which skill it is, or "unknown" (Sec. 3.3)."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem, State

from drake_skills.library.incremental import SkillLibrary
from drake_skills.systems.decision_rule import DecisionRule
from drake_skills.data.workspace import Workspace

log = logging.getLogger(__name__)

#: Period of the sampling and decision update (s); exact in binary.
GATING_PERIOD = 1.0 / 64.0
#: Value of the "component" output while the motion is still being observed.
PENDING = -2
#: Value of the "component" output when the motion matches no skill.
UNKNOWN = -1


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
    """The gating's state: what was observed and, once decided, the decision.

    Attributes
    ----------
    motion : ObservedMotion
    decided : bool
    component : int
        Component id, ``UNKNOWN`` (-1) or ``PENDING`` (-2).
    responsibilities : dict
        Component id -> p(k | w_h) (Eq. 5) at the decision; empty before.
    time : float
        Simulation time of the decision (NaN before).
    """

    motion: ObservedMotion = field(default_factory=ObservedMotion)
    decided: bool = False
    component: int = PENDING
    responsibilities: dict = field(default_factory=dict)
    time: float = float("nan")


def identity_workspace(dim: int, scale: float = 10.0) -> Workspace:
    """A workspace whose normalization is the identity (for already normalized samples)."""
    return Workspace(np.zeros(dim), np.full(dim, float(scale)), float(scale))


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


def recognize_motion(library: SkillLibrary, motion: ObservedMotion, scale: float = 10.0) -> tuple[int, dict]:
    """Which component explains the motion (Eq. 12)?

    Parameters
    ----------
    library : SkillLibrary
        May be empty (then the answer is unknown).
    motion : ObservedMotion
        Normalized samples relative to the start (Eq. 14 already applied).
    scale : float
        The normalized range of the workspace the samples were normalized with.

    Returns
    -------
    component : int
        Component id, or ``UNKNOWN``.
    responsibilities : dict
        Component id -> responsibility.
    """
    if library.n_components == 0 or motion.n < 2:
        return UNKNOWN, {}
    y = motion.samples
    if float(np.max(np.linalg.norm(y - y[0], axis=1))) <= 0.0:
        return UNKNOWN, {}
    rec = library.recognize(y, workspace=identity_workspace(y.shape[1], scale))
    resp = {int(k): float(r) for k, r in zip(rec.ids, rec.responsibilities)}
    return (UNKNOWN if rec.component is None else int(rec.component)), resp


def gating_step(state: GatingDecision, time: float, sample: np.ndarray, library: SkillLibrary,
                rule: DecisionRule, scale: float = 10.0) -> GatingDecision:
    """One update: record the sample and, when it is time, decide (once)."""
    if state.decided:
        return state
    motion = state.motion.append(time, sample)
    if not should_decide(motion, rule):
        return GatingDecision(motion)
    component, resp = recognize_motion(library, motion, scale)
    log.debug("gating decided %s at t=%.3f after %d samples", component, time, motion.n)
    return GatingDecision(motion, True, component, resp, float(time))


class SkillGating(LeafSystem):
    """Accumulates the normalized wrist and, once the motion is over, recognizes the skill.

    .. pydrake_system::

        name: SkillGating
        input_ports:
        - normalized_wrist
        output_ports:
        - component
        - responsibilities
        - observed_motion

    Every 1/64 s the input is appended to the observed motion (abstract
    state).  When the motion is over (:func:`motion_is_over`) or at the
    configured decision time, ``library.recognize`` is called once.
    ``component`` is then the chosen id, ``-1`` for unknown, and ``-2``
    while undecided; ``responsibilities`` is a dict id -> p(k | w_h);
    ``observed_motion`` (an :class:`ObservedMotion`) the samples the decision
    was made on.  A context reset starts a new trial.

    Parameters
    ----------
    library : SkillLibrary
        Read at decision time, so it may grow between trials.
    rule : DecisionRule, optional
    dim : int
        Dimension of the wrist.
    scale : float
        The normalized range of the workspace (Eq. 14; 10 in the paper).
    """

    def __init__(self, library: SkillLibrary, rule: DecisionRule | None = None, *, dim: int = 3,
                 scale: float = 10.0):
        super().__init__()
        if not isinstance(library, SkillLibrary):
            raise ValueError(f"library must be a SkillLibrary, got {type(library).__name__}")
        self._library = library
        if rule is not None and not isinstance(rule, DecisionRule):
            raise ValueError(f"rule must be a DecisionRule, got {type(rule).__name__}")
        self._rule = replace(rule) if rule is not None else DecisionRule()  # our own copy
        self._scale = float(scale)
        self._wrist = self.DeclareVectorInputPort("normalized_wrist", dim)
        self._state = self.DeclareAbstractState(AbstractValue.Make(GatingDecision(
            ObservedMotion(np.zeros(0), np.zeros((0, dim))))))
        self.DeclarePeriodicUnrestrictedUpdateEvent(GATING_PERIOD, 0.0, self._update)
        self.DeclareForcedUnrestrictedUpdateEvent(self._update)
        self._component = self.DeclareVectorOutputPort(
            "component", 1, self._calc_component, prerequisites_of_calc={self.abstract_state_ticket(self._state)})
        self._responsibilities = self.DeclareAbstractOutputPort(
            "responsibilities", lambda: AbstractValue.Make(dict()), self._calc_responsibilities,
            prerequisites_of_calc={self.abstract_state_ticket(self._state)})
        self._motion = self.DeclareAbstractOutputPort(
            "observed_motion", lambda: AbstractValue.Make(ObservedMotion()), self._calc_motion,
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
        new = gating_step(old, context.get_time(), self._wrist.Eval(context), self._library, self._rule,
                          self._scale)
        state.get_mutable_abstract_state(self._state).set_value(new)

    def _calc_component(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, float(self.decision(context).component))

    def _calc_responsibilities(self, context: Context, output: AbstractValue) -> None:
        output.set_value(dict(self.decision(context).responsibilities))

    def _calc_motion(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self.decision(context).motion)
