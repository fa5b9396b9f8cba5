"""Folders of demonstrations: each demonstration once, other files skipped with a note, one layout;
``Demonstration.save`` and workspace files."""
import json

import numpy as np
import pytest

from drake_skills import SkillLibrary
from drake_skills.data.demonstration import Demonstration
from drake_skills.data.demos import (check_layout, load_demo, load_dir, load_workspace, save_calibration, save_csv,
                                     save_npz, scan_dir)
from drake_skills.data.workspace import Workspace


def _demo(seed=0, T=40, d_h=3, d_r=7, task="bowl"):
    rng = np.random.default_rng(seed)
    t = np.arange(T) / 150.0
    human = np.cumsum(rng.normal(0, 0.01, (T, d_h)), axis=0)
    robot = np.cumsum(rng.normal(0, 0.01, (T, d_r)), axis=0) if d_r else None
    return Demonstration(t=t, human=human, robot=robot, task=task, subject="subject1")


@pytest.mark.parametrize("suffix", [".npz", ".csv", ".NPZ"])
def test_demonstration_save_writes_the_format_of_the_suffix_and_loads_back_exactly(tmp_path, suffix):
    demo = _demo()
    path = demo.save(tmp_path / f"d{suffix}")
    assert path == tmp_path / f"d{suffix}"
    if suffix == ".csv":
        assert path.read_text().startswith("t,hx,hy,hz,q1,")
    back = load_demo(path)
    np.testing.assert_array_equal(back.t, demo.t)
    np.testing.assert_array_equal(back.human, demo.human)
    np.testing.assert_array_equal(back.robot, demo.robot)
    assert (back.task, back.subject) == (demo.task, demo.subject)


def test_demonstration_save_rejects_another_suffix_naming_the_file(tmp_path):
    with pytest.raises(ValueError, match=r"d\.txt.*\.npz or \.csv"):
        _demo().save(tmp_path / "d.txt")
    assert not (tmp_path / "d.txt").exists()


def test_an_npz_and_a_csv_of_the_same_name_are_one_demonstration(tmp_path):
    for i in range(3):
        d = _demo(seed=i)
        save_npz(d, tmp_path / f"reach_{i}.npz")
        save_csv(d, tmp_path / f"reach_{i}.csv")
    scan = scan_dir(tmp_path)
    assert [d.name.rsplit("/", 1)[-1] for d in scan.demos] == ["reach_0.npz", "reach_1.npz", "reach_2.npz"]
    assert len(scan.duplicates) == 3 and all(a.suffix == ".npz" and b.suffix == ".csv" for a, b in scan.duplicates)
    assert any("read" in n and "reach_0.csv" in n for n in scan.notes())
    assert len(load_dir(tmp_path)) == 3


def test_a_csv_only_demonstration_is_kept_with_its_npz_twin_elsewhere(tmp_path):
    save_csv(_demo(seed=1), tmp_path / "a" / "x.csv")
    save_npz(_demo(seed=2), tmp_path / "b" / "x.npz")  # same stem, other folder: another demonstration
    assert len(scan_dir(tmp_path).demos) == 2


def test_an_npz_and_a_csv_of_the_same_name_with_different_data_are_an_error_naming_both(tmp_path):
    save_npz(_demo(seed=1), tmp_path / "reach.npz")
    save_csv(_demo(seed=2), tmp_path / "reach.csv")
    with pytest.raises(ValueError, match=r"reach\.(npz|csv)'? and 'reach\.(npz|csv)'.*different.*human"):
        scan_dir(tmp_path)
    save_csv(Demonstration(t=_demo(1).t, human=_demo(1).human, robot=_demo(1).robot, task="tomato",
                           subject="subject1"), tmp_path / "reach.csv")
    with pytest.raises(ValueError, match="task '(bowl|tomato)' vs '(bowl|tomato)'"):
        scan_dir(tmp_path)


def test_a_library_calibration_output_and_table_in_the_folder_are_skipped_with_a_note(tmp_path):
    demos = [_demo(seed=i) for i in range(3)]
    for i, d in enumerate(demos):
        save_npz(d, tmp_path / f"d{i}.npz")
    lib = SkillLibrary()
    lib.partial_fit(demos[0], workspace=Workspace.from_calibration([demos[0].human]))
    lib.save(tmp_path / "library.npz")
    save_calibration(tmp_path / "calibration.npz", [np.zeros((5, 3)), np.ones((5, 3))])
    np.savez(tmp_path / "predictions.npz", format=np.array("drake-skills predictions"), t=np.zeros((0, 3)))
    (tmp_path / "results.csv").write_text("file,decision\na,skill\n")
    scan = scan_dir(tmp_path)
    assert len(scan.demos) == 3
    skipped = {p.name: why for p, why in scan.skipped}
    assert set(skipped) == {"library.npz", "calibration.npz", "predictions.npz", "results.csv"}
    assert "library" in skipped["library.npz"] and "calibration" in skipped["calibration.npz"]
    assert all(f"skipped '{tmp_path / name}'" in " ".join(scan.notes()) for name in skipped)


def test_a_broken_demonstration_is_still_an_error_not_skipped(tmp_path):
    d = _demo()
    np.savez(tmp_path / "broken.npz", t=d.t, robot=d.robot)  # looks like a demonstration, has no human
    with pytest.raises(ValueError, match=r"broken\.npz.*missing.*human"):
        scan_dir(tmp_path)


@pytest.mark.parametrize("d_h, d_r, message", [
    (2, 7, "missing column 'hz'"),
    (3, 6, "missing column 'q7'"),
    (3, 0, "missing columns 'q1', 'q2'"),
    (3, 8, "extra column 'q8'"),
])
def test_a_demonstration_with_other_columns_than_the_first_is_an_error_naming_the_column(tmp_path, d_h, d_r,
                                                                                         message):
    odd = save_csv(_demo(d_h=d_h, d_r=d_r), tmp_path / "odd.csv")
    with pytest.raises(ValueError) as exc:
        check_layout(load_demo(odd), 3, 7, "its first demonstration 'first.npz'")
    msg = str(exc.value)
    assert "odd.csv" in msg and message in msg and "first.npz" in msg and "t, hx, hy, hz, q1..q7" in msg, msg
    check_layout(_demo(), 3, 7, "x")  # the same layout passes


def test_workspace_json_round_trips_and_bad_files_name_the_file(tmp_path):
    ws = Workspace([-0.1, -0.3, -0.4], [0.4, 0.3, 0.2], scale=10.0)
    path = ws.save(tmp_path / "workspace.json")
    back = load_workspace(path)
    np.testing.assert_array_equal(back.lower, ws.lower)
    np.testing.assert_array_equal(back.upper, ws.upper)
    assert json.loads(path.read_text()) == {"lower": [-0.1, -0.3, -0.4], "upper": [0.4, 0.3, 0.2], "scale": 10.0}
    cases = {"notjson.json": ("{lower", "not a JSON"), "keys.json": ('{"lower": [0]}', "'upper'"),
             "extra.json": ('{"lower": [0], "upper": [1], "size": 3}', "'upper'"),
             "empty.json": ('{"lower": [0, 1], "upper": [1, 1]}', "empty along axes [1]")}
    for name, (text, problem) in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(ValueError) as exc:
            Workspace.load(tmp_path / name)
        assert name in str(exc.value) and problem in str(exc.value), (name, str(exc.value))


def test_a_calibration_file_gives_the_range_with_the_third_axis_shrunk(tmp_path):
    xy = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 0.0]])
    zy = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 1.0]])
    ws = load_workspace(save_calibration(tmp_path / "calibration.npz", [xy, zy]))
    np.testing.assert_allclose(ws.lower, [0.0, 0.0, 0.05])
    np.testing.assert_allclose(ws.upper, [1.0, 2.0, 0.95])
