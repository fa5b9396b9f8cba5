"""``InteractionProMPConditioner``: the robot's answer to the observed motion (Eq. 13)."""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue

from drake_skills.systems.shared import Shared
from pydrake.systems.framework import Context, LeafSystem, State

from drake_skills.library.incremental import SkillLibrary
from drake_skills.systems.gating import GATING_PERIOD, GatingDecision, ObservedMotion

log = logging.getLogger(__name__)

#: Period at which a new decision is looked for (s); exact in binary.
CONDITIONER_PERIOD = GATING_PERIOD


@dataclass(frozen=True, eq=False)
class ConditionedTrajectory(Shared):
    """A robot joint trajectory conditioned on the observed human motion.

    Attributes
    ----------
    component : int
        The skill it came from.
    mean : array, shape (n, D_r)
        Joint positions over the component's normalized time, evenly spaced.
    std : array, shape (n, D_r)
        Per-joint standard deviation of the conditioned distribution.
    duration : float
        Seconds over which ``mean`` is played (the component's mean duration).
    start_time : float
        Simulation time at which it starts.
    """

    component: int
    mean: np.ndarray
    std: np.ndarray
    duration: float
    start_time: float
    #: 0 for the first conditioning of a decision, +1 for each re-conditioning on a longer prefix.
    revision: int = 0
    #: Estimated fraction of the person's motion observed when it was conditioned.
    phase: float = 1.0

    @property
    def end_time(self) -> float:
        return self.start_time + self.duration

    @property
    def key(self) -> tuple[int, float, int]:
        """Identifies what it answers (abstract values are deep-copied, so not ``id``)."""
        return (self.component, self.start_time, self.revision)


#: Seconds between two re-conditionings on the growing prefix while the person moves.
RECONDITION_PERIOD = 0.125


@dataclass(frozen=True, eq=False)
class Conditioning(Shared):
    """The conditioner's state and its second output: what it did with this trial's decision.

    Attributes
    ----------
    component : int or None
        The component it conditioned (or tried to); None while nothing is committed.
    trajectory : ConditionedTrajectory or None
        The result; None before, after the gating gave the skill up, and after a failure
        (e.g. the component was deleted between the decision and the conditioning): the
        robot then holds.
    final : bool
        Conditioned on the whole motion after the final decision (no more updates).
    samples : int
        Number of wrist samples it was conditioned on.
    time : float
        When it was last conditioned (NaN before).
    """

    component: int | None = None
    trajectory: ConditionedTrajectory | None = None
    final: bool = False
    samples: int = 0
    time: float = float("nan")

    @property
    def failed(self) -> bool:
        return self.component is not None and self.trajectory is None


def condition_robot(library: SkillLibrary, component: int, motion: ObservedMotion, start_time: float, *,
                    n_steps: int | None = None, whole: bool = True, revision: int = 0,
                    restart: int = 0) -> ConditionedTrajectory:
    """Condition component ``component`` on the observed motion (Eq. 13).

    Parameters
    ----------
    library : SkillLibrary
    component : int
    motion : ObservedMotion
        Samples in the library's normalized units (Eq. 14 already applied).
    start_time : float
        When the robot starts (s).
    n_steps : int, optional
        Samples of the returned trajectory (default: the library's n_samples).
    whole : bool
        The motion is complete; otherwise it is a prefix whose phase the library
        estimates for this component.
    revision : int
    restart : int
        Condition on the samples from this one on (the gating's ``restart``: the library read
        the motion from there, after a false start); 0: all.

    Raises
    ------
    KeyError
        If ``component`` is not in the library.
    """
    c = library.component(int(component))
    if whole:
        phase = 1.0
    else:
        phase = library.estimate_phase(motion.samples, int(component), normalized=True, restart=restart)
    mean, var = library.predict_robot(motion.samples, phase, normalized=True, component=int(component),
                                      n_steps=n_steps, restart=restart, variances_only=True)
    std = np.sqrt(np.maximum(var, 0.0))
    return ConditionedTrajectory(int(component), mean, std, float(c.duration), float(start_time), int(revision),
                                 float(phase))


def conditioning_step(state: Conditioning, decision: GatingDecision, library: SkillLibrary, time: float, *,
                      n_steps: int | None = None) -> Conditioning:
    """Condition when the gating commits or switches, re-condition on the growing prefix, and once at the end.

    * a new committed component: condition on the prefix, starting now;
    * the same component, the person still moving: re-condition every
      :data:`RECONDITION_PERIOD` on the longer prefix (same start, revision + 1);
    * the final decision: condition on the whole motion once (``observed_fraction=1``);
    * no committed component: no trajectory (the robot holds or stops);
    * the wrist lost (``decision.status == "lost"``, even after the final decision):
      the trajectory is withdrawn, so the robot stops and holds.

    A failure (bad input, a component deleted meanwhile) is logged and gives a
    :class:`Conditioning` without trajectory, so the robot holds still.
    """
    if decision.status == "lost" and (state.component is not None or not state.final):
        log.info("the wrist is lost: the robot holds")  # also after the final answer
        return Conditioning(None, None, True, decision.motion.n, float(time))
    if state.final:
        return state
    k = decision.component
    if k is None:
        if state.component is None and not decision.final:
            return state
        return Conditioning(None, None, decision.final, decision.motion.n, float(time))
    k = int(k)
    same = state.component == k and state.trajectory is not None
    if same and not decision.final:
        if decision.motion.n <= state.samples or time - state.time < RECONDITION_PERIOD - 1e-9:
            return state
    if state.component == k and state.trajectory is None and not decision.final:
        return state  # it failed for this component: do not retry every tick
    start = state.trajectory.start_time if same else float(time)
    revision = state.trajectory.revision + 1 if same else 0
    try:
        traj = condition_robot(library, k, decision.motion, start, n_steps=n_steps, whole=decision.final,
                               revision=revision, restart=decision.restart)
    except (KeyError, ValueError) as exc:
        log.warning("cannot condition component %d: %s; the robot holds still", k, exc)
        traj = None
    return Conditioning(k, traj, decision.final, decision.motion.n, float(time))


class InteractionProMPConditioner(LeafSystem):
    """Conditions the chosen Interaction ProMP on the observed human motion, once per decision.

    .. pydrake_system::

        name: InteractionProMPConditioner
        input_ports:
        - decision
        output_ports:
        - robot_trajectory
        - conditioning

    ``decision`` is the gating's :class:`~drake_skills.systems.gating.GatingDecision`.
    ``robot_trajectory`` is a :class:`ConditionedTrajectory`, or None while
    nothing is committed (or conditioning failed). It is computed in an update
    (every 1/64 s) when the gating commits or switches, recomputed on the growing
    prefix and once more on the whole motion (:func:`conditioning_step`), and
    cached in abstract state (:class:`Conditioning`, the ``conditioning`` output).
    A context reset starts a new trial.

    Parameters
    ----------
    library : SkillLibrary
    n_steps : int, optional
        Samples of the conditioned trajectory.
    """

    def __init__(self, library: SkillLibrary, *, n_steps: int | None = None):
        super().__init__()
        if not isinstance(library, SkillLibrary):
            raise ValueError(f"library must be a SkillLibrary, got {type(library).__name__}")
        self._library = library
        self._n_steps = n_steps
        self._decision = self.DeclareAbstractInputPort("decision", AbstractValue.Make(GatingDecision()))
        self._state = self.DeclareAbstractState(AbstractValue.Make(Conditioning()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(CONDITIONER_PERIOD, 0.0, self._update)
        self.DeclareForcedUnrestrictedUpdateEvent(self._update)
        deps = {self.abstract_state_ticket(self._state)}
        self._out = self.DeclareAbstractOutputPort(
            "robot_trajectory", lambda: AbstractValue.Make(None), self._calc_trajectory, prerequisites_of_calc=deps)
        self._conditioning = self.DeclareAbstractOutputPort(
            "conditioning", lambda: AbstractValue.Make(Conditioning()), self._calc_conditioning,
            prerequisites_of_calc=deps)

    def conditioning(self, context: Context) -> Conditioning:
        """The conditioner's state in ``context``."""
        return context.get_abstract_state(self._state).get_value()

    def trajectory(self, context: Context) -> ConditionedTrajectory | None:
        """The cached trajectory in ``context``, or None."""
        return self.conditioning(context).trajectory

    def _update(self, context: Context, state: State) -> None:
        old = self.conditioning(context)
        if old.final and old.component is None:
            return
        new = conditioning_step(old, self._decision.Eval(context), self._library, context.get_time(),
                                n_steps=self._n_steps)
        if new is not old:
            state.get_mutable_abstract_state(self._state).set_value(new)

    def _calc_trajectory(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self.trajectory(context))

    def _calc_conditioning(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self.conditioning(context))
