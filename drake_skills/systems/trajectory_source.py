"""``JointTrajectorySource``: desired joint state and acceleration for the controller.

A conditioned trajectory becomes a smooth :class:`JointPlan` once, starting at rest
from the held pose no earlier than the moment the source sees it (:func:`build_plan`). A
new one while a plan runs (the conditioner re-conditioned on a longer prefix, or the
gating switched skills) is blended into the running command from the current desired
position and velocity (:func:`blend_plan`): position and velocity stay continuous, the
offset fades out over ``BLEND_TIME`` with a quintic. Every plan keeps joint positions
inside the limits (minus a margin), is slowed down (time stretched) until no joint exceeds
its velocity limit, and ends at the trajectory's last pose at rest: the conditioned mean
moves at its first and last samples (at its end 0.06-0.19 rad/s on the salad), so its first
and last ``TAIL`` are played speeding up from and slowing down to zero velocity and
acceleration (:func:`trajectory_clock`) instead of starting and stopping within one knot
interval (10-53 rad/s^2). When the trajectory is withdrawn (the gating gave the
skill up) the robot decelerates to rest (:func:`stop_plan`) and holds.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue

from drake_skills.systems.shared import Shared
from pydrake.systems.framework import BasicVector, Context, LeafSystem, State
from pydrake.trajectories import PiecewisePolynomial
from scipy.interpolate import CubicSpline

from drake_skills.systems.conditioner import ConditionedTrajectory

#: Period at which a new conditioned trajectory is looked for (s); exact in binary.
SOURCE_PERIOD = 1.0 / 64.0
#: Shortest duration a trajectory is stretched to (s), so velocities stay finite.
MIN_DURATION = 0.25


#: Seconds over which a re-plan's offset from the running command fades out.
BLEND_TIME = 0.5
#: Seconds in which a withdrawn plan decelerates to rest.
STOP_TIME = 0.5
#: Distance kept from the joint limits (rad).
LIMIT_MARGIN = 0.02
#: A plan plays the first and the last stretch of its trajectory (the trajectory's clock, s;
#: at most ``TAIL_FRACTION`` of the duration each) in twice the time, speeding up from rest
#: and slowing down to rest (:func:`trajectory_clock`).
TAIL = 0.25
TAIL_FRACTION = 0.15


def tail_of(duration: float) -> float:
    """Seconds at each end of a trajectory of ``duration`` s that its plan plays at half speed on average."""
    return min(TAIL, TAIL_FRACTION * float(duration))


def trajectory_clock(r: np.ndarray, duration: float, tail: float) -> np.ndarray:
    """The trajectory's own time for plan time ``r`` (both from its start; ``r`` in ``[0, duration + 2 tail]``).

    The clock starts at rest, reaches full speed after ``2 tail`` of plan time (``tail`` of
    its own), runs at full speed, and slows to a stop at ``duration``, reached at plan time
    ``duration + 2 tail``: ``dtau/dr`` rises as ``3u^2 - 2u^3`` and falls as its mirror
    image, so its speed and acceleration are continuous and zero at both ends. Whatever the
    trajectory's first and last velocities (the conditioned mean still moves at its last
    sample), the played motion starts and ends at rest with zero acceleration.
    """
    r = np.asarray(r, float)
    if tail <= 0:
        return np.clip(r, 0.0, duration)
    u0 = np.clip(r / (2.0 * tail), 0.0, 1.0)
    u1 = np.clip((r - duration) / (2.0 * tail), 0.0, 1.0)
    start = 2.0 * tail * (u0 ** 3 - 0.5 * u0 ** 4)                    # 0 -> tail
    end = duration - tail + 2.0 * tail * (u1 - u1 ** 3 + 0.5 * u1 ** 4)   # duration - tail -> duration
    return np.where(r < 2.0 * tail, start, np.where(r < duration, r - tail, end))


@dataclass(frozen=True, eq=False)
class JointPlan(Shared):
    """A smooth joint trajectory built from a conditioned trajectory (or a stop).

    Attributes
    ----------
    source : ConditionedTrajectory or None
        What it was built from (compared by ``key`` to spot a new one); None for a
        stop (:func:`stop_plan`).
    q, qd, qdd : PiecewisePolynomial
        Position, velocity and acceleration over ``[start_time, end_time]``.
    """

    source: ConditionedTrajectory
    q: PiecewisePolynomial
    qd: PiecewisePolynomial
    qdd: PiecewisePolynomial
    #: ``q``'s time span, kept as floats (the outputs ask for it at every plant step).
    start_time: float = float("nan")
    end_time: float = float("nan")

    def __post_init__(self):
        object.__setattr__(self, "start_time", float(self.q.start_time()))
        object.__setattr__(self, "end_time", float(self.q.end_time()))


def plan_knots(traj: ConditionedTrajectory, q_hold: np.ndarray, lower: np.ndarray, upper: np.ndarray, *,
               blend_fraction: float = 0.2, margin: float = 0.02, start: float | None = None,
               stretch: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Knot times and positions for a conditioned trajectory, starting exactly at ``q_hold``.

    The offset ``q_hold - mean[0]`` is faded out with a smoothstep over the first
    ``blend_fraction`` of the motion, so the robot starts where it is without a jump;
    the first and last :func:`tail_of` the duration are played speeding up from and
    slowing down to rest (:func:`trajectory_clock`); positions are clipped to
    ``[lower + margin, upper - margin]``.
    ``start`` (default ``traj.start_time``) is when the plan begins; ``stretch`` > 1 plays
    the whole motion that many times slower.

    Returns
    -------
    times : array, shape (n,)
        From ``start`` to ``start + stretch (duration + 2 tail)``.
    q : array, shape (n, D)
    """
    mean = np.asarray(traj.mean, float)
    n = mean.shape[0]
    duration = max(float(traj.duration), MIN_DURATION)
    tail = tail_of(duration)
    r_own = duration * np.linspace(0.0, 1.0, n) + tail                  # the mean's samples at full speed
    gap = 1e-6 * duration   # a sample within rounding of a boundary would repeat that knot's time
    r = np.concatenate([np.linspace(0.0, 2.0 * tail, 21),               # dense where it speeds up ...
                        r_own[(r_own > 2.0 * tail + gap) & (r_own < duration - gap)],
                        np.linspace(duration, duration + 2.0 * tail, 21)])   # ... and slows down
    s = trajectory_clock(r, duration, tail) / duration
    q_mean = np.stack([np.interp(s, np.linspace(0.0, 1.0, n), mean[:, j]) for j in range(mean.shape[1])], axis=1)
    z = np.clip(s / blend_fraction, 0.0, 1.0) if blend_fraction > 0 else np.ones_like(s)
    fade = 1.0 - (3 * z ** 2 - 2 * z ** 3)  # 1 at the start, 0 after the blend
    q = q_mean + np.outer(fade, np.asarray(q_hold, float) - mean[0])
    q = np.clip(q, np.asarray(lower) + margin, np.asarray(upper) - margin)
    q[0] = q_hold   # exactly where it holds, even inside the margin (the knots after it are not)
    t0 = traj.start_time if start is None else float(start)
    return t0 + stretch * r, q


def build_plan(traj: ConditionedTrajectory, q_hold: np.ndarray, lower: np.ndarray, upper: np.ndarray,
               vmax: np.ndarray | None = None, *, start: float | None = None) -> JointPlan:
    """Shape-preserving cubic through :func:`plan_knots` with zero end velocities.

    Shape preservation keeps the curve between neighbouring knots, so it stays inside the
    clipped joint limits. If ``vmax`` (rad/s per joint) is given and the plan is faster,
    it is played slower (time stretched) until it is not: the first plan of a trial may
    start far from the trajectory's first pose (on a real robot, where the last trial's
    handover left it). ``start``: when the plan begins (default ``traj.start_time``; the
    source passes the moment it sees the trajectory, never earlier, so the robot starts
    at rest from where it holds).
    """
    def at(stretch: float) -> JointPlan:
        times, q = plan_knots(traj, q_hold, lower, upper, start=start, stretch=stretch)
        pp = PiecewisePolynomial.CubicShapePreserving(times, q.T, zero_end_point_derivatives=True)
        qd = pp.derivative(1)
        return JointPlan(traj, pp, qd, qd.derivative(1))

    return _within_speed(at, vmax)


def _within_speed(plan_at, vmax: np.ndarray | None) -> JointPlan:
    """``plan_at(stretch)`` at 1, then played slower (``stretch`` up, at most 12 times) until no joint exceeds ``vmax``."""
    stretch = 1.0
    for _ in range(12):
        plan = plan_at(stretch)
        if vmax is None:
            return plan
        ratio = peak_speed_ratio(plan, vmax)
        if ratio <= 1.0:
            return plan
        stretch *= 1.05 * ratio
    return plan


def _quintic_fade(sigma: np.ndarray) -> np.ndarray:
    """1 at 0, 0 from 1 on, with zero first and second derivatives at both ends."""
    x = np.clip(sigma, 0.0, 1.0)
    return 1.0 - x ** 3 * (10.0 - 15.0 * x + 6.0 * x ** 2)


def _velocity_bump(sigma: np.ndarray, T: float) -> np.ndarray:
    """``T sigma (1 - sigma)^3``: 0 at both ends, slope 1 per second at 0, flat at 1."""
    x = np.clip(sigma, 0.0, 1.0)
    return T * x * (1.0 - x) ** 3


def _fit(times: np.ndarray, q: np.ndarray, v0: np.ndarray, source) -> JointPlan:
    pp = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(times, q.T, np.asarray(v0, float).reshape(-1, 1),
                                                                   np.zeros((q.shape[1], 1)))
    qd = pp.derivative(1)
    return JointPlan(source, pp, qd, qd.derivative(1))


def peak_speed_ratio(plan: JointPlan, vmax: np.ndarray, n: int = 2000) -> float:
    """max over the plan and the joints of |qd| / vmax (sampled at ``n`` times; 200 missed a 6 % peak)."""
    ts = np.linspace(plan.start_time, plan.end_time, n)
    qd = plan.qd.vector_values(ts)   # (D, n)
    return float(np.max(np.abs(qd) / np.asarray(vmax, float)[:, None]))


def _acceleration_bump(sigma: np.ndarray, T: float) -> np.ndarray:
    """``T^2 sigma^2 (1 - sigma)^3 / 2``: 0 with zero slope at 0, second derivative 1 per s^2 there, flat at 1."""
    x = np.clip(sigma, 0.0, 1.0)
    return 0.5 * T * T * x * x * (1.0 - x) ** 3


def blend_plan(traj: ConditionedTrajectory, now: float, q0: np.ndarray, v0: np.ndarray, lower: np.ndarray,
               upper: np.ndarray, vmax: np.ndarray | None = None, *, blend_time: float = BLEND_TIME,
               margin: float = LIMIT_MARGIN, a0: np.ndarray | None = None) -> JointPlan:
    """The rest of ``traj`` from ``now`` on, joined to the running command ``(q0, v0)`` without a jump.

    ``q(t) = p(t) + f(s) (q0 - p(now)) + b(s) (v0 - p'(now)) [+ c(s) (...)]`` with ``p`` the
    trajectory's mean played from its ``start_time`` on :func:`trajectory_clock` (speeding up
    from rest, slowing down to rest at its end), ``s = (t - now) / blend_time``,
    ``f`` a quintic fade and ``b`` a velocity bump, so ``q(now) = q0`` and
    ``qd(now) = v0``; then a cubic with continuous second derivatives through knots
    of that curve (start velocity ``v0``, end velocity 0), positions clipped to the
    limits minus ``margin``. If ``vmax`` is given and the plan is faster, the part
    after ``now`` and the blend are slowed down (time stretched) until it is not. Given the
    running command's acceleration ``a0``, an acceleration bump ``c`` makes the curve start
    with it too (``p`` is then a C2 spline of the mean), so a re-plan is no torque step
    either (8-10 rad/s^2 in the closed loop without it; the source passes it).

    Parameters
    ----------
    traj : ConditionedTrajectory
    now : float
    q0, v0 : arrays, shape (D,)
        The running command's position and velocity at ``now``.
    lower, upper : arrays, shape (D,)
    vmax : array, shape (D,), optional
        Joint velocity limits (rad/s).
    a0 : array, shape (D,), optional
        The running command's acceleration at ``now`` (continued if given).
    """
    mean = np.asarray(traj.mean, float)
    n = mean.shape[0]
    duration = max(float(traj.duration), MIN_DURATION)
    tail = tail_of(duration)
    t_traj = traj.start_time + duration * np.linspace(0.0, 1.0, n)

    smooth = CubicSpline(t_traj, mean, axis=0, bc_type="natural")   # C2: its acceleration is defined

    def played(t):  # the mean on its own clock, speeding up from and slowing down to rest
        tau = traj.start_time + trajectory_clock(np.asarray(t, float) - traj.start_time, duration, tail)
        return smooth(np.clip(tau, t_traj[0], t_traj[-1]))

    end = max(t_traj[-1] + 2.0 * tail, now + blend_time)

    def at(stretch: float) -> JointPlan:
        span = (end - now) * stretch
        times = now + span * np.linspace(0.0, 1.0, max(n, 20) + 20)
        # the trajectory's own clock, slowed by `stretch` after now
        p = played(now + (times - now) / stretch)
        dt = 1e-3
        p_now = played(now)
        p_dot = (played(now + dt) - p_now) / dt / stretch
        T_b = blend_time * stretch
        sig = (times - now) / T_b
        q = p + np.outer(_quintic_fade(sig), q0 - p_now) + np.outer(_velocity_bump(sig, T_b), v0 - p_dot)
        if a0 is not None and stretch == 1.0:  # and the running command's acceleration (the velocity bump
            # adds -6/T (v0 - p')); not once the blend must be slowed down: the bump's velocity grows with T
            p_ddot = (played(now + 2 * dt) - 2 * played(now + dt) + p_now) / (dt * dt) / (stretch * stretch)
            q += np.outer(_acceleration_bump(sig, T_b), np.asarray(a0, float) - p_ddot + 6.0 / T_b * (v0 - p_dot))
        q = np.clip(q, np.asarray(lower) + margin, np.asarray(upper) - margin)
        q[0] = q0
        return _fit(times, q, v0, traj)

    return _within_speed(at, vmax)


def stop_plan(now: float, q0: np.ndarray, v0: np.ndarray, lower: np.ndarray, upper: np.ndarray, *,
              stop_time: float = STOP_TIME, margin: float = LIMIT_MARGIN) -> JointPlan:
    """Decelerate from ``(q0, v0)`` to rest in ``stop_time`` and hold: ``q = q0 + v0 T (s - s^3 + s^4 / 2)``.

    Velocity falls from ``v0`` to 0 with zero acceleration at the end; the robot
    stops ``v0 T / 2`` further on (clipped to the limits). Unlike a re-plan, the stop does
    not continue the running command's acceleration: it decelerates at once, so the
    command never speeds up after the skill was given up (an acceleration step, deliberately).
    """
    T = float(stop_time)
    times = now + T * np.linspace(0.0, 1.0, 20)
    s_ = np.linspace(0.0, 1.0, 20)
    q = np.asarray(q0, float) + np.outer(T * (s_ - s_ ** 3 + 0.5 * s_ ** 4), v0)
    q = np.clip(q, np.asarray(lower) + margin, np.asarray(upper) - margin)
    q[0] = q0
    return _fit(times, q, v0, None)


def desired_at(plan: JointPlan | None, q_hold: np.ndarray, time: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Desired (q, v, a) at ``time``: hold before the plan starts and its last point after it ends."""
    nq = q_hold.shape[0]
    if plan is None or time < plan.start_time:
        return q_hold, np.zeros(nq), np.zeros(nq)
    if time >= plan.end_time:
        return plan.q.value(plan.end_time)[:, 0], np.zeros(nq), np.zeros(nq)
    return plan.q.value(time)[:, 0], plan.qd.value(time)[:, 0], plan.qdd.value(time)[:, 0]


class JointTrajectorySource(LeafSystem):
    """Desired state [q; v] and acceleration for an inverse-dynamics controller.

    .. pydrake_system::

        name: JointTrajectorySource
        input_ports:
        - robot_trajectory
        - measured_state
        output_ports:
        - desired_state
        - desired_acceleration

    While no trajectory is given (pending or unknown) it holds the pose
    latched from ``measured_state`` ([q; v]) at initialization (a trial
    start), or ``q_default`` if the context was never initialized.  A new
    :class:`ConditionedTrajectory` on ``robot_trajectory`` is turned into a
    smooth :class:`JointPlan` in an update every 1/64 s (blended into the
    running plan, see the module docstring) and cached in abstract state; the
    outputs only evaluate it. A trajectory withdrawn while a plan runs stops
    the robot (:func:`stop_plan`).

    Parameters
    ----------
    lower, upper : array, shape (D,)
        Joint limits (rad).
    q_default : array, shape (D,)
        Pose held before any measurement was latched.
    velocity_limits : array, shape (D,), optional
        Joint speed limits (rad/s) every plan is slowed down to respect.
    """

    def __init__(self, lower, upper, q_default, velocity_limits=None):
        super().__init__()
        self._lower = np.asarray(lower, float).copy()
        self._upper = np.asarray(upper, float).copy()
        q_default = np.asarray(q_default, float).copy()
        n = q_default.shape[0]
        if self._lower.shape != (n,) or self._upper.shape != (n,) or (self._upper <= self._lower).any():
            raise ValueError(f"joint limits must be two arrays of shape ({n},) with upper > lower")
        self._n = n
        self._vmax = None if velocity_limits is None else np.asarray(velocity_limits, float).copy()
        self._memo = (None, None)
        self._trajectory = self.DeclareAbstractInputPort("robot_trajectory", AbstractValue.Make(None))
        self._measured = self.DeclareVectorInputPort("measured_state", 2 * n)
        # (q_hold (n,), plan or None)
        self._state = self.DeclareAbstractState(AbstractValue.Make((q_default, None)))
        self.DeclareInitializationUnrestrictedUpdateEvent(self._latch)
        self.DeclarePeriodicUnrestrictedUpdateEvent(SOURCE_PERIOD, 0.0, self._update)
        self.DeclareForcedUnrestrictedUpdateEvent(self._update)
        deps = {self.abstract_state_ticket(self._state), self.time_ticket()}
        self._desired_state = self.DeclareVectorOutputPort("desired_state", 2 * n, self._calc_state,
                                                           prerequisites_of_calc=deps)
        self._desired_acceleration = self.DeclareVectorOutputPort("desired_acceleration", n, self._calc_acceleration,
                                                                  prerequisites_of_calc=deps)

    def hold_pose(self, context: Context) -> np.ndarray:
        return context.get_abstract_state(self._state).get_value()[0]

    def plan(self, context: Context) -> JointPlan | None:
        return context.get_abstract_state(self._state).get_value()[1]

    def _latch(self, context: Context, state: State) -> None:
        q = np.array(self._measured.Eval(context)[:self._n])
        state.get_mutable_abstract_state(self._state).set_value((q, None))

    def _update(self, context: Context, state: State) -> None:
        traj = self._trajectory.Eval(context)
        q_hold, plan = context.get_abstract_state(self._state).get_value()
        now = context.get_time()
        if traj is None:
            if plan is not None and plan.source is not None:  # withdrawn: stop where the command is
                q0, v0, _ = desired_at(plan, q_hold, now)
                new = stop_plan(now, q0, v0, self._lower, self._upper)
                state.get_mutable_abstract_state(self._state).set_value((q_hold, new))
            return
        if not isinstance(traj, ConditionedTrajectory):
            raise ValueError(f"robot_trajectory must be a ConditionedTrajectory, got {type(traj).__name__}")
        if plan is not None and plan.source is not None and plan.source.key == traj.key:
            return
        if plan is None:  # from rest where it holds, never from a start already past (no jump)
            new = build_plan(traj, q_hold, self._lower, self._upper, self._vmax, start=max(traj.start_time, now))
        else:
            q0, v0, a0 = desired_at(plan, q_hold, now)
            new = blend_plan(traj, now, q0, v0, self._lower, self._upper, self._vmax, a0=a0)
        state.get_mutable_abstract_state(self._state).set_value((q_hold, new))

    def _desired(self, context: Context):
        """(q, v, a) at the context's time; the two outputs ask at every plant step, so the last answer is kept."""
        q_hold, plan = context.get_abstract_state(self._state).get_value()
        t = context.get_time()
        # the memo holds the objects themselves, not their ids: a freed plan's id can be reused by the next
        key, hit = self._memo
        if key is None or key[0] is not plan or key[1] is not q_hold or key[2] != t:
            hit = desired_at(plan, q_hold, t)
            self._memo = ((plan, q_hold, t), hit)
        return hit

    def _calc_state(self, context: Context, output: BasicVector) -> None:
        q, v, _ = self._desired(context)
        output.SetFromVector(np.concatenate([q, v]))

    def _calc_acceleration(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._desired(context)[2])
