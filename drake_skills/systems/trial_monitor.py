"""``TrialMonitor``: where a trial is and when it ends, computed inside the Diagram."""
from __future__ import annotations

import math
from dataclasses import dataclass

from pydrake.common.value import AbstractValue

from drake_skills.systems.shared import Shared
from pydrake.systems.framework import Context, LeafSystem

from drake_skills.systems.conditioner import Conditioning
from drake_skills.systems.gating import GatingDecision

#: The phases of a trial, in order.
PHASES = ("observing", "conditioning", "executing", "holding")


@dataclass(frozen=True)
class TrialStatus(Shared):
    """The phase of a trial and, once it is known, the simulation time at which the trial is over.

    Attributes
    ----------
    phase : str
        ``"observing"`` (nothing committed), ``"conditioning"`` (a skill was chosen,
        its trajectory is not computed yet), ``"executing"`` (the robot plays it, also
        while the person still moves) or ``"holding"`` (the final answer is unknown or
        undecided, or conditioning failed: the robot holds).
    end_time : float or None
        When the trial is over (s): after the final decision, the end of the trajectory
        plus the settle time, or the final decision plus the hold time; None before.
    """

    phase: str
    end_time: float | None = None

    def __post_init__(self):
        if self.phase not in PHASES:
            raise ValueError(f"TrialStatus.phase must be one of {PHASES}, got {self.phase!r}")

    def done(self, time: float) -> bool:
        """Is the trial over at ``time``?"""
        return self.end_time is not None and time >= self.end_time - 1e-12


def trial_status(decision: GatingDecision, conditioning: Conditioning, *, settle_time: float,
                 unknown_hold_time: float) -> TrialStatus:
    """The trial's phase and end from the gating's decision and the conditioner's result."""
    if decision.component is None:
        if not decision.final:
            return TrialStatus("observing")
        return TrialStatus("holding", decision.time + unknown_hold_time)
    if conditioning.component != decision.component:
        return TrialStatus("conditioning")
    if conditioning.trajectory is None:  # conditioning failed: the robot holds as for unknown
        return TrialStatus("holding", (decision.time + unknown_hold_time) if decision.final else None)
    if not (decision.final and conditioning.final):
        return TrialStatus("executing")
    return TrialStatus("executing", max(conditioning.trajectory.end_time, conditioning.time) + settle_time)


class TrialMonitor(LeafSystem):
    """The trial's :class:`TrialStatus`, for whoever runs trials (a stateless output).

    .. pydrake_system::

        name: TrialMonitor
        input_ports:
        - decision
        - conditioning
        output_ports:
        - trial_status

    Parameters
    ----------
    settle_time : float
        Seconds after the conditioned trajectory ends before the trial is over.
    unknown_hold_time : float
        Seconds the robot holds still after an "unknown" decision (or a failed conditioning).
    """

    def __init__(self, *, settle_time: float, unknown_hold_time: float):
        super().__init__()
        for name, v in (("settle_time", settle_time), ("unknown_hold_time", unknown_hold_time)):
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"TrialMonitor: {name} must be a finite number >= 0, got {v!r}")
        self._settle, self._hold = float(settle_time), float(unknown_hold_time)
        self._decision = self.DeclareAbstractInputPort("decision", AbstractValue.Make(GatingDecision()))
        self._conditioning = self.DeclareAbstractInputPort("conditioning", AbstractValue.Make(Conditioning()))
        self.DeclareAbstractOutputPort("trial_status", lambda: AbstractValue.Make(TrialStatus("observing")),
                                       self._calc_status)

    def _calc_status(self, context: Context, output: AbstractValue) -> None:
        output.set_value(trial_status(self._decision.Eval(context), self._conditioning.Eval(context),
                                      settle_time=self._settle, unknown_hold_time=self._hold))
