"""``HumanWristSource``: the person's wrist position, replayed from a demonstration or live."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from drake_skills._checks import as_finite_array, check_increasing


@dataclass(frozen=True, eq=False)
class WristTrial:
    """One replayed wrist trajectory.

    Parameters
    ----------
    t : array, shape (T,)
        Sample times in seconds (any origin; ``t[0]`` is played at ``start_time``).
    human : array, shape (T, 3)
        Wrist positions p_WH in metres, world frame.
    start_time : float
        Simulation time at which ``t[0]`` is played (the trial start offset).
    """

    t: np.ndarray
    human: np.ndarray
    start_time: float = 0.0

    def __post_init__(self):
        t = as_finite_array(self.t, "wrist t", ndim=1, min_rows=1)
        if t.shape[0] > 1:
            check_increasing(t, "wrist t")
        human = as_finite_array(self.human, "wrist trajectory", shape=(t.shape[0], 3))
        object.__setattr__(self, "t", t - t[0])
        object.__setattr__(self, "human", human)
        object.__setattr__(self, "start_time", float(self.start_time))

    @property
    def end_time(self) -> float:
        """Simulation time of the last sample."""
        return self.start_time + float(self.t[-1])


def wrist_at(trial: WristTrial, time: float) -> np.ndarray:
    """Linearly interpolated wrist position at simulation ``time``.

    Before the trial start the first sample is held, after its end the last.

    Returns
    -------
    p_WH : array, shape (3,)
    """
    tau = time - trial.start_time
    t, y = trial.t, trial.human
    if tau <= 0.0:
        return y[0].copy()
    if tau >= t[-1]:
        return y[-1].copy()
    i = int(np.searchsorted(t, tau, side="right"))  # t[i-1] <= tau < t[i]
    a = (tau - t[i - 1]) / (t[i] - t[i - 1])
    return (1.0 - a) * y[i - 1] + a * y[i]


class HumanWristSource(LeafSystem):
    """The human wrist position p_WH, replayed from a recording or passed through from a tracker.

    .. pydrake_system::

        name: HumanWristSource
        input_ports:
        - tracker_wrist (only with passthrough=True)
        output_ports:
        - human_wrist
        - wrist_time (replay mode only)

    In replay mode the trajectory lives in an abstract parameter of the
    context (:meth:`SetTrial`), so one Diagram replays any number of trials.
    :meth:`SetFeed` replaces the perfect replay by what a faulty tracker delivers
    (:func:`~drake_skills.systems.wrist_faults.tracker_feed`: dropouts, stale
    repeats, NaN, outliers, latency); ``wrist_time`` (1,) is the time the delivered
    sample was measured (the simulation time for the perfect replay).

    Parameters
    ----------
    trial : WristTrial, optional
        Default trial (replay mode); a motionless wrist at the origin if omitted.
    passthrough : bool
        Pass the input ``tracker_wrist`` (3,) through instead of replaying.
    """

    def __init__(self, trial: WristTrial | None = None, *, passthrough: bool = False):
        super().__init__()
        self._passthrough = bool(passthrough)
        if self._passthrough:
            if trial is not None:
                raise ValueError("HumanWristSource: a trial makes no sense with passthrough=True")
            self._tracker = self.DeclareVectorInputPort("tracker_wrist", 3)
            self._trial_index = None
        else:
            self._tracker = None
            default = trial if trial is not None else WristTrial(np.zeros(1), np.zeros((1, 3)))
            self._trial_index = self.DeclareAbstractParameter(AbstractValue.Make(default))
            self._feed_index = self.DeclareAbstractParameter(AbstractValue.Make((None,)))
        self._out = self.DeclareVectorOutputPort("human_wrist", 3, self._calc_wrist)
        if not self._passthrough:
            self.DeclareVectorOutputPort("wrist_time", 1, self._calc_time)

    @property
    def passthrough(self) -> bool:
        return self._passthrough

    def SetTrial(self, context: Context, trial: WristTrial) -> None:
        """Replay ``trial`` in ``context`` (this system's context)."""
        if self._passthrough:
            raise ValueError("HumanWristSource: SetTrial needs replay mode (passthrough=False)")
        if not isinstance(trial, WristTrial):
            raise ValueError(f"trial must be a WristTrial, got {type(trial).__name__}")
        context.get_mutable_abstract_parameter(self._trial_index).set_value(trial)

    def SetFeed(self, context: Context, feed) -> None:
        """Deliver ``feed`` (a TrackerFeed, or None for the perfect replay of the trial) in ``context``."""
        if self._passthrough:
            raise ValueError("HumanWristSource: SetFeed needs replay mode (passthrough=False)")
        if feed is not None and type(feed).__name__ != "TrackerFeed":  # no import: wrist_faults imports us
            raise ValueError(f"feed must be a TrackerFeed or None, got {type(feed).__name__}")
        context.get_mutable_abstract_parameter(self._feed_index).set_value((feed,))

    def _feed(self, context: Context):
        return context.get_abstract_parameter(self._feed_index).get_value()[0]

    def GetTrial(self, context: Context) -> WristTrial:
        """The trial replayed in ``context``."""
        if self._passthrough:
            raise ValueError("HumanWristSource: no trial in passthrough mode")
        return context.get_abstract_parameter(self._trial_index).get_value()

    def _calc_wrist(self, context: Context, output: BasicVector) -> None:
        if self._passthrough:
            output.SetFromVector(self._tracker.Eval(context))
            return
        feed = self._feed(context)
        if feed is None:
            output.SetFromVector(wrist_at(self.GetTrial(context), context.get_time()))
        else:
            output.SetFromVector(feed.at(context.get_time())[0])

    def _calc_time(self, context: Context, output: BasicVector) -> None:
        feed = self._feed(context)
        output.SetFromVector([context.get_time() if feed is None else feed.at(context.get_time())[1]])
