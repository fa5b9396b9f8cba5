"""``JointTrajectorySource``: desired joint state and acceleration for the controller."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem, State
from pydrake.trajectories import PiecewisePolynomial

from drake_skills.systems.conditioner import ConditionedTrajectory

#: Period at which a new conditioned trajectory is looked for (s); exact in binary.
SOURCE_PERIOD = 1.0 / 64.0
#: Shortest duration a trajectory is stretched to (s), so velocities stay finite.
MIN_DURATION = 0.25


@dataclass(frozen=True, eq=False)
class JointPlan:
    """A smooth joint trajectory built once from a conditioned trajectory.

    Attributes
    ----------
    source : ConditionedTrajectory
        What it was built from (compared by ``key`` to spot a new one).
    q, qd, qdd : PiecewisePolynomial
        Position, velocity and acceleration over ``[start_time, end_time]``.
    """

    source: ConditionedTrajectory
    q: PiecewisePolynomial
    qd: PiecewisePolynomial
    qdd: PiecewisePolynomial

    @property
    def start_time(self) -> float:
        return self.q.start_time()

    @property
    def end_time(self) -> float:
        return self.q.end_time()


def plan_knots(traj: ConditionedTrajectory, q_hold: np.ndarray, lower: np.ndarray, upper: np.ndarray, *,
               blend_fraction: float = 0.2, margin: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """Knot times and positions for a conditioned trajectory, starting exactly at ``q_hold``.

    The offset ``q_hold - mean[0]`` is faded out with a smoothstep over the
    first ``blend_fraction`` of the motion, so the robot starts where it is
    without a jump; positions are clipped to ``[lower + margin, upper - margin]``.

    Returns
    -------
    times : array, shape (n,)
    q : array, shape (n, D)
    """
    mean = np.asarray(traj.mean, float)
    n = mean.shape[0]
    duration = max(float(traj.duration), MIN_DURATION)
    s = np.linspace(0.0, 1.0, n)
    z = np.clip(s / blend_fraction, 0.0, 1.0) if blend_fraction > 0 else np.ones(n)
    fade = 1.0 - (3 * z ** 2 - 2 * z ** 3)  # 1 at the start, 0 after the blend
    q = mean + np.outer(fade, np.asarray(q_hold, float) - mean[0])
    q = np.clip(q, np.asarray(lower) + margin, np.asarray(upper) - margin)
    return traj.start_time + duration * s, q


def build_plan(traj: ConditionedTrajectory, q_hold: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> JointPlan:
    """Shape-preserving cubic through :func:`plan_knots` with zero end velocities.

    Shape preservation keeps the curve between neighbouring knots, so it
    stays inside the clipped joint limits.
    """
    times, q = plan_knots(traj, q_hold, lower, upper)
    pp = PiecewisePolynomial.CubicShapePreserving(times, q.T, zero_end_point_derivatives=True)
    qd = pp.derivative(1)
    return JointPlan(traj, pp, qd, qd.derivative(1))


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
    smooth :class:`JointPlan` once, in an update every 1/64 s, and cached in
    abstract state; the outputs only evaluate it.

    Parameters
    ----------
    lower, upper : array, shape (D,)
        Joint limits (rad).
    q_default : array, shape (D,)
        Pose held before any measurement was latched.
    """

    def __init__(self, lower, upper, q_default):
        super().__init__()
        self._lower = np.asarray(lower, float).copy()
        self._upper = np.asarray(upper, float).copy()
        q_default = np.asarray(q_default, float).copy()
        n = q_default.shape[0]
        if self._lower.shape != (n,) or self._upper.shape != (n,) or (self._upper <= self._lower).any():
            raise ValueError(f"joint limits must be two arrays of shape ({n},) with upper > lower")
        self._n = n
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
        if traj is None or (plan is not None and plan.source.key == traj.key):
            return
        if not isinstance(traj, ConditionedTrajectory):
            raise ValueError(f"robot_trajectory must be a ConditionedTrajectory, got {type(traj).__name__}")
        state.get_mutable_abstract_state(self._state).set_value(
            (q_hold, build_plan(traj, q_hold, self._lower, self._upper)))

    def _calc_state(self, context: Context, output: BasicVector) -> None:
        q_hold, plan = context.get_abstract_state(self._state).get_value()
        q, v, _ = desired_at(plan, q_hold, context.get_time())
        output.SetFromVector(np.concatenate([q, v]))

    def _calc_acceleration(self, context: Context, output: BasicVector) -> None:
        q_hold, plan = context.get_abstract_state(self._state).get_value()
        output.SetFromVector(desired_at(plan, q_hold, context.get_time())[2])
