"""Styled salad subjects: habits drawn from their stated distributions, and paths that show them."""
import dataclasses
from collections import Counter

import numpy as np
import pytest

from drake_skills.library.incremental import SkillLibrary
from drake_skills.scenario.salad import TASKS, generate_subject, make_subject
from drake_skills.scenario.salad_styles import (CAMERA_HZ, CAMERA_SUBJECTS, LEFT_HANDED_SUBJECTS, STANDUP_STYLES,
                                                make_styled_subject, plan_styled_reach, track)
from drake_skills.scenario.salad_subject import SLOPPY_SUBJECTS, _rng, _scene
from drake_skills.sim.models import IIWA7_JOINT_LIMITS


def _with(subject, **style):
    """The subject with some habits replaced."""
    return dataclasses.replace(subject, style=dataclasses.replace(subject.style, **style))


def _plans(subject, task, n=6):
    return [plan_styled_reach(subject, task, _rng(0, subject.index, 1, TASKS.index(task), k)) for k in range(n)]


def test_the_ten_subjects_have_the_stated_rare_traits():
    for i in range(1, 11):
        s = make_styled_subject(i)
        assert s.style.hand == ("left" if i in LEFT_HANDED_SUBJECTS else "right"), i
        assert s.style.tracker == ("camera" if i in CAMERA_SUBJECTS else "mocap"), i
        assert s.sloppy == (i in SLOPPY_SUBJECTS), i


def test_habits_follow_their_stated_distributions():
    """390 further subjects: each frequency within 4 binomial standard deviations of its stated
    probability; seats N(0, 3 cm) clipped at 6 cm; the knife hold in its stated ranges."""
    styles = [make_styled_subject(i) for i in range(11, 401)]
    n = len(styles)

    def near(count, p):
        return abs(count / n - p) <= 4 * np.sqrt(p * (1 - p) / n)

    standup = Counter(s.style.standup for s in styles)
    for style, p in STANDUP_STYLES.items():
        assert near(standup[style], p), (style, standup)
    assert near(sum(s.style.elbow == "up" for s in styles), 0.5)
    assert near(sum(s.style.dressing_path == "over" for s in styles), 0.5)
    assert near(sum(s.style.hand == "left" for s in styles), 0.1)
    assert near(sum(s.style.tracker == "camera" for s in styles), 0.2)
    assert near(sum(s.sloppy for s in styles), 0.2)
    seat = np.array([s.style.seat for s in styles])
    assert np.abs(seat).max() <= 0.06 and (seat[:, 2] == 0).all()
    assert 0.024 < seat[:, :2].std() < 0.032  # N(0, 3 cm) clipped at 2 sigma: 2.6 cm
    hold = np.array([s.style.knife_hold for s in styles])
    assert (hold.min(axis=0) >= [0.10, 0.08, 0.05]).all() and (hold.max(axis=0) <= [0.16, 0.14, 0.22]).all()
    assert np.ptp(hold[:, 2]) > 0.15  # people hold the knife at different heights


def test_a_left_handed_subject_is_the_mirror_image_of_the_body():
    s = make_styled_subject(LEFT_HANDED_SUBJECTS[0])
    midline = _scene().person.seat[1] + s.style.seat[1]
    assert s.style.side == 1.0
    assert s.rest[1] > midline + 0.1 and s.shoulder[1] > midline + 0.1  # left of the body
    right = make_styled_subject(1)
    assert right.rest[1] < _scene().person.seat[1] + right.style.seat[1] - 0.1
    assert s.rest[1] - right.rest[1] > 0.25  # the tracked wrist starts a hand's breadth of shoulders away


def test_styles_change_the_path_by_the_stated_amounts():
    """Same subject, one habit swapped: the paths differ where the style says, by centimetres."""
    cfg = _scene()
    s = make_styled_subject(1)
    assert not s.sloppy
    # dressing: over the bowl the path is higher halfway along than around it
    bowl_z = cfg.tasks["bowl"].target[2]

    def half_height(subject):
        return np.mean([p.path[np.argmin(np.abs(p.arc - 0.5 * p.arc[-1])), 2] - bowl_z
                        for p in _plans(subject, "dressing")])

    assert half_height(_with(s, dressing_path="over")) - half_height(_with(s, dressing_path="around")) > 0.04
    # board: elbow up takes the knife from above (>= 8 cm over its handle), elbow down from the side
    knife_z = cfg.tasks["board"].target[2]

    def first_stroke_top(subject):
        return [p.path[:np.searchsorted(p.arc, p.knots[1]), 2].max() - knife_z for p in _plans(subject, "board")]

    assert min(first_stroke_top(_with(s, elbow="up"))) > 0.08
    assert max(first_stroke_top(_with(s, elbow="down"))) < 0.05
    # stand-up: turning swings the hand >= 20 cm outward; pushing keeps it on the table (within
    # 3 cm of its rest height) for more than 0.6 s; leaning takes it >= 10 cm forward first
    for style, check in (("turn", lambda out, low, fwd: out > 0.2), ("push", lambda out, low, fwd: low > 0.6),
                         ("lean", lambda out, low, fwd: fwd > 0.1 and out < 0.15)):
        for p in _plans(_with(s, standup=style), "standup"):
            t = np.arange(0.0, p.T_move, 1 / 150)
            y = p.position(t)
            out = float(((y[:, 1] - s.rest[1]) * s.style.side).max())
            low = float((y[:, 2] < s.rest[2] + 0.03).sum() / 150)
            fwd = float((y[:, 0] - s.rest[0]).max())
            assert check(out, low, fwd), (style, out, low, fwd)


def test_a_sloppy_subject_switches_styles_from_trial_to_trial():
    s = make_styled_subject(SLOPPY_SUBJECTS[0])
    assert s.sloppy
    knife_z = _scene().tasks["board"].target[2]
    tops = [p.path[:np.searchsorted(p.arc, p.knots[1]), 2].max() - knife_z for p in _plans(s, "board", n=30)]
    up = sum(t > 0.08 for t in tops)
    habit = 30 if s.style.elbow == "up" else 0
    assert 2 <= abs(habit - up) <= 15  # P = 0.25 of the other elbow: 7.5 expected in 30 trials


def test_camera_tracker_updates_at_its_frame_rate_with_noise_and_dropouts():
    s = make_styled_subject(CAMERA_SUBJECTS[0])
    st = s.style
    assert st.tracker == "camera" and 0.003 <= st.camera_noise <= 0.005 and 0.5 <= st.dropout_rate <= 1.5
    t = np.arange(0, 20.0, 1 / 150)
    wrist = np.stack([0.5 * np.sin(t), 0.3 * np.cos(t), 0.9 + 0.05 * t / 20], axis=1)  # moving all the time
    y = track(s, t, wrist, np.random.default_rng(0))
    changes = np.flatnonzero(np.any(np.diff(y, axis=0) != 0, axis=1)) + 1
    frames = np.floor(t * CAMERA_HZ + 1e-9).astype(int)
    assert set(changes) <= set(np.flatnonzero(np.diff(frames)) + 1)  # new values only with a new frame
    runs = np.diff(np.concatenate([[0], changes, [len(t)]]))
    assert runs.max() >= 0.05 * 150 + 5 and (runs > 6).sum() >= 5  # dropouts: a frame repeated
    err = np.linalg.norm(y - wrist, axis=1)
    assert 0.002 < np.median(err) < 0.05  # mm to cm: noise, slow error and the smoothing's lag
    mocap = track(make_styled_subject(1), t, wrist, np.random.default_rng(0)) - wrist
    assert 0.0004 < mocap.std() < 0.0006


@pytest.mark.parametrize("index", [3, CAMERA_SUBJECTS[0], LEFT_HANDED_SUBJECTS[0]])
def test_styled_demos_stay_in_the_calibration_and_two_degrees_inside_the_joint_limits(index):
    data = generate_subject(index, n_demos=2, seed=1)
    ws = data.workspace(z_factor=None)
    lower, upper = IIWA7_JOINT_LIMITS
    margin = np.deg2rad(2.0) - 1e-6
    for d in data.demos:
        y = ws.normalize(d.human, subtract_start=False)
        assert y.min() >= 0.0 and y.max() <= 10.0, (d.name, y.min(), y.max())
        assert (d.robot >= lower + margin).all() and (d.robot <= upper - margin).all(), d.name


def test_handover_ik_keeps_two_degrees_where_a_styled_handover_presses_a_limit():
    """Subject 2 holds the knife low and close to the robot: joint 4 of the board handover ends on
    the IK's 2-degree margin (without the margin it would go to the limit)."""
    from drake_skills.scenario.salad import make_demonstration

    lower, upper = IIWA7_JOINT_LIMITS
    d = make_demonstration(make_subject(2), "board", 1)
    gap = np.minimum(d.robot - lower, upper - d.robot).min(axis=0)
    assert gap.min() >= np.deg2rad(2.0) - 1e-6
    assert gap[3] < np.deg2rad(2.05)  # the case is still the one it is named for


def test_tasks_are_apart_in_geometry():
    """For tidy subjects the closest two task means (the library's gating weights) lie at least
    three times the within-task spread apart: the tasks differ in where the hand goes."""
    lib = SkillLibrary()
    n = lib.config.n_basis_human * 3
    for index in (1, 2):
        data = generate_subject(index, n_demos=4)
        ws = data.workspace()
        w = {t: np.array([lib.encode(d, ws)[:n] for d in data.by_task(t)]) for t in TASKS}
        within = np.sqrt(np.mean([np.mean((x - x.mean(axis=0)) ** 2) * 4 / 3 for x in w.values()]))
        closest = min(np.sqrt(np.mean((w[a].mean(axis=0) - w[b].mean(axis=0)) ** 2))
                      for a in TASKS for b in TASKS if a < b)
        assert closest > 3 * within, (index, closest, within)


def test_subject_models_share_the_body_but_not_the_habits():
    classic, styled = make_subject(2, model="classic"), make_subject(2)
    assert classic.arm_length == styled.arm_length and classic.reach == styled.reach
    assert classic.style is None and styled.style is not None
