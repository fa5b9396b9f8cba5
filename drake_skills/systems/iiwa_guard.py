"""``IiwaCommandGuard``: the last system before the iiwa command: a safe joint position or a hold.

It turns the trajectory source's desired state into the joint position command
that goes to the robot, watching the robot's status (as decoded by pydrake's
``IiwaStatusReceiver``), and it is the one place that decides what is safe to send:

* no command before a status message has been seen (initializing without one is an error);
  the first command is the measured position itself (inside the hard limits);
* the command moves at most ``v_max * period`` per period (joint speed limits) and stays
  ``margin`` inside the joint position limits (a robot parked inside the margin is moved
  out of it at the speed limit);
* a stale status (no new message for ``stale_timeout``) freezes the command where it is;
  it follows the desired state again only when the status is fresh and the desired
  position has come back within ``resume_tolerance`` of the frozen command (in practice:
  at the next trial, whose hold pose is latched from the measured position), so the robot
  never jumps to catch up;
* a new status whose position is more than ``max_lag`` from the command while it follows,
  or more than ``hold_lag`` while it holds, means the robot is not where it is commanded. If
  the status says the robot is at rest (every joint under ``rest_speed``: a protective stop, a
  robot moved or restarted during a status gap), the command is set to the measured position;
  if it still moves (statuses arriving late), a following command is frozen where it is, and a
  held one waits. Either way the command holds until the next trial (its initialization):
  it never leads the robot by more than ``max_lag``, never jumps back to where a moved robot
  was, and never resumes mid-trial against a robot it lost;
* a desired position that is not finite holds the command;
* a status whose positions are not finite counts as not received, and the controller's
  measured state is the last good status (a trial starting on a bad message latches it).

Freshness is judged by the controller's own clock: a message is new when its timestamp
differs from the last one seen, and its arrival is the time of the update that saw it.
The robot's timestamp is never compared with the controller's clock (they are different
machines).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem


@dataclass(frozen=True)
class GuardLimits:
    """What the guard enforces.

    Attributes
    ----------
    lower, upper : array, shape (n,)
        Joint position limits (rad).
    v_max : array, shape (n,)
        Joint speed limits (rad/s).
    period : float
        Seconds between commands.
    stale_timeout : float
        A status older than this (s) freezes the command.
    margin : float
        Commands stay this far inside the position limits (rad).
    resume_tolerance : float
        After a freeze, follow the desired position again once it is this close (rad, max norm).
    max_lag : float
        Largest distance (rad, max norm) between the command and a new measured position while
        following; beyond it the command is re-latched to the measured position and held. The
        simulated station lags up to 0.07 rad (0.15 with 20 ms of bus latency).
    hold_lag : float
        The same while holding, when the robot should be at the command.
    rest_speed : float
        A status whose joint speeds are all below this (rad/s) says the robot is at rest there.
    """

    lower: np.ndarray
    upper: np.ndarray
    v_max: np.ndarray
    period: float
    stale_timeout: float = 0.1
    margin: float = math.radians(1.0)
    resume_tolerance: float = 0.01
    max_lag: float = 0.3
    hold_lag: float = 0.05
    rest_speed: float = 0.05

    def __post_init__(self):
        lower, upper, v_max = (np.asarray(a, float).copy() for a in (self.lower, self.upper, self.v_max))
        n = lower.shape[0]
        if lower.ndim != 1 or upper.shape != (n,) or v_max.shape != (n,):
            raise ValueError(f"GuardLimits: lower, upper and v_max must have shape ({n},)")
        if (upper - lower <= 2 * self.margin).any() or (v_max <= 0).any():
            raise ValueError("GuardLimits: need upper - lower > 2 margin and v_max > 0")
        for name in ("period", "stale_timeout", "resume_tolerance", "max_lag", "hold_lag", "rest_speed"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"GuardLimits.{name} must be positive, got {v!r}")
        for name, a in (("lower", lower), ("upper", upper), ("v_max", v_max)):
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        # what guard_step uses, computed once
        object.__setattr__(self, "q_min", lower + self.margin)
        object.__setattr__(self, "q_max", upper - self.margin)
        object.__setattr__(self, "step_max", v_max * self.period)

    @property
    def n(self) -> int:
        return int(self.lower.shape[0])

    #: lower + margin, upper - margin, v_max * period (set in __post_init__).
    q_min: np.ndarray = field(init=False, repr=False, compare=False)
    q_max: np.ndarray = field(init=False, repr=False, compare=False)
    step_max: np.ndarray = field(init=False, repr=False, compare=False)


@dataclass(frozen=True, eq=False)
class GuardState:
    """The guard's state and its ``guard_status`` output.

    Attributes
    ----------
    command : array, shape (n,), or None
        The joint positions being commanded (rad); None before the first status.
    status_time : float
        Timestamp of the newest status seen (s, the robot's clock; NaN: none).
    arrival_time : float
        Controller time at which that status was first seen (s; NaN: none).
    holding : bool
        The command is frozen (the status went stale, or the robot was not where commanded).
    limited : int
        Updates in which a speed or position limit changed the command (a diagnostic).
    stale_events : int
        Times the status went stale.
    measured, velocity : array, shape (n,), or None
        The newest good (finite) status's joint positions and velocities (None: none yet).
    lag_events : int
        Times a new status found the robot too far from the command (see the module).
    needs_trial : bool
        The robot was lost that way: hold until the next trial starts (the guard's initialization).
    """

    command: np.ndarray | None = None
    status_time: float = float("nan")
    arrival_time: float = float("nan")
    holding: bool = False
    limited: int = 0
    stale_events: int = 0
    measured: np.ndarray | None = None
    velocity: np.ndarray | None = None
    lag_events: int = 0
    needs_trial: bool = False

    def status_age(self, time: float) -> float:
        """Seconds since the newest status arrived (inf: none yet)."""
        return math.inf if math.isnan(self.arrival_time) else time - self.arrival_time

    def to_vector(self, n: int) -> np.ndarray:
        """The state as the guard's discrete state vector (3 n + 9,)."""
        nan = np.full(n, np.nan)
        command = self.command if self.command is not None else nan
        measured = self.measured if self.measured is not None else nan
        velocity = self.velocity if self.velocity is not None else nan
        return np.concatenate([command, [self.status_time, self.arrival_time, float(self.holding), self.limited,
                                         self.stale_events, float(self.command is not None)],
                               measured, velocity, [float(self.measured is not None), self.lag_events,
                                                    float(self.needs_trial)]])

    @classmethod
    def from_vector(cls, x: np.ndarray, n: int) -> "GuardState":
        """Inverse of :meth:`to_vector`."""
        m = n + 6
        has = x[3 * n + 6] > 0.5
        return cls(np.array(x[:n]) if x[n + 5] > 0.5 else None, float(x[n]), float(x[n + 1]), bool(x[n + 2] > 0.5),
                   int(x[n + 3]), int(x[n + 4]), np.array(x[m:m + n]) if has else None,
                   np.array(x[m + n:m + 2 * n]) if has else None, int(x[3 * n + 7]), bool(x[3 * n + 8] > 0.5))


def status_received(q_measured: np.ndarray, status_time: float) -> bool:
    """Is this the content of a real status, not of the default (never received) message?

    ``IiwaStatusReceiver`` turns the default message into zeros: time 0 and all
    joints at exactly 0.0, which no measured robot reports (and the simulated
    station's home pose is not zero). The controller's harness also waits for a
    status before it initializes (:func:`~drake_skills.sim.lcm_controller.receive_first_messages`);
    this is the second check.
    """
    finite = bool(np.isfinite(q_measured).all())
    return finite and (status_time != 0.0 or bool(q_measured.any()))


def guard_step(state: GuardState, time: float, q_measured: np.ndarray, status_time: float, q_desired: np.ndarray,
               limits: GuardLimits, q_velocity: np.ndarray | None = None) -> GuardState:
    """One command period: note a new status, freeze on a stale one, limit and advance the command.

    Parameters
    ----------
    state : GuardState
    time : float
        Controller time (s).
    q_measured : array, shape (n,)
        Joint positions of the newest status (rad).
    status_time : float
        Its timestamp (s, the robot's clock; only compared with the previous one).
    q_desired : array, shape (n,)
        Joint positions the trajectory source asks for (rad); not finite: hold.
    limits : GuardLimits
    q_velocity : array, shape (n,), optional
        Joint velocities of the newest status (kept with the last good position).

    Returns
    -------
    GuardState
    """
    status_t, arrival = state.status_time, state.arrival_time
    received = status_received(q_measured, status_time)
    measured, velocity = state.measured, state.velocity
    new_status = received and status_time != status_t
    if received:
        measured = np.array(q_measured, float)
        velocity = np.array(q_velocity, float) if q_velocity is not None else np.zeros_like(measured)
        if new_status:
            status_t, arrival = float(status_time), float(time)
    keep = dict(measured=measured, velocity=velocity, lag_events=state.lag_events, needs_trial=state.needs_trial)
    q = state.command
    if q is None:
        if not received:
            return GuardState(None, status_t, arrival, state.holding, state.limited, state.stale_events, **keep)
        q = np.minimum(np.maximum(q_measured, limits.lower), limits.upper)   # where the robot is: no jump
    stale = not time - arrival <= limits.stale_timeout + 1e-9  # NaN arrival (none yet) is stale
    holding, stale_events = state.holding, state.stale_events
    if stale and not holding:
        holding, stale_events = True, stale_events + 1
    fresh = received and not stale
    # only a new status says where the robot is now (between statuses the last one ages)
    if new_status and not stale and float(np.max(np.abs(q - q_measured))) > (limits.hold_lag if holding
                                                                             else limits.max_lag):
        at_rest = q_velocity is None or not np.isfinite(q_velocity).all() or \
            float(np.max(np.abs(q_velocity))) <= limits.rest_speed
        if at_rest or not holding:
            # at rest there: command it there (no jump back); still moving: freeze a following command
            if at_rest:
                q = np.minimum(np.maximum(q_measured, limits.lower), limits.upper)
            keep["lag_events"], keep["needs_trial"] = state.lag_events + 1, True
            return GuardState(q, status_t, arrival, True, state.limited, stale_events, **keep)
        # held, and the robot still moves towards the held command (a late status): wait
    desired_ok = bool(np.isfinite(q_desired).all())
    if holding and fresh and desired_ok and not keep["needs_trial"] and \
            float(np.max(np.abs(q_desired - q))) <= limits.resume_tolerance:
        holding = False
    if holding or not desired_ok:
        return GuardState(q, status_t, arrival, holding, state.limited, stale_events, **keep)
    target = np.minimum(np.maximum(q_desired, limits.q_min), limits.q_max)
    delta = target - q
    step = np.minimum(np.maximum(delta, -limits.step_max), limits.step_max)
    changed = not (target == q_desired).all() or not (step == delta).all()
    return GuardState(q + step, status_t, arrival, False, state.limited + changed, stale_events, **keep)


class IiwaCommandGuard(LeafSystem):
    """A limited, stale-safe joint position command from the desired state and the robot's status.

    .. pydrake_system::

        name: IiwaCommandGuard
        input_ports:
        - desired_state
        - position_measured
        - velocity_estimated
        - status_time
        output_ports:
        - position
        - measured_state
        - guard_status

    ``position_measured`` (n,), ``velocity_estimated`` (n,) and ``status_time`` (1,)
    are the ``IiwaStatusReceiver``'s outputs of the newest ``lcmt_iiwa_status``;
    ``measured_state`` passes them on as [q; v] (2n,) for the controller, and
    evaluating it before a status has been received is an error (the receiver would
    give zeros, and a hold pose latched from them would send the robot to zero).
    ``position`` (n,) is the command, updated every ``limits.period`` by
    :func:`guard_step` from ``desired_state`` ([q; v], only q is used) and latched
    from the measured position at initialization; ``guard_status`` is the
    :class:`GuardState` (kept as a discrete state vector, so a 200 Hz update copies
    no Python object). A context reset forgets everything, so the controller resets
    the guard only together with the robot.

    Parameters
    ----------
    limits : GuardLimits
    channel : str
        Name of the status channel, for error messages.
    """

    def __init__(self, limits: GuardLimits, *, channel: str = "IIWA_STATUS"):
        super().__init__()
        if not isinstance(limits, GuardLimits):
            raise ValueError(f"limits must be GuardLimits, got {type(limits).__name__}")
        self._limits = limits
        self._channel = channel
        n = self._n = limits.n
        self._desired = self.DeclareVectorInputPort("desired_state", 2 * n)
        self._measured = self.DeclareVectorInputPort("position_measured", n)
        self._velocity = self.DeclareVectorInputPort("velocity_estimated", n)
        self._time = self.DeclareVectorInputPort("status_time", 1)
        self._state = self.DeclareDiscreteState(GuardState().to_vector(n))
        self.DeclareInitializationDiscreteUpdateEvent(self._initialize)
        self.DeclarePeriodicDiscreteUpdateEvent(limits.period, 0.0, self._update)
        deps = {self.discrete_state_ticket(self._state)}
        self.DeclareVectorOutputPort("position", n, self._calc_position, prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("measured_state", 2 * n, self._calc_measured_state,
                                     prerequisites_of_calc={self._measured.ticket(), self._velocity.ticket(),
                                                            self._time.ticket()})
        self.DeclareAbstractOutputPort("guard_status", lambda: AbstractValue.Make(GuardState()),
                                       self._calc_status, prerequisites_of_calc=deps)

    @property
    def limits(self) -> GuardLimits:
        return self._limits

    def guard_state(self, context: Context) -> GuardState:
        """The guard's state in ``context`` (this system's context)."""
        return GuardState.from_vector(context.get_discrete_state(self._state).get_value(), self._n)

    def _initialize(self, context: Context, discrete_state: DiscreteValues) -> None:
        old = self.guard_state(context)
        if old.command is not None:
            # a new trial of a running controller: keep commanding from where we are; a robot lost in
            # the last trial may be followed again (its hold pose is latched from its measured position)
            if old.needs_trial:
                discrete_state.get_mutable_vector(self._state).SetFromVector(
                    replace(old, needs_trial=False).to_vector(self._n))
            return
        q, t = np.asarray(self._measured.Eval(context)), float(self._time.Eval(context)[0])
        if not status_received(q, t):
            raise RuntimeError(f"IiwaCommandGuard: no lcmt_iiwa_status received on '{self._channel}'; the "
                               f"controller must not start before the robot reports")
        new = replace(guard_step(old, context.get_time(), q, t, q, self._limits,
                                 np.asarray(self._velocity.Eval(context))), limited=0)
        discrete_state.get_mutable_vector(self._state).SetFromVector(new.to_vector(self._n))

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        new = guard_step(self.guard_state(context), context.get_time(), np.asarray(self._measured.Eval(context)),
                         float(self._time.Eval(context)[0]), np.asarray(self._desired.Eval(context)[:self._n]),
                         self._limits, np.asarray(self._velocity.Eval(context)))
        discrete_state.get_mutable_vector(self._state).SetFromVector(new.to_vector(self._n))

    def _calc_position(self, context: Context, output: BasicVector) -> None:
        x = context.get_discrete_state(self._state).get_value()
        if x[self._n + 5] < 0.5:
            raise RuntimeError(f"IiwaCommandGuard: no command yet (no lcmt_iiwa_status on '{self._channel}')")
        output.SetFromVector(x[:self._n])

    def _calc_measured_state(self, context: Context, output: BasicVector) -> None:
        q = np.asarray(self._measured.Eval(context))
        if status_received(q, float(self._time.Eval(context)[0])):
            output.SetFromVector(np.concatenate([q, self._velocity.Eval(context)]))
            return
        last = self.guard_state(context)   # the newest message is bad (NaN): the last good one
        if last.measured is None:
            raise RuntimeError(f"IiwaCommandGuard: no good lcmt_iiwa_status received on '{self._channel}' (none "
                               f"yet, or only ones with non-finite positions); deliver a status before the "
                               f"controller initializes")
        output.SetFromVector(np.concatenate([last.measured, np.nan_to_num(last.velocity)]))

    def _calc_status(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self.guard_state(context))
