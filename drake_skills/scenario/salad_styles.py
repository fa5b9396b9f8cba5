"""Styled subjects of the salad scenario: people who differ in how they move, not only in size.

The classic subjects (:func:`drake_skills.scenario.salad.make_subject` with ``model="classic"``)
share one task geometry scaled by arm length. A styled subject reaches for the objects where
they stand on the table (``tasks.<name>.target`` of ``models/salad/scene.yaml``): the knife
beside the place is grasped where it lies; the tomato, the bowl and the shelf are out of easy
reach, so the hand goes toward them and stops at the subject's stretch (the robot passes the
object). The seated body scales with the arm (shoulder height and width, and so the calibrated
workspace), and each person has habits, drawn once from the distributions below (the seed,
the subject index and :data:`STREAM_STYLE` seed them; each demonstration draws its own
trial-to-trial variation from the demonstration's stream):

================  ========================================================================
posture, seat     chair moved N(0, 3 cm) along and across the table (at most 6 cm);
                  slouch U(0, 1): the shoulder up to 5 cm lower and 3 cm further forward
handedness        the working, tracked hand: left for :data:`LEFT_HANDED_SUBJECTS` (the
                  body mirrored about its midline, the table as it is), right otherwise
elbow             ``"up"`` or ``"down"`` (P = 1/2): reaches bulge up, or outward with a
                  lower lift; the knife is taken from above, or low from the side
dressing path     ``"over"`` the bowl (U(15, 22) cm above it) or ``"around"`` it on the
                  person's side (P = 1/2) on the way to the shelf
stand-up          ``"lean"`` (P = 0.4): forward, then up; ``"push"`` (0.35): press on the
                  table, creep while the body rises over the hand (0.35-0.55 s), then lift
                  the hand; ``"turn"`` (0.25): swing the hand out to the side while turning
                  out of the chair; via point and end of the wrist path per person
                  (:func:`_draw_standup_paths`, a few to 20 cm ranges)
knife hold        after the grasp (board) the knife is held U(10, 16) cm in front of the
                  rest, U(8, 14) cm toward the midline, U(5, 22) cm above the table
lift, stretch     every reach starts by lifting the hand U(4, 7) cm forward and U(7, 11) cm
                  up; reaches stop at U(0.84, 0.92) of the arm's reach from the shoulder
speed, pauses     duration U(1.1, 1.8) s per nominal reach, speed-profile skew U(-0.6, 1.4);
                  a hesitation (a stop of U(0.08, 0.25) s inside the longest stroke) in
                  U(0, 0.3) of the motions; the knife grasp stops U(0.08, 0.25) s
tracker           motion capture (0.5 mm noise), or for :data:`CAMERA_SUBJECTS` a camera
                  at :data:`CAMERA_HZ`: U(3, 5) mm noise per frame, a slow error of
                  U(4, 8) mm (0.2-1 Hz), the tracker's own smoothing (exponential,
                  U(60, 120) ms, so it lags), and dropouts (U(0.5, 1.5) per second,
                  U(0.05, 0.25) s each) that repeat the last value
trial to trial    via points N(0, j), the knife hold N(0, 0.8 j), the goals of tomato and
                  bowl N(0, 2 j) (gestures), of the shelf and the stand-up N(0, 1.2 j), the
                  knife grasp N(0, 0.7 j), with j = U(1.0, 1.6) cm per person; the start
                  N(0, 1 cm); path bulge U(4, 9) % of the chord, +-25 % and +-0.25 rad
================  ========================================================================

The sloppy subjects (:data:`~drake_skills.scenario.salad_subject.SLOPPY_SUBJECTS`) jitter
j = 2 cm (1.8 times as much at the start) and switch their elbow, dressing-path and
stand-up style from one trial to the next (P = 0.25, 0.25, 0.2). Subjects beyond the ten of
the experiment are left-handed, camera-tracked and sloppy with the frequencies of the ten
(0.1, 0.2, 0.2).

Every path is built from cubic Bezier pieces whose control points lie inside the
subject's calibration box shrunk by 2.5 cm (z: at least 4.5 cm above the table), so the
calibration bounds the noise-free path by construction and the tracker's errors stay
inside the margin.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_skills.scenario.salad_subject import (_STREAM_SUBJECT, _TASK_DURATION, SLOPPY_SUBJECTS, TABLE_TOP_Z,
                                                 TASKS, Subject, _check_subject, _draw_body, _rng, _scene,
                                                 _skewed_profile, _unit)

#: 1-based subjects who work (and are tracked) with the left hand.
LEFT_HANDED_SUBJECTS = (6,)
#: 1-based subjects tracked by a camera instead of motion capture (noise and dropouts).
CAMERA_SUBJECTS = (4, 9)
#: Frame rate of the camera tracker (Hz); its values are repeated until the next frame.
CAMERA_HZ = 30.0
#: Stand-up styles and their probabilities.
STANDUP_STYLES = {"lean": 0.4, "push": 0.35, "turn": 0.25}
#: Random stream of the style draws (second seed word after the subject index).
STREAM_STYLE = 3
#: How far the styled control points stay inside the calibration box (metres).
_MARGIN = 0.025


@dataclass(frozen=True)
class SubjectStyle:
    """How one styled person moves (drawn by :func:`make_styled_subject`)."""

    #: "right" or "left": the hand that works and is tracked.
    hand: str
    #: "up" or "down" (reaches over the top, or low and outward).
    elbow: str
    #: "over" or "around" the bowl on the way to the shelf (dressing).
    dressing_path: str
    #: How high over the bowl the "over" path passes (m above the bowl's target).
    over_height: float
    #: "lean", "push" or "turn" (see the module docstring).
    standup: str
    #: Seat offset (x, y, 0) from the nominal chair, metres.
    seat: tuple
    #: 0 (upright) .. 1 (slouched).
    slouch: float
    #: Where the knife is held after the grasp: forward, toward the midline, above the table (m).
    knife_hold: tuple
    #: The lift off the table that starts every reach: forward and up (m, nominal body).
    lift: tuple
    #: Per stand-up style, the via point and the end of the wrist path relative to the rest
    #: position (forward, outward, up; m, nominal body); the person uses ``standup``, a
    #: sloppy one sometimes another.
    standup_paths: dict
    #: Reaches stop at this fraction of the reach from the shoulder.
    stretch: float
    #: Fraction of motions with a hesitation.
    hesitation: float
    #: "mocap" or "camera".
    tracker: str
    #: Camera tracker: white noise (m), slow error amplitude (m), dropouts per second.
    camera_noise: float = 0.0
    camera_drift: float = 0.0
    dropout_rate: float = 0.0
    #: Camera tracker: time constant of its exponential smoothing (s).
    camera_smoothing: float = 0.0

    @property
    def side(self) -> float:
        """-1 for the right hand, +1 for the left: the direction (in world y) away from the body's midline."""
        return -1.0 if self.hand == "right" else 1.0


def _flag(index: int, fixed: tuple, p: float, rng: np.random.Generator) -> bool:
    draw = bool(rng.random() < p)  # always drawn, so the draws after it do not depend on the index
    return int(index) in fixed if int(index) <= 10 else draw


def _draw_standup_paths(rng: np.random.Generator) -> dict:
    u = rng.uniform
    return {
        "lean": ((u(0.08, 0.20), u(-0.02, 0.04), u(0.0, 0.06)), (u(-0.14, 0.0), u(-0.02, 0.08), u(0.30, 0.50))),
        "push": ((u(0.04, 0.14), u(0.0, 0.05), -0.03), (u(-0.18, -0.04), u(0.0, 0.10), u(0.30, 0.48))),
        "turn": ((u(-0.04, 0.06), u(0.12, 0.26), u(0.06, 0.16)), (u(-0.22, -0.08), u(0.14, 0.30), u(0.30, 0.48))),
    }


def make_styled_subject(index: int, seed: int = 0) -> Subject:
    """Draw the body and the habits of styled subject ``index`` (1-based).

    The body (arm length, torso lean, reach scale, noise amplitude, speed) is drawn
    like the classic subject's; position, posture and style come from the
    distributions of the module docstring.
    """
    _check_subject(index, seed)
    cfg = _scene().person
    body = _rng(seed, index, _STREAM_SUBJECT)
    arm, lean, scale = _draw_body(cfg, body)
    rng = _rng(seed, index, STREAM_STYLE)
    left = _flag(index, LEFT_HANDED_SUBJECTS, 0.1, rng)
    camera = _flag(index, CAMERA_SUBJECTS, 0.2, rng)
    sloppy = _flag(index, SLOPPY_SUBJECTS, 0.2, rng)
    seat = np.append(np.clip(rng.normal(0, 0.03, 2), -0.06, 0.06), 0.0)
    slouch = float(rng.uniform(0, 1))
    style = SubjectStyle(
        hand="left" if left else "right", elbow="up" if rng.random() < 0.5 else "down",
        dressing_path="over" if rng.random() < 0.5 else "around", over_height=float(rng.uniform(0.15, 0.22)),
        standup=str(rng.choice(list(STANDUP_STYLES), p=list(STANDUP_STYLES.values()))),
        seat=tuple(seat), slouch=slouch, lift=(float(rng.uniform(0.04, 0.07)), float(rng.uniform(0.07, 0.11))),
        standup_paths=_draw_standup_paths(rng),
        knife_hold=(float(rng.uniform(0.10, 0.16)), float(rng.uniform(0.08, 0.14)), float(rng.uniform(0.05, 0.22))),
        stretch=float(rng.uniform(0.84, 0.92)), hesitation=float(rng.uniform(0.0, 0.3)),
        tracker="camera" if camera else "mocap", camera_noise=float(rng.uniform(0.003, 0.005)) if camera else 0.0,
        camera_drift=float(rng.uniform(0.004, 0.008)) if camera else 0.0,
        dropout_rate=float(rng.uniform(0.5, 1.5)) if camera else 0.0,
        camera_smoothing=float(rng.uniform(0.06, 0.12)) if camera else 0.0)
    # the seated body scales with the arm: shoulder above and behind the wrist rest, both
    # beside the body's midline; the chair moves both, the rest only half as far along x
    g = arm / cfg.arm_length
    (rx, ry, rz), (sx, sy, sz) = np.asarray(cfg.wrist_rest, float), np.asarray(cfg.shoulder, float)
    midline = float(cfg.seat[1]) + seat[1]
    shoulder = np.array([rx + seat[0] + g * (sx - rx) + 0.03 * slouch, midline + g * (sy - cfg.seat[1]),
                         rz + g * (sz - rz) - 0.05 * slouch])
    rest = (np.array([rx + 0.5 * seat[0], midline + g * (ry - cfg.seat[1]), rz])
            + np.array([rng.normal(0, 0.015), rng.normal(0, 0.015), rng.normal(0, 0.003)]))
    if left:  # the mirror image of the body about its midline; the table stays as it is
        shoulder[1] = 2 * midline - shoulder[1]
        rest[1] = 2 * midline - rest[1]
    return Subject(
        name=f"subject{int(index)}", arm_length=arm, index=int(index), reach=arm + lean, workspace_scale=scale,
        shoulder=shoulder, rest=rest, duration=float(rng.uniform(1.1, 1.8)),
        profile_skew=float(rng.uniform(-0.6, 1.4)), curvature=float(rng.uniform(0.04, 0.09)), curvature_angle=0.0,
        noise=float(rng.uniform(0.002, 0.005)), jitter=0.02 if sloppy else float(rng.uniform(0.010, 0.016)),
        task_offsets={task: rng.normal(0.0, 0.015, 3) for task in TASKS}, sloppy=sloppy, style=style)


# --------------------------------------------------------------------------- paths
def _through(points: list[np.ndarray], inside) -> np.ndarray:
    """A smooth curve through ``points`` (n >= 2, each (3,)): Catmull-Rom pieces as cubic Beziers.

    The Bezier control points are clipped by ``inside``; the curve lies in their convex
    hull, so it stays inside the box too. Returns shape (M, 3), 400 samples per piece.
    """
    P = [inside(np.asarray(p, float)) for p in points]
    ext = [2 * P[0] - P[1], *P, 2 * P[-1] - P[-2]]
    s = np.linspace(0, 1, 400)[:, None]
    out = []
    for i in range(len(P) - 1):
        a, b = P[i], P[i + 1]
        c1 = inside(a + (ext[i + 2] - ext[i]) / 6.0)
        c2 = inside(b - (ext[i + 3] - ext[i + 1]) / 6.0)
        seg = (1 - s) ** 3 * a + 3 * (1 - s) ** 2 * s * c1 + 3 * (1 - s) * s ** 2 * c2 + s ** 3 * b
        out.append(seg if i == 0 else seg[1:])
    return np.concatenate(out)


@dataclass(eq=False)
class StyledPlan:
    """A styled wrist motion: strokes that stop where they meet, each timed by a skewed minimum jerk.

    Attributes
    ----------
    path : array, shape (M, 3)
        Densely sampled path, metres (world).
    arc : array, shape (M,)
        Arc length along ``path`` from 0.
    knots : array, shape (n + 1,)
        Arc lengths where the hand stops (0 and ``arc[-1]`` included).
    durations, pauses, skews : array, shape (n,)
        Duration of each stroke, the stop after it (s; the last one is 0) and its profile skew.
    goal : array, shape (3,)
        Noise-free end of the motion.
    T_hold : float
        Minimum hold at the goal (s).
    noise : array, shape (3, 3, 3)
        Frequencies, phases and amplitudes of the smooth tremor (3 sinusoids x 3 axes).
    """

    path: np.ndarray
    arc: np.ndarray
    knots: np.ndarray
    durations: np.ndarray
    pauses: np.ndarray
    skews: np.ndarray
    goal: np.ndarray
    T_hold: float
    noise: np.ndarray

    @property
    def T_move(self) -> float:
        """Duration of the motion, stops included (s)."""
        return float(self.durations.sum() + self.pauses.sum())

    def position(self, t: np.ndarray) -> np.ndarray:
        """Wrist positions (T, 3) at times t (T,), with the tremor, without tracker noise."""
        t = np.asarray(t, float)
        starts = np.concatenate([[0.0], np.cumsum(self.durations + self.pauses)[:-1]])
        sa = np.zeros_like(t)
        for t0, d, sk, a, b in zip(starts, self.durations, self.skews, self.knots[:-1], self.knots[1:]):
            sa += (b - a) * _skewed_profile((t - t0) / d, sk)
        y = np.stack([np.interp(sa, self.arc, self.path[:, k]) for k in range(3)], axis=1)
        f, ph, a = self.noise
        n = np.einsum("ka,tka->ta", a, np.sin(2 * np.pi * f[None] * t[:, None, None] + ph[None]))
        fade = 0.5 * (1 - np.cos(np.pi * np.clip(t / 0.4, 0, 1)))  # the start is the rest position
        return y + n * fade[:, None]


def _switch(habit: str, options: tuple, p: float, sloppy: bool, rng: np.random.Generator) -> str:
    """The habit, or for a sloppy subject with probability p one of the other options (two draws always)."""
    flip, pick = rng.random(), rng.random()
    if sloppy and flip < p:
        others = [o for o in options if o != habit]
        return others[int(pick * len(others))]
    return habit


def plan_styled_reach(subject: Subject, task: str, rng: np.random.Generator) -> StyledPlan:
    """Plan one wrist motion of a styled subject doing ``task`` (see the module docstring).

    Parameters
    ----------
    subject : Subject
        With ``style`` set (:func:`make_styled_subject`).
    task : str
        One of :data:`TASKS`.
    rng : Generator
        The demonstration's random stream.
    """
    st: SubjectStyle = subject.style
    cfg = _scene()
    b, side, sloppy = subject.workspace_scale, st.side, subject.sloppy
    lo, hi = subject.calibration_box()
    lo_in, hi_in = lo + _MARGIN, hi - _MARGIN
    lo_in[2] = max(lo[2] + 0.03, TABLE_TOP_Z + 0.045)

    def inside(p):
        return np.clip(p, lo_in, hi_in)

    def body(fwd, out, up):  # a personal offset (nominal body) in the world
        return b * np.array([fwd, side * out, up])

    def within_reach(p):
        d = p - subject.shoulder
        r = st.stretch * subject.reach
        return subject.shoulder + r * _unit(d) if np.linalg.norm(d) > r else p

    def jitter(scale=1.0):
        return rng.normal(0, subject.jitter * scale, 3)

    elbow = _switch(st.elbow, ("up", "down"), 0.25, sloppy, rng)
    p0 = subject.rest + rng.normal(0, [0.01, 0.01, 0.003]) * (1.8 if sloppy else 1.0)
    lift = p0 + body(st.lift[0], 0.0, st.lift[1] * (1.0 if elbow == "up" else 0.6)) * (1 + rng.normal(0, 0.04))
    target = np.asarray(cfg.tasks[task].target, float) if task != "standup" else None
    angle = rng.normal(0, 0.25)
    curv = subject.curvature * (1 + rng.normal(0, 0.25))

    def reach(a, goal):
        """Via points from a to goal: bulging up (elbow up) or outward (elbow down)."""
        chord = goal - a
        L = float(np.linalg.norm(chord))
        up = np.array([0.0, 0.0, 1.0])
        n_up = _unit(up - (up @ chord) / max(L * L, 1e-12) * chord)
        n_out = _unit(np.cross(chord, n_up))
        if n_out @ np.array([-0.3, side, 0.0]) < 0:
            n_out = -n_out
        th = angle + (0.0 if elbow == "up" else 1.1)
        mid = 0.5 * (a + goal) + curv * L * (np.cos(th) * n_up + np.sin(th) * n_out)
        return [mid, goal]

    strokes, stops, extra = [], [], []
    if task == "board":
        knife = target + 0.5 * subject.task_offsets[task] + jitter(0.7)
        if elbow == "up":
            strokes.append([p0, lift, knife + np.array([0.0, 0.0, 0.09 * b]), knife])
        else:
            strokes.append([p0, 0.5 * (p0 + knife) + body(0.0, 0.04, 0.025), knife])
        f, m, h = st.knife_hold
        hold = p0 + body(f, -m, 0.0) + jitter(0.8)
        hold[2] = TABLE_TOP_Z + h + rng.normal(0, 0.8 * subject.jitter)
        strokes.append([knife, knife + np.array([0.0, 0.0, 0.05]) + 0.3 * (hold - knife), hold])
        stops.append(float(rng.uniform(0.08, 0.25)))  # the grasp
    elif task in ("tomato", "bowl"):
        goal = within_reach(target + subject.task_offsets[task] + jitter(2.0))  # a gesture: the robot passes it
        strokes.append([p0, lift, *reach(lift, goal)])
    elif task == "dressing":
        goal = within_reach(target + subject.task_offsets[task] + jitter(1.2))
        bowl = np.asarray(cfg.tasks["bowl"].target, float)
        how = _switch(st.dressing_path, ("over", "around"), 0.25, sloppy, rng)
        if how == "over":
            via = bowl + np.array([0.0, 0.0, st.over_height]) + jitter()
        else:
            chord = goal - lift
            n = _unit(np.array([-chord[1], chord[0], 0.0]))
            n = n if n[0] < 0 else -n  # pass the bowl on the person's side
            via = bowl + 0.17 * n + np.array([0.0, 0.0, 0.05]) + jitter()
        strokes.append([p0, lift, via, goal])
    else:  # standup
        how = _switch(st.standup, tuple(STANDUP_STYLES), 0.2, sloppy, rng)
        (vf, vo, vu), (ef, eo, eu) = st.standup_paths[how]
        via = p0 + body(vf, vo, vu) + jitter()
        end = p0 + body(ef, eo, eu) + subject.task_offsets[task] + jitter(1.2)
        if how == "push":  # press on the table, creep while the body rises over the hand, then lift the hand
            creep = via + body(-0.02, 0.0, 0.03)
            strokes += [[p0, via], [via, creep], [creep, 0.5 * (creep + end) + body(-0.03, 0.0, 0.02), end]]
            stops += [0.0, 0.0]
            extra.append((1, float(rng.uniform(0.35, 0.55))))  # the creep lasts as long as the rise takes
        else:
            strokes.append([p0, via, end])

    pieces = [_through(s, inside) for s in strokes]
    path = np.concatenate([pieces[0]] + [p[1:] for p in pieces[1:]])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    ends = np.cumsum([len(p) - (0 if i == 0 else 1) for i, p in enumerate(pieces)]) - 1
    knots = np.concatenate([[0.0], arc[ends]])
    pauses = list(stops)
    # a hesitation: the longest stroke stops somewhere in its middle
    hesitate, where, pause = rng.random(), rng.uniform(0.35, 0.7), rng.uniform(0.08, 0.25)
    if hesitate < st.hesitation + (0.2 if sloppy else 0.0):
        i = int(np.argmax(np.diff(knots)))
        knots = np.insert(knots, i + 1, knots[i] + where * (knots[i + 1] - knots[i]))
        pauses.insert(i, float(pause))
        extra = [(j + (1 if j > i else 0), d) for j, d in extra]
    pauses.append(0.0)
    lengths = np.diff(knots)
    jit = 0.15 if sloppy else 0.07
    T = subject.duration * _TASK_DURATION[task] * float(np.exp(rng.normal(0, jit)))
    durations = T * np.sqrt(lengths) / np.sqrt(lengths).sum()
    for j, d in extra:
        durations[j] = d
    skews = subject.profile_skew + rng.normal(0, 0.2, lengths.size)
    noise = np.stack([rng.uniform(0.4, 1.6, (3, 3)), rng.uniform(0, 2 * np.pi, (3, 3)),
                      rng.normal(0, subject.noise / np.sqrt(3), (3, 3))])
    return StyledPlan(path=path, arc=arc, knots=knots, durations=durations, pauses=np.array(pauses),
                      skews=skews, goal=path[-1].copy(), T_hold=float(rng.uniform(0.5, 0.8)), noise=noise)


# --------------------------------------------------------------------------- tracker
def track(subject: Subject, t: np.ndarray, wrist: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """What the tracker reports of the true wrist positions ``wrist`` (T, 3) at times ``t`` (T,).

    Motion capture adds 0.5 mm white noise at 150 Hz. A camera tracker sees the wrist in
    frames at :data:`CAMERA_HZ` (each value repeated until the next frame) with
    ``camera_noise`` white noise and a slow error (3 sinusoids of 0.2-1 Hz per axis,
    ``camera_drift`` in all), smooths it (exponential, ``camera_smoothing``: it lags),
    and loses the wrist now and then: during a dropout it repeats its last value (as a
    real-time tracker does), then its filter catches up with the wrist.

    Parameters
    ----------
    subject : Subject
        A styled subject.
    t : array, shape (T,)
    wrist : array, shape (T, 3)
    rng : Generator

    Returns
    -------
    array, shape (T, 3)
    """
    st: SubjectStyle = subject.style
    if st.tracker != "camera":
        return wrist + rng.normal(0, 0.0005, wrist.shape)
    f = rng.uniform(0.2, 1.0, (3, 3))
    ph = rng.uniform(0, 2 * np.pi, (3, 3))
    slow = np.einsum("ka,tka->ta", np.full((3, 3), st.camera_drift / 3.0),
                     np.sin(2 * np.pi * f[None] * t[:, None, None] + ph[None]))
    frame = np.floor(t * CAMERA_HZ + 1e-9).astype(int)  # a new camera frame every 5th sample at 150 Hz
    first = np.concatenate([[0], np.flatnonzero(np.diff(frame)) + 1])
    raw = wrist[first] + slow[first] + rng.normal(0, st.camera_noise, (first.size, 3))
    lost = np.zeros(first.size, bool)  # frames in which the tracker loses the wrist
    T = float(t[-1])
    n = int(rng.poisson(st.dropout_rate * T))
    for t0, d in zip(rng.uniform(0.2, max(T - 0.3, 0.2), n), rng.uniform(0.05, 0.25, n)):
        lost[(t[first] >= t0) & (t[first] < t0 + d)] = True
    a = float(np.exp(-1.0 / (CAMERA_HZ * st.camera_smoothing)))  # the tracker's own low-pass filter (lags)
    seen = raw.copy()
    for k in range(1, first.size):
        seen[k] = seen[k - 1] if lost[k] else a * seen[k - 1] + (1 - a) * raw[k]
    y = seen[np.searchsorted(first, np.arange(len(t)), side="right") - 1]
    return y


def track_calibration(subject: Subject, motions: list[np.ndarray], rng: np.random.Generator) -> list[np.ndarray]:
    """The calibration half circles as the subject's tracker reports them (camera: noisier; no dropouts)."""
    st: SubjectStyle = subject.style
    if st is None or st.tracker != "camera":
        return motions
    return [m + rng.normal(0, st.camera_noise, m.shape) for m in motions]
