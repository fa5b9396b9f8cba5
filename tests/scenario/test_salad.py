"""The simulated salad scenario: valid, smooth, reproducible, personal, and hard but learnable."""
import json

import numpy as np
import pytest

from drake_skills.data.demos import save_npz
from drake_skills.scenario.salad import RATE_HZ, SLOPPY_SUBJECTS, TABLE_TOP_Z, TASKS, generate_subject, make_subject
from drake_skills.sim.models import IIWA7_JOINT_LIMITS, IIWA7_VELOCITY_LIMITS


@pytest.fixture(scope="module")
def subjects():
    """Subjects 1-3 (3 is sloppy), 3 demonstrations per task."""
    return {i: generate_subject(i, n_demos=3, seed=0) for i in (1, 2, 3)}


def test_demonstrations_are_finite_continuous_and_within_joint_limits(subjects):
    lower, upper = IIWA7_JOINT_LIMITS
    for data in subjects.values():
        assert len(data.demos) == 3 * len(TASKS)
        for d in data.demos:
            assert d.robot.shape == (d.t.shape[0], 7) and d.human.shape == (d.t.shape[0], 3)
            assert np.isfinite(d.human).all() and np.isfinite(d.robot).all()
            np.testing.assert_allclose(np.diff(d.t), 1 / RATE_HZ, atol=1e-12)
            assert (d.robot >= lower).all() and (d.robot <= upper).all(), d.name
            # continuous: joint speed below the datasheet limit (no jumps between IK branches)
            qd = np.abs(np.diff(d.robot, axis=0)) * RATE_HZ
            assert (qd <= IIWA7_VELOCITY_LIMITS).all(), (d.name, qd.max(axis=0))
            # wrist: no jump above 2 cm per sample (<= 3 m/s), above the table top
            assert np.linalg.norm(np.diff(d.human, axis=0), axis=1).max() < 0.02, d.name
            assert d.human[:, 2].min() > TABLE_TOP_Z, d.name


def test_same_seed_gives_the_same_bytes(subjects, tmp_path):
    again = generate_subject(2, n_demos=3, seed=0)
    for a, b in zip(subjects[2].demos, again.demos):
        pa, pb = save_npz(a, tmp_path / "a.npz"), save_npz(b, tmp_path / "b.npz")
        assert pa.read_bytes() == pb.read_bytes(), a.name
    other = generate_subject(2, n_demos=3, seed=1)
    assert not np.array_equal(other.demos[0].human, subjects[2].demos[0].human)


def test_subjects_differ_in_body_and_motion(subjects):
    s1, s2 = make_subject(1), make_subject(2)
    assert s1.arm_length != s2.arm_length and not np.allclose(s1.rest, s2.rest)
    for task in TASKS:
        h1, h2 = subjects[1].by_task(task)[0].human, subjects[2].by_task(task)[0].human
        assert np.linalg.norm(h1[-1] - h2[-1]) > 0.01, task  # different goals (> 1 cm)


def test_calibration_normalizes_every_subjects_wrist_into_0_10(subjects):
    """Inside [0, 10] with the calibration's bounding box; with the paper's 90 % z range
    (shrunk about its centre) the wrist may poke out by at most 5 % of the range in z."""
    for data in subjects.values():
        full, paper = data.workspace(z_factor=None), data.workspace()
        for d in data.demos:
            y = full.normalize(d.human, subtract_start=False)
            assert y.min() >= 0.0 and y.max() <= 10.0, (d.name, y.min(), y.max())
            z = paper.normalize(d.human, subtract_start=False)[:, 2]
            assert z.min() >= -0.5 and z.max() <= 10.5, (d.name, z.min(), z.max())


def test_tasks_share_their_first_segment_but_end_apart(subjects):
    """Early recognition is not trivial: 6 cm along the path (from its own start, the way Eq. 14
    sees it) every task has moved the same way, within 2 cm."""
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


def test_sloppy_subjects_vary_more(subjects):
    assert 3 in SLOPPY_SUBJECTS and 1 not in SLOPPY_SUBJECTS

    def spread(data):
        return np.mean([np.std([d.human[-1] for d in data.by_task(t)], axis=0).mean() for t in TASKS])

    assert spread(subjects[3]) > 1.5 * spread(subjects[1])


def test_generator_rejects_bad_arguments():
    with pytest.raises(ValueError, match="1-based"):
        generate_subject(0)
    with pytest.raises(ValueError, match="unknown task"):
        generate_subject(1, n_demos=1, tasks=("soup",))
    with pytest.raises(ValueError, match="non-negative"):
        make_subject(1, seed=-1)


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
    pngs = list((tmp_path / "plots").glob("*.png"))
    assert pngs and all(p.stat().st_size > 20_000 for p in pngs)


def test_handover_ik_stays_off_the_joint_limits():
    """Regression: seed 1, subject 7, bowl 11 once put joint 1 on its limit and aborted generation."""
    from drake_skills.scenario.salad import make_demonstration

    lower, upper = IIWA7_JOINT_LIMITS
    d = make_demonstration(make_subject(7, seed=1), "bowl", 11, seed=1)
    margin = np.deg2rad(2.0) - 1e-6
    assert (d.robot >= lower + margin).all() and (d.robot <= upper - margin).all()
