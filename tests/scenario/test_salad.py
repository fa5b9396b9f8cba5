"""The simulated salad scenario: valid, smooth, reproducible, personal, and hard but learnable.

The checks every subject model must pass run on both (``subjects`` classic, ``styled``);
the style-specific behaviour is in ``test_salad_styles.py``.
"""
import json

import numpy as np
import pytest

from drake_skills.data.demos import save_npz
from drake_skills.scenario.salad import (RATE_HZ, SLOPPY_SUBJECTS, SUBJECT_MODELS, TABLE_TOP_Z, TASKS,
                                         generate_subject, make_subject)
from drake_skills.scenario.salad_styles import CAMERA_SUBJECTS, LEFT_HANDED_SUBJECTS
from drake_skills.sim.models import IIWA7_JOINT_LIMITS, IIWA7_VELOCITY_LIMITS


@pytest.fixture(scope="module")
def subjects():
    """Classic subjects 1-3 (3 is sloppy), 3 demonstrations per task."""
    return {i: generate_subject(i, n_demos=3, seed=0, model="classic") for i in (1, 2, 3)}


@pytest.fixture(scope="module")
def styled():
    """Styled subjects 1-3 (3 is sloppy), 4 (camera tracker) and 6 (left-handed), 3 demonstrations per task."""
    assert 4 in CAMERA_SUBJECTS and 6 in LEFT_HANDED_SUBJECTS and 3 in SLOPPY_SUBJECTS
    return {i: generate_subject(i, n_demos=3, seed=0, model="styled") for i in (1, 2, 3, 4, 6)}


@pytest.fixture(params=SUBJECT_MODELS)
def either(request, subjects, styled):
    return {"classic": subjects, "styled": styled}[request.param]


def test_the_styled_model_is_the_default():
    assert SUBJECT_MODELS[0] == "styled" and make_subject(1).style is not None
    assert make_subject(1, model="classic").style is None


def test_demonstrations_are_finite_continuous_and_within_joint_limits(either):
    lower, upper = IIWA7_JOINT_LIMITS
    for data in either.values():
        camera = data.subject.style is not None and data.subject.style.tracker == "camera"
        assert len(data.demos) == 3 * len(TASKS)
        for d in data.demos:
            assert d.robot.shape == (d.t.shape[0], 7) and d.human.shape == (d.t.shape[0], 3)
            assert np.isfinite(d.human).all() and np.isfinite(d.robot).all()
            np.testing.assert_allclose(np.diff(d.t), 1 / RATE_HZ, atol=1e-12)
            assert (d.robot >= lower).all() and (d.robot <= upper).all(), d.name
            # continuous: joint speed below the datasheet limit (no jumps between IK branches)
            qd = np.abs(np.diff(d.robot, axis=0)) * RATE_HZ
            assert (qd <= IIWA7_VELOCITY_LIMITS).all(), (d.name, qd.max(axis=0))
            # wrist: no jump above 2 cm per sample (<= 3 m/s; a camera catches up after a dropout), above
            # the table top
            assert camera or np.linalg.norm(np.diff(d.human, axis=0), axis=1).max() < 0.02, d.name
            assert d.human[:, 2].min() > TABLE_TOP_Z, d.name


@pytest.mark.parametrize("model", SUBJECT_MODELS)
def test_same_seed_gives_the_same_bytes(subjects, styled, model, tmp_path):
    first = {"classic": subjects, "styled": styled}[model][2]
    again = generate_subject(2, n_demos=3, seed=0, model=model)
    for a, b in zip(first.demos, again.demos):
        pa, pb = save_npz(a, tmp_path / "a.npz"), save_npz(b, tmp_path / "b.npz")
        assert pa.read_bytes() == pb.read_bytes(), a.name
    for m, n in zip(first.calibration, again.calibration):
        np.testing.assert_array_equal(m, n)
    other = generate_subject(2, n_demos=1, seed=1, model=model)
    assert not np.array_equal(other.demos[0].human, first.demos[0].human)


def test_subjects_differ_in_body_and_motion(subjects):
    s1, s2 = make_subject(1, model="classic"), make_subject(2, model="classic")
    assert s1.arm_length != s2.arm_length and not np.allclose(s1.rest, s2.rest)
    for task in TASKS:
        h1, h2 = subjects[1].by_task(task)[0].human, subjects[2].by_task(task)[0].human
        assert np.linalg.norm(h1[-1] - h2[-1]) > 0.01, task  # different goals (> 1 cm)


def test_calibration_normalizes_every_subjects_wrist_into_0_10(either):
    """Inside [0, 10] with the calibration's bounding box; with the paper's 90 % z range
    (shrunk about its centre) the wrist may poke out by at most 5 % of the range in z."""
    for data in either.values():
        full, paper = data.workspace(z_factor=None), data.workspace()
        for d in data.demos:
            y = full.normalize(d.human, subtract_start=False)
            assert y.min() >= 0.0 and y.max() <= 10.0, (d.name, y.min(), y.max())
            z = paper.normalize(d.human, subtract_start=False)[:, 2]
            assert z.min() >= -0.5 and z.max() <= 10.5, (d.name, z.min(), z.max())


def test_tasks_share_their_first_segment_but_end_apart(subjects):
    """Classic subjects: early recognition is not trivial: 6 cm along the path (from its own start,
    the way Eq. 14 sees it) every task has moved the same way, within 2 cm."""
    data = subjects[1]
    first = np.array([d.human[0] for d in data.demos])
    early, end = [], []
    for task in TASKS:
        d = data.by_task(task)[0]
        step = np.linalg.norm(np.diff(d.human, axis=0), axis=1)
        s = np.concatenate([[0], np.cumsum(step)])
        early.append(d.human[np.searchsorted(s, 0.06)] - d.human[0])
        end.append(d.human[-1])
    early, end = np.array(early), np.array(end)
    pair = lambda p: min(np.linalg.norm(p[i] - p[j]) for i in range(5) for j in range(i + 1, 5))
    assert np.ptp(first, axis=0).max() < 0.06
    assert max(np.linalg.norm(early[i] - early[j]) for i in range(5) for j in range(i + 1, 5)) < 0.02
    assert pair(end) > 0.2  # every pair of task goals more than 20 cm apart


def test_sloppy_subjects_vary_more(either):
    """The trial-to-trial spread of a sloppy subject's paths, as the library encodes them (its own
    workspace, start subtracted, arc length), is more than 1.5 times a tidy subject's."""
    from drake_skills.library.incremental import SkillLibrary

    assert 3 in SLOPPY_SUBJECTS and 1 not in SLOPPY_SUBJECTS
    lib = SkillLibrary()

    def spread(data):
        ws = data.workspace()
        w = [np.array([lib.encode(d, ws)[:lib.config.n_basis_human * 3] for d in data.by_task(t)]) for t in TASKS]
        return np.sqrt(np.mean([np.mean((x - x.mean(axis=0)) ** 2) for x in w]))

    assert spread(either[3]) > 1.5 * spread(either[1])


def test_generator_rejects_bad_arguments():
    with pytest.raises(ValueError, match="1-based"):
        generate_subject(0)
    with pytest.raises(ValueError, match="unknown task"):
        generate_subject(1, n_demos=1, tasks=("soup",))
    for model in SUBJECT_MODELS:
        with pytest.raises(ValueError, match="non-negative"):
            make_subject(1, seed=-1, model=model)
        with pytest.raises(ValueError, match="1-based"):
            make_subject(0, model=model)
    with pytest.raises(ValueError, match="subject model"):
        generate_subject(1, n_demos=1, model="stylish")


def test_generate_and_plot_commands_write_a_dataset_and_a_picture(tmp_path):
    from drake_skills.cli import main
    from drake_skills.data.demos import load_calibration, load_dir
    from drake_skills.promp.preprocessing import Workspace

    out = tmp_path / "salad"
    assert main(["generate", "salad", "--subjects", "2", "--demos", "2", "--out", str(out)]) == 0
    demos = load_dir(out)
    assert len(demos) == 2 * 2 * len(TASKS)
    manifest = json.loads((out / "manifest.json").read_text())
    assert len(manifest["files"]) == len(demos) and manifest["tasks"] == list(TASKS)
    assert manifest["subject_model"] == "styled"
    assert [s["style"]["hand"] for s in manifest["subjects"]] == ["right", "right"]
    assert manifest["subjects"][0]["style"]["standup"] == make_subject(1).style.standup
    for s in ("subject1", "subject2"):
        calibration = load_calibration(out / s / "calibration.npz")
        assert set(calibration) == {"xy", "zy"}
        # the calibration on disk is enough to normalize that subject's demonstrations into [0, 10]
        workspace = Workspace.from_calibration(list(calibration.values()))
        mine = [d for d in demos if d.subject == s]
        assert len(mine) == 2 * len(TASKS) and all(d.robot.shape[1] == 7 for d in mine)
        y = np.concatenate([workspace.normalize(d.human, subtract_start=False) for d in mine])
        assert y.min() >= 0.0 and y.max() <= 10.0, (s, y.min(), y.max())
    assert main(["plot-demos", str(out), "--out", str(tmp_path / "plots")]) == 0
    pngs = sorted(p.name for p in (tmp_path / "plots").glob("*.png"))
    assert pngs == ["demos.png", "tasks.png"]  # one subject, and every task across the subjects
    assert all((tmp_path / "plots" / p).stat().st_size > 20_000 for p in pngs)
    classic = tmp_path / "classic"
    assert main(["generate", "salad", "--subjects", "1", "--demos", "1", "--subjects-model", "classic",
                 "--out", str(classic)]) == 0
    manifest = json.loads((classic / "manifest.json").read_text())
    assert manifest["subject_model"] == "classic" and manifest["subjects"][0]["style"] is None
    np.testing.assert_array_equal(load_dir(classic)[0].human,
                                  generate_subject(1, n_demos=1, tasks=("board",), model="classic").demos[0].human)


def test_handover_ik_stays_off_the_joint_limits():
    """Regression: seed 1, subject 7, bowl 11 once put joint 1 on its limit and aborted generation."""
    from drake_skills.scenario.salad import make_demonstration

    lower, upper = IIWA7_JOINT_LIMITS
    d = make_demonstration(make_subject(7, seed=1, model="classic"), "bowl", 11, seed=1)
    margin = np.deg2rad(2.0) - 1e-6
    assert (d.robot >= lower + margin).all() and (d.robot <= upper - margin).all()
