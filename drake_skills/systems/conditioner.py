"""``InteractionProMPConditioner``: the robot's answer to the observed motion (Eq. 13)."""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem, State

from drake_skills.library.incremental import SkillLibrary
from drake_skills.systems.gating import GATING_PERIOD, ObservedMotion, identity_workspace

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


def condition_robot(library: SkillLibrary, component: int, motion: ObservedMotion, start_time: float, *,
                    n_steps: int | None = None, scale: float = 10.0) -> ConditionedTrajectory:
    """Condition component ``component`` on the observed motion (Eq. 13).

    Parameters
    ----------
    library : SkillLibrary
    component : int
    motion : ObservedMotion
        Normalized samples relative to the start (Eq. 14 already applied).
    start_time : float
        When the robot starts (s).
    n_steps : int, optional
        Samples of the returned trajectory (default: the library's n_samples).
    scale : float
        The normalized range of the workspace.
    """
    y = motion.samples
    mean, cov = library.predict_robot(y, workspace=identity_workspace(y.shape[1], scale), component=int(component),
                                      n_steps=n_steps)
    std = np.sqrt(np.maximum(np.diagonal(cov, axis1=1, axis2=2), 0.0))
    duration = float(library.component(int(component)).duration)
    return ConditionedTrajectory(int(component), mean, std, duration, float(start_time))


class InteractionProMPConditioner(LeafSystem):
    """Conditions the chosen Interaction ProMP on the observed human motion, once per decision.

    .. pydrake_system::

        name: InteractionProMPConditioner
        input_ports:
        - component
        - observed_motion
        output_ports:
        - robot_trajectory

    ``robot_trajectory`` is a :class:`ConditionedTrajectory`, or None while
    the decision is pending or unknown.  It is computed in an update (every
    1/64 s while no trajectory is held) the first time ``component`` is a
    valid id, cached in abstract state, and starts at that update's time.
    A context reset starts a new trial.

    Parameters
    ----------
    library : SkillLibrary
    n_steps : int, optional
        Samples of the conditioned trajectory.
    scale : float
        The normalized range of the workspace (Eq. 14).
    """

    def __init__(self, library: SkillLibrary, *, n_steps: int | None = None, scale: float = 10.0):
        super().__init__()
        if not isinstance(library, SkillLibrary):
            raise ValueError(f"library must be a SkillLibrary, got {type(library).__name__}")
        self._library = library
        self._n_steps = n_steps
        self._scale = float(scale)
        self._component = self.DeclareVectorInputPort("component", 1)
        self._motion = self.DeclareAbstractInputPort("observed_motion", AbstractValue.Make(ObservedMotion()))
        # [trajectory or None, component it was made for or None]
        self._state = self.DeclareAbstractState(AbstractValue.Make((None, None)))
        self.DeclarePeriodicUnrestrictedUpdateEvent(CONDITIONER_PERIOD, 0.0, self._update)
        self.DeclareForcedUnrestrictedUpdateEvent(self._update)
        self._out = self.DeclareAbstractOutputPort(
            "robot_trajectory", lambda: AbstractValue.Make(None), self._calc_trajectory,
            prerequisites_of_calc={self.abstract_state_ticket(self._state)})

    def trajectory(self, context: Context) -> ConditionedTrajectory | None:
        """The cached trajectory in ``context``, or None."""
        return context.get_abstract_state(self._state).get_value()[0]

    def _update(self, context: Context, state: State) -> None:
        _, done_for = context.get_abstract_state(self._state).get_value()
        if done_for is not None:
            return  # one decision per trial: computed once
        k = int(round(self._component.Eval(context)[0]))
        if k < 0:
            return
        try:
            traj = condition_robot(self._library, k, self._motion.Eval(context), context.get_time(),
                                   n_steps=self._n_steps, scale=self._scale)
        except (KeyError, ValueError) as exc:  # e.g. the component was deleted meanwhile
            log.warning("cannot condition component %d: %s", k, exc)
            traj = None
        state.get_mutable_abstract_state(self._state).set_value((traj, k))

    def _calc_trajectory(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self.trajectory(context))
