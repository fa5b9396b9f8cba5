"""The simulated salad scenario (paper Sec. 4.2, Fig. 5): 10 subjects x 5 tasks.

Two subject models (:data:`SUBJECT_MODELS`):

``"styled"`` (the default; :mod:`drake_skills.scenario.salad_styles`)
    People who differ in how they move: they reach for the objects where they stand on
    the table, from a seat and posture of their own, with the left or the right hand,
    elbow up or down, over or around the bowl, standing up by leaning forward, pushing
    off the table or turning, with pauses, and some of them tracked by a noisy camera.
``"classic"`` (the first model, kept for comparison)
    One task geometry scaled per person: every motion starts at the subject's rest
    position on the table edge, first lifts the hand the same way for every task (the
    shared first segment, about a quarter of the path), then bends toward the task's
    nominal goal (``tasks.<name>.reach`` of the scene): the knife (board), the tomato,
    the bowl, the shelf (dressing), or up and back as the person rises (standup).
    Subjects differ in arm length, workspace size, seated position, start offset, speed
    profile, path curvature, personal goal offsets of a few centimetres and noise.
    Subjects 3 and 7 are sloppy (:data:`SLOPPY_SUBJECTS`): large via-point jitter and two
    alternating path styles.

Human
    One wrist of a seated person, 3-D positions in metres (world frame of
    ``models/salad/scene.yaml``) at 150 Hz. The path is timed by a skewed minimum-jerk
    profile (bell-shaped speed), and the hand then holds still while the robot completes
    the handover.
Calibration (Sec. 4.2.2)
    Half circles at arm's reach (arm length + torso lean) in the x-y plane (at table
    height, centred at the shoulder) and in the z-y plane (in front of the body, from
    table height over the top), arrays of shape (T, 3). Every demonstration lies inside
    their bounding box by construction (the path's control points are kept inside it).
Robot
    IIWA7 joint angles (radians) from Drake inverse kinematics
    (:mod:`drake_skills.sim.salad_robot`): from :data:`~drake_skills.sim.models.HOME_Q`
    to the task's fixed grasp pose (solved once per task and cached), then to a handover
    pose that follows the person's final wrist position, seeded with the grasp solution.
    The joint trajectory is two minimum-jerk segments in joint space (stopping at the
    grasp), starting shortly after the human starts.

Randomness: every draw comes from ``np.random.default_rng`` seeded by
``(seed, subject index, stream, ...)``, so subject k's data does not depend on how
many subjects or which tasks are generated, and the same seed gives the same bytes.

A scenario sits above ``sim/``: it reads the scene of :mod:`drake_skills.sim.models` and
the robot's inverse kinematics, and makes :class:`~drake_skills.data.demonstration.Demonstration`
objects (``data/``, the bottom layer, imports nothing of it).
"""
from __future__ import annotations

import logging
from typing import Callable

import numpy as np

from drake_skills.data.demonstration import Demonstration
from drake_skills.scenario import salad_styles
from drake_skills.scenario.salad_subject import (_STREAM_CALIBRATION, _STREAM_DEMO, _STREAM_SUBJECT,
                                                 _TASK_DURATION, RATE_HZ, SLOPPY_SUBJECTS, TABLE_TOP_Z, TASKS,
                                                 ReachPlan, Subject, SubjectData, _bezier, _calibration_z,
                                                 _check_subject, _draw_body, _rng, _scene, _unit, min_jerk)
from drake_skills.sim.config import SUBJECT_MODELS
from drake_skills.sim.models import IIWA7_JOINT_LIMITS, IIWA7_VELOCITY_LIMITS
from drake_skills.sim.salad_robot import salad_robot

__all__ = ["RATE_HZ", "SLOPPY_SUBJECTS", "SUBJECT_MODELS", "TABLE_TOP_Z", "TASKS", "ReachPlan", "Subject",
           "SubjectData", "calibration_motions", "generate_salad", "generate_subject", "make_demonstration",
           "make_subject", "min_jerk", "plan_reach", "robot_motion"]

log = logging.getLogger(__name__)
#: The subject model of :func:`make_subject` and :func:`generate_subject` when none is named.
DEFAULT_SUBJECT_MODEL = SUBJECT_MODELS[0]


def _check_model(model: str) -> str:
    if model not in SUBJECT_MODELS:
        raise ValueError(f"unknown subject model {model!r}; subject models are {SUBJECT_MODELS}")
    return model


def make_subject(index: int, seed: int = 0, model: str = DEFAULT_SUBJECT_MODEL) -> Subject:
    """Draw the body and habits of subject ``index`` (1-based).

    Parameters
    ----------
    index : int
        1-based subject number; subjects in :data:`SLOPPY_SUBJECTS` are sloppy.
    seed : int
        Non-negative base seed.
    model : str
        One of :data:`SUBJECT_MODELS`.
    """
    if _check_model(model) == "styled":
        return salad_styles.make_styled_subject(index, seed)
    _check_subject(index, seed)
    cfg = _scene().person
    rng = _rng(seed, index, _STREAM_SUBJECT)
    arm, lean, scale = _draw_body(cfg, rng)
    seat = np.array([rng.normal(0, 0.03), rng.normal(0, 0.03), rng.normal(0, 0.03)])
    shoulder = np.asarray(cfg.shoulder, float) + seat
    # the wrist rests on the table edge: it moves with the seat in x-y, not in z
    start = np.array([rng.normal(0, 0.02), rng.normal(0, 0.02), rng.normal(0, 0.003)])
    rest = np.asarray(cfg.wrist_rest, float) + np.array([seat[0], seat[1], 0.0]) + start
    sloppy = int(index) in SLOPPY_SUBJECTS
    offsets = {task: rng.normal(0.0, 0.025, 3) for task in TASKS}
    return Subject(
        name=f"subject{int(index)}", arm_length=arm, index=int(index), reach=arm + lean,
        workspace_scale=scale, shoulder=shoulder, rest=rest,
        duration=float(rng.uniform(1.1, 1.8)), profile_skew=float(rng.uniform(-0.6, 1.4)),
        curvature=float(rng.uniform(0.04, 0.12)), curvature_angle=float(rng.uniform(-0.9, 0.9)),
        noise=float(rng.uniform(0.002, 0.005)), jitter=0.045 if sloppy else float(rng.uniform(0.008, 0.014)),
        task_offsets=offsets, sloppy=sloppy)


def calibration_motions(subject: Subject, seed: int = 0) -> list[np.ndarray]:
    """The calibration half circles of Sec. 4.2.2 (Fig. 5(c)).

    Parameters
    ----------
    subject : Subject
    seed : int

    Returns
    -------
    [xy, zy] : list of array, shape (T, 3)
        ``xy``: a horizontal half circle of radius ``subject.reach`` about the shoulder at
        table height, from the right through the front to the left. ``zy``: a vertical
        half circle of the same radius in the plane ``x = shoulder_x + 0.45 reach``,
        from the right at table height over the top to the left.
    """
    rng = _rng(seed, subject.index, _STREAM_CALIBRATION)
    R, (xs, ys, _) = subject.reach, subject.shoulder
    zc = _calibration_z(subject)
    out = []
    for plane in ("xy", "zy"):
        T = float(rng.uniform(2.5, 3.5))
        t = np.arange(int(round(T * RATE_HZ)) + 1) / RATE_HZ
        a = np.pi * min_jerk(t / T)  # angle 0 -> pi
        if plane == "xy":
            p = np.stack([xs + R * np.sin(a), ys - R * np.cos(a), np.full_like(a, zc)], axis=1)
        else:
            p = np.stack([np.full_like(a, xs + 0.45 * R), ys - R * np.cos(a), zc + R * np.sin(a)], axis=1)
        p = p + rng.normal(0.0, 0.0005, p.shape)  # motion-capture noise
        out.append(p)
    return out

def plan_reach(subject: Subject, task: str, rng: np.random.Generator) -> ReachPlan:
    """Plan one wrist motion of ``subject`` doing ``task``.

    The path is a straight lift off the table edge shared by all tasks (``person.lift``
    of the scene, scaled to the subject), then a cubic Bezier curve leaving the lift
    tangentially and bending (``curvature``) toward the task's goal. All control points
    lie inside the subject's calibration box (shrunk by 2.5 cm), so the path does too.

    Parameters
    ----------
    subject : Subject
    task : str
        One of :data:`TASKS`.
    rng : Generator
        The demonstration's random stream (a fixed number of draws).
    """
    cfg = _scene()
    person, tcfg = cfg.person, cfg.tasks[task]
    s = subject.workspace_scale
    lo, hi = subject.calibration_box()
    lo_in, hi_in = lo + 0.025, hi - 0.025
    lo_in[2] = max(lo_in[2], TABLE_TOP_Z + 0.04)

    def inside(p):
        return np.clip(p, lo_in, hi_in)

    p0 = subject.rest + rng.normal(0, [0.008, 0.008, 0.003]) * (1.8 if subject.sloppy else 1.0)
    p0 = np.clip(p0, lo + 0.02, hi - 0.02)
    p1 = inside(p0 + s * np.asarray(person.lift, float) * (1 + rng.normal(0, 0.04)))
    goal = (subject.rest + s * (np.asarray(tcfg.reach, float) - np.asarray(person.wrist_rest, float))
            + subject.task_offsets[task] + rng.normal(0, subject.jitter, 3))
    # no further than 92 % of the reach from the shoulder, and inside the calibrated box
    d = goal - subject.shoulder
    if np.linalg.norm(d) > 0.92 * subject.reach:
        goal = subject.shoulder + 0.92 * subject.reach * _unit(d)
    goal = inside(goal)

    d1 = _unit(p1 - p0)
    chord = goal - p1
    L = float(np.linalg.norm(chord))
    up = np.array([0.0, 0.0, 1.0])
    n_up = _unit(up - (up @ chord) / max(L * L, 1e-12) * chord)  # "up", perpendicular to the chord
    n_side = _unit(np.cross(chord, n_up))
    angle = subject.curvature_angle + rng.normal(0, 0.15)
    curv = subject.curvature * (1 + rng.normal(0, 0.15))
    style, extra = rng.random(), rng.normal(0, 0.06)
    if subject.sloppy:
        # two path styles (over the top / swung sideways) and a loose curvature
        angle += (np.pi / 2) * (1.0 if style < 0.5 else -0.2)
        curv = abs(curv * 2.2 + extra)
    bulge = curv * L * (np.cos(angle) * n_up + np.sin(angle) * n_side)
    b1 = inside(p1 + 0.35 * L * d1)
    b2 = inside(goal + 0.3 * (b1 - goal) + (4.0 / 3.0) * bulge)
    seg_a = p0 + np.linspace(0, 1, 200)[:, None] * (p1 - p0)
    seg_b = _bezier(np.stack([p1, b1, b2, goal]), 1200)
    path = np.concatenate([seg_a, seg_b[1:]])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])

    jit = 0.15 if subject.sloppy else 0.07
    T_move = subject.duration * _TASK_DURATION[task] * float(np.exp(rng.normal(0, jit)))
    T_hold = float(rng.uniform(0.5, 0.8))
    skew = subject.profile_skew + rng.normal(0, 0.2)
    noise = np.stack([rng.uniform(0.4, 1.6, (3, 3)), rng.uniform(0, 2 * np.pi, (3, 3)),
                      rng.normal(0, subject.noise / np.sqrt(3), (3, 3))])
    return ReachPlan(path=path, arc=arc, goal=goal, T_move=T_move, T_hold=T_hold, skew=skew, noise=noise)

# --------------------------------------------------------------------------- robot
def robot_motion(task: str, wrist_goal: np.ndarray, t_human: float,
                 rng: np.random.Generator) -> tuple[float, Callable[[np.ndarray], np.ndarray]]:
    """Plan the robot's joint trajectory home -> grasp -> handover.

    The two minimum-jerk segments (stopping at the grasp) last long enough that no joint
    exceeds 85 % of its speed limit; the robot starts 0.1-0.25 s after the human.

    Parameters
    ----------
    task : str
    wrist_goal : array, shape (3,)
        The person's wrist at the end of the reach (the handover follows it).
    t_human : float
        Duration of the human motion (reach + hold), seconds.
    rng : Generator

    Returns
    -------
    t_end : float
        When the robot arrives at the handover, seconds (may exceed ``t_human``).
    q_of_t : callable
        Maps times (T,) to joint angles (T, 7), radians.
    """
    ik = salad_robot()
    q_grasp = ik.grasp(task)
    q_hand = ik.handover(task, wrist_goal)
    t_start = float(rng.uniform(0.1, 0.25))
    slack = float(rng.uniform(0.0, 0.1))
    frac = float(rng.uniform(0.45, 0.55))
    span = t_human - slack - t_start
    vmax = 0.85 * IIWA7_VELOCITY_LIMITS
    T1 = max(frac * span, 1.875 * float(np.max(np.abs(q_grasp - ik.home) / vmax)))  # peak = 1.875 dq / T
    T2 = max((1 - frac) * span, 1.875 * float(np.max(np.abs(q_hand - q_grasp) / vmax)))
    t_grasp, t_end = t_start + T1, t_start + T1 + T2

    def q_of_t(t):
        t = np.asarray(t, float)
        s1 = min_jerk((t - t_start) / T1)[:, None]
        s2 = min_jerk((t - t_grasp) / T2)[:, None]
        return ik.home + s1 * (q_grasp - ik.home) + s2 * (q_hand - q_grasp)

    return t_end, q_of_t

def make_demonstration(subject: Subject, task: str, k: int, seed: int = 0) -> Demonstration:
    """Demonstration ``k`` (0-based) of ``task`` by ``subject`` (classic or styled).

    Returns
    -------
    Demonstration
        ``t`` (T,) from 0 at 150 Hz, ``human`` (T, 3) wrist in metres, ``robot`` (T, 7)
        IIWA7 joints in radians; the hand holds still until the robot has arrived.
    """
    rng = _rng(seed, subject.index, _STREAM_DEMO, TASKS.index(task), k)
    styled = subject.style is not None
    plan = salad_styles.plan_styled_reach(subject, task, rng) if styled else plan_reach(subject, task, rng)
    wrist_goal = plan.position(np.array([plan.T_move]))[0]
    t_human = plan.T_move + plan.T_hold
    t_end, q_of_t = robot_motion(task, wrist_goal, t_human, rng)
    T = max(t_human, t_end + float(rng.uniform(0.05, 0.15)))
    t = np.arange(int(round(T * RATE_HZ)) + 1) / RATE_HZ
    if styled:
        wrist = salad_styles.track(subject, t, plan.position(t), rng)
    else:
        wrist = plan.position(t) + rng.normal(0, 0.0005, (t.shape[0], 3))  # motion-capture noise
    q = q_of_t(t)
    lo, hi = IIWA7_JOINT_LIMITS
    if (q < lo).any() or (q > hi).any():
        raise AssertionError(f"{subject.name} {task} {k}: robot trajectory leaves the joint limits")
    return Demonstration(t=t, human=wrist, robot=q, task=task, subject=subject.name,
                         name=f"{subject.name}/{task}_{k:02d}")


# --------------------------------------------------------------------------- generation
def generate_subject(index: int, n_demos: int = 15, seed: int = 0, tasks=TASKS,
                     model: str = DEFAULT_SUBJECT_MODEL) -> SubjectData:
    """Calibration and demonstrations of one subject.

    Parameters
    ----------
    index : int
        1-based subject number (``"subject{index}"``).
    n_demos : int
        Demonstrations per task.
    seed : int
        Non-negative base seed.
    tasks : sequence of str
        Subset of :data:`TASKS`.
    model : str
        One of :data:`SUBJECT_MODELS`.

    Returns
    -------
    SubjectData
        ``demos`` ordered by task then demo; ``Demonstration.name`` like ``"subject3/bowl_07"``
        (demo numbers from 0), ``t`` shape (T,), ``human`` (T, 3), ``robot`` (T, 7).
    """
    tasks = tuple(tasks)
    unknown = [t for t in tasks if t not in TASKS]
    if unknown:
        raise ValueError(f"unknown task(s) {unknown}; tasks are {TASKS}")
    if int(n_demos) < 0:
        raise ValueError(f"n_demos must be non-negative, got {n_demos!r}")
    subject = make_subject(index, seed, model)
    calibration = calibration_motions(subject, seed)
    if subject.style is not None:
        calibration = salad_styles.track_calibration(subject, calibration, _rng(seed, index, _STREAM_CALIBRATION, 1))
    data = SubjectData(subject=subject, calibration=calibration)
    for task in tasks:
        for k in range(int(n_demos)):
            data.demos.append(make_demonstration(subject, task, k, seed))
        log.debug("%s: %d demonstrations of %s", subject.name, n_demos, task)
    return data


def generate_salad(n_subjects: int = 10, n_demos: int = 15, seed: int = 0, tasks=TASKS,
                   model: str = DEFAULT_SUBJECT_MODEL) -> list[SubjectData]:
    """Subjects 1..n_subjects of the salad scenario (see :func:`generate_subject`)."""
    if int(n_subjects) < 1:
        raise ValueError(f"n_subjects must be at least 1, got {n_subjects!r}")
    return [generate_subject(i, n_demos, seed, tasks, model) for i in range(1, int(n_subjects) + 1)]
