"""``InteractionProMPConditioner``: the robot's answer to the observed motion (Eq. 13)."""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem, State

from drake_skills.library.incremental import SkillLibrary
from drake_skills.systems.gating import GATING_PERIOD, GatingDecision, ObservedMotion

log = logging.getLogger(__name__)

#: Period at which a new decision is looked for (s); exact in binary.
CONDITIONER_PERIOD = GATING_PERIOD


@dataclass(frozen=True, eq=False)
class ConditionedTrajectory:
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

    @property
    def end_time(self) -> float:
        return self.start_time + self.duration

    @property
    def key(self) -> tuple[int, float]:
        """Identifies the decision it answers (abstract values are deep-copied, so not ``id``)."""
        return (self.component, self.start_time)


@dataclass(frozen=True, eq=False)
class Conditioning:
    """The conditioner's state and its second output: what it did with this trial's decision.

    Attributes
    ----------
    component : int or None
        The component it conditioned (or tried to); None until it has.
    trajectory : ConditionedTrajectory or None
        The result; None before, and after a failure (e.g. the component was
        deleted between the decision and the conditioning): the robot then holds.
    """

    component: int | None = None
    trajectory: ConditionedTrajectory | None = None

    @property
    def failed(self) -> bool:
        return self.component is not None and self.trajectory is None


def condition_robot(library: SkillLibrary, component: int, motion: ObservedMotion, start_time: float, *,
                    n_steps: int | None = None) -> ConditionedTrajectory:
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

    Raises
    ------
    KeyError
        If ``component`` is not in the library.
    """
    mean, cov = library.predict_robot(motion.samples, 1.0, normalized=True, component=int(component), n_steps=n_steps)
    std = np.sqrt(np.maximum(np.diagonal(cov, axis1=1, axis2=2), 0.0))
    duration = float(library.component(int(component)).duration)
    return ConditionedTrajectory(int(component), mean, std, duration, float(start_time))


def conditioning_step(state: Conditioning, decision: GatingDecision, library: SkillLibrary, time: float, *,
                      n_steps: int | None = None) -> Conditioning:
    """Condition once per trial, the first time the decision names a component.

    A failure (bad input, a component deleted meanwhile) is logged and gives a
    :class:`Conditioning` without trajectory, so the robot holds still.
    """
    if state.component is not None or decision.component is None:
        return state
    k = int(decision.component)
    try:
        traj = condition_robot(library, k, decision.motion, time, n_steps=n_steps)
    except (KeyError, ValueError) as exc:
        log.warning("cannot condition component %d: %s; the robot holds still", k, exc)
        traj = None
    return Conditioning(k, traj)


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
    ``robot_trajectory`` is a :class:`ConditionedTrajectory`, or None while the
    decision is pending or unknown (or conditioning failed). It is computed in an
    update (every 1/64 s until done) the first time the decision names a
    component, cached in abstract state (:class:`Conditioning`, the
    ``conditioning`` output) and starts at that update's time. A context reset
    starts a new trial.

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
        if old.component is not None:
            return  # one decision per trial: computed once
        new = conditioning_step(old, self._decision.Eval(context), self._library, context.get_time(),
                                n_steps=self._n_steps)
        if new is not old:
            state.get_mutable_abstract_state(self._state).set_value(new)

    def _calc_trajectory(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self.trajectory(context))

    def _calc_conditioning(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self.conditioning(context))
