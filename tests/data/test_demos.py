"""Demonstration files (npz, CSV, directories, calibration): round trips and errors that name the file."""
import os
import stat

import numpy as np
import pytest

from drake_skills.data.demonstration import Demonstration
from drake_skills.data.demos import (load_calibration, load_csv, load_demo, load_dir, load_npz, save_calibration,
                                     save_csv, save_npz)


def _demo(T=40, robot=True, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(T) / 150.0
    human = np.cumsum(rng.normal(0, 0.01, (T, 3)), axis=0)
    q = np.cumsum(rng.normal(0, 0.01, (T, 7)), axis=0) if robot else None
    return Demonstration(t=t, human=human, robot=q, task="bowl", subject="subject1")


@pytest.mark.parametrize("save, load, suffix", [(save_npz, load_npz, ".npz"), (save_csv, load_csv, ".csv")])
@pytest.mark.parametrize("robot", [True, False])
def test_round_trip_is_exact(tmp_path, save, load, suffix, robot):
    demo = _demo(robot=robot)
    back = load(save(demo, tmp_path / f"d{suffix}"))
    np.testing.assert_array_equal(back.t, demo.t)
    np.testing.assert_array_equal(back.human, demo.human)
    if robot:
        np.testing.assert_array_equal(back.robot, demo.robot)
    else:
        assert back.robot is None
    assert (back.task, back.subject) == ("bowl", "subject1")


def test_csv_header_is_the_documented_one(tmp_path):
    path = save_csv(_demo(), tmp_path / "d.csv")
    assert path.read_text().splitlines()[0] == "t,hx,hy,hz,q1,q2,q3,q4,q5,q6,q7,task,subject"


def test_load_dir_finds_both_formats_and_skips_calibration(tmp_path):
    save_npz(_demo(seed=1), tmp_path / "a" / "one.npz")
    save_csv(_demo(seed=2), tmp_path / "b" / "two.csv")
    save_calibration(tmp_path / "a" / "calibration.npz", [np.random.default_rng(0).normal(size=(10, 3))] * 2)
    demos = load_dir(tmp_path)
    assert [d.name.split("/")[-1] for d in demos] == ["one.npz", "two.csv"]
    cal = load_calibration(tmp_path / "a" / "calibration.npz")
    assert list(cal) == ["xy", "zy"] and cal["xy"].shape == (10, 3)


def _write_npz(path, **arrays):
    np.savez(path, **arrays)
    return path


def _bad_npz_files(tmp_path):
    d = _demo()
    nan = d.human.copy()
    nan[12:15, 1] = np.nan
    back = d.t.copy()
    back[20] = back[19] - 0.01
    return {
        "NaN": _write_npz(tmp_path / "nan.npz", t=d.t, human=nan, robot=d.robot),
        "non-monotonic": _write_npz(tmp_path / "time.npz", t=back, human=d.human, robot=d.robot),
        "too short": _write_npz(tmp_path / "short.npz", t=d.t[:3], human=d.human[:3], robot=d.robot[:3]),
        "rows": _write_npz(tmp_path / "rows.npz", t=d.t, human=d.human[:-1], robot=d.robot),
        "missing": _write_npz(tmp_path / "foreign.npz", x=np.zeros(3)),
        "flat human": _write_npz(tmp_path / "flat.npz", t=d.t, human=d.human[:, 0], robot=d.robot),
        "no robot columns": _write_npz(tmp_path / "nocols.npz", t=d.t, human=d.human, robot=d.robot[:, :0]),
        "text": _write_npz(tmp_path / "text.npz", t=d.t, human=np.full((len(d.t), 3), "x")),
        "not an npz": tmp_path / "garbage.npz",
        "pickle": tmp_path / "objects.npz",
    }


def test_every_malformed_npz_names_the_file_and_the_problem(tmp_path):
    files = _bad_npz_files(tmp_path)
    files["not an npz"].write_bytes(b"this is not a zip archive")
    np.savez(files["pickle"], t=np.array([object()] * 5, dtype=object), human=np.zeros((5, 3)))
    expected = {"NaN": "NaN", "non-monotonic": "increas", "too short": "at least", "rows": "rows",
                "missing": "missing", "flat human": "2 dimension", "no robot columns": "no columns",
                "text": "expected numbers", "not an npz": "not an npz", "pickle": "never loaded"}
    for problem, path in files.items():
        with pytest.raises(ValueError) as exc:
            load_demo(path)
        msg = str(exc.value)
        assert path.name in msg, (problem, msg)
        assert expected[problem].lower() in msg.lower(), (problem, msg)


def test_every_malformed_csv_names_the_file_and_the_problem(tmp_path):
    good = save_csv(_demo(), tmp_path / "good.csv").read_text().splitlines()
    header, rows = good[0], good[1:]
    cases = {
        "empty.csv": ("", "empty"),
        "nohead.csv": ("\n".join(["hx,hy,hz"] + rows), "first column must be 't'"),
        "cols.csv": ("\n".join([header.replace("q7", "q9")] + rows), "robot columns"),
        "extra.csv": ("\n".join([header + ",speed"] + [r + ",1" for r in rows]), "unknown column"),
        "short_row.csv": ("\n".join([header] + rows[:5] + [rows[5].rsplit(",", 3)[0]] + rows[6:]), "line 7"),
        "word.csv": ("\n".join([header] + [rows[0].replace(rows[0].split(",")[1], "abc", 1)] + rows[1:]),
                     "not a number"),
        "nan.csv": ("\n".join([header] + [rows[0].replace(rows[0].split(",")[2], "nan", 1)] + rows[1:]), "NaN"),
        "time.csv": ("\n".join([header] + rows[1:2] + rows[0:1] + rows[2:]), "increas"),
        "short.csv": ("\n".join([header] + rows[:3]), "at least 5"),
        "nohuman.csv": ("\n".join(["t,q1"] + ["%d,0" % i for i in range(10)]), "no human columns"),
    }
    for name, (text, problem) in cases.items():
        path = tmp_path / name
        path.write_text(text)
        with pytest.raises(ValueError) as exc:
            load_demo(path)
        msg = str(exc.value)
        assert name in msg and problem.lower() in msg.lower(), (name, msg)


def test_unknown_suffix_and_missing_directory(tmp_path):
    (tmp_path / "x.txt").write_text("1")
    with pytest.raises(ValueError, match="x.txt.*unknown file type"):
        load_demo(tmp_path / "x.txt")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_dir(tmp_path / "nope")


def test_load_dir_reports_the_first_bad_file(tmp_path):
    save_npz(_demo(), tmp_path / "a.npz")
    (tmp_path / "b.csv").write_text("t,hx\n0,nan\n")
    with pytest.raises(ValueError, match="b.csv"):
        load_dir(tmp_path)


def test_written_files_get_the_usual_permissions_not_owner_only(tmp_path):
    """Atomic writes go through a temporary file; the result must have the mode open() gives."""
    mask = os.umask(0o022)
    try:
        for path in (save_npz(_demo(), tmp_path / "d.npz"), save_csv(_demo(), tmp_path / "d.csv"),
                     save_calibration(tmp_path / "calibration.npz", [np.zeros((5, 3)), np.ones((5, 3))])):
            assert stat.S_IMODE(path.stat().st_mode) == 0o644, path
    finally:
        os.umask(mask)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary files left


def test_a_demonstration_owns_read_only_copies_and_leaves_the_callers_arrays_alone():
    """The caller's arrays stay writable; writing to them (or to the array they view) changes nothing."""
    base = np.zeros((20, 10))
    base[:, 0] = np.linspace(0.0, 1.9, 20)
    base[:, 1:4] = np.linspace(0.0, 0.3, 20)[:, None]
    t, human, robot = base[:, 0], base[:, 1:4], base[:, 3:]
    d = Demonstration(t, human, robot)
    assert t.flags.writeable and human.flags.writeable and base.flags.writeable
    before = (d.t.copy(), d.human.copy(), d.robot.copy())
    base[:] = 7.0
    for got, want in zip((d.t, d.human, d.robot), before):
        np.testing.assert_array_equal(got, want)
        assert not got.flags.writeable
        with pytest.raises(ValueError):
            got[0] = 1.0


@pytest.mark.parametrize("what", ["t", "human", "robot"])
def test_finite_values_whose_span_overflows_are_refused_with_the_units_hint(what):
    """t from -1e308 to 1e308 has an infinite duration: refused here, not deep in the basis fit."""
    t = np.linspace(0.0, 1.0, 10)
    human = np.zeros((10, 3))
    robot = np.zeros((10, 7))
    arrays = dict(t=t, human=human, robot=robot)
    a = arrays[what].copy()
    a[0], a[-1] = -1e308, 1e308     # first and last sample (every column of a row)
    arrays[what] = a
    with pytest.raises(ValueError, match=rf"demo 'big': {what} spans more than the largest float.*units"):
        Demonstration(arrays["t"], arrays["human"], arrays["robot"], name="big")


def test_complex_samples_are_refused_not_cast():
    """numpy would drop the imaginary part with a warning; a demonstration refuses them."""
    with pytest.raises(ValueError, match="^demo 'c': human is complex; give real numbers$"):
        Demonstration(np.linspace(0, 1, 10), np.zeros((10, 3)) + 1j, name="c")


def test_csv_labels_are_stripped_and_an_empty_label_is_none(tmp_path):
    path = save_csv(_demo(), tmp_path / "d.csv")
    lines = path.read_text().splitlines()
    body = [",".join(r.split(",")[:-2] + [" bowl ", ""]) for r in lines[1:]]
    (tmp_path / "e.csv").write_text("\n".join([lines[0]] + body) + "\n")
    back = load_csv(tmp_path / "e.csv")
    assert (back.task, back.subject) == ("bowl", None)
