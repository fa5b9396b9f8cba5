"""Interactions stored back to back in one npz (the buetepage_hr layout): the real file, and every error naming the file."""
import numpy as np
import pytest

from drake_skills.data.interaction import COLUMNS, GapWarning, load_interactions
from shared_data import require


def _arrays(m=3, T=20, seed=0, robot=True):
    rng = np.random.default_rng(seed)
    lengths = T + np.arange(m)
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    n = int(offsets[-1])
    out = {"human": rng.normal(size=(n, 9)), "offsets": offsets,
           "task": np.array(["a", "b", "a"][:m]), "split": np.array(["train", "train", "test"][:m]),
           "active_end": (lengths - 3).astype(np.int64)}
    if robot:
        out["robot"] = rng.normal(size=(n, 7))
    return out


def _write(path, **arrays):
    np.savez(path, **arrays)
    return path


def test_real_file_has_41_interactions_in_the_sources_split():
    demos = load_interactions(require())
    assert len(demos) == 41 and len(demos.train) == 32 and len(demos.test) == 9
    assert demos.tasks == ("hand_wave", "hand_shake", "rocket", "parachute")
    for task in demos.tasks:
        assert sum(d.task == task for d in demos.train) == 8
    d = demos[17]
    assert d.name == "buetepage_hr:017:train" and d.task == "rocket"
    assert d.human.shape == (495, 3) and d.robot.shape == (495, 7)
    np.testing.assert_allclose(np.diff(d.t), 0.01, rtol=1e-12)  # 100 Hz by default
    assert demos.split[17] == "train" and demos.active_end[17] == 470
    assert all(d.name.endswith(":test") for d in demos.test)
    arm = load_interactions(require(), columns="arm")
    assert arm[17].human.shape == (495, 9)
    np.testing.assert_array_equal(arm[17].human[:, 6:9], d.human)  # the hand is columns 6:9 of the arm


def test_columns_rate_and_names_follow_the_arguments(tmp_path):
    a = _arrays()
    path = _write(tmp_path / "x.npz", **a)
    demos = load_interactions(path, columns=[0, 4], rate_hz=50.0)
    assert [d.name for d in demos] == ["x:000:train", "x:001:train", "x:002:test"]
    np.testing.assert_array_equal(demos[1].human, a["human"][20:41][:, [0, 4]])
    np.testing.assert_array_equal(demos[1].robot, a["robot"][20:41])
    assert demos[2].t[-1] == pytest.approx(21 / 50.0)
    assert demos.columns == (0, 4) and demos.rate_hz == 50.0
    assert [d.name for d in demos.subset("test")] == ["x:002:test"]
    assert set(COLUMNS) >= {"hand", "arm"}


def test_robot_split_and_active_end_are_optional(tmp_path):
    a = _arrays(robot=False)
    del a["split"], a["active_end"], a["task"]
    demos = load_interactions(_write(tmp_path / "y.npz", **a))
    assert [d.name for d in demos] == ["y:000", "y:001", "y:002"]
    assert all(d.robot is None and d.task is None for d in demos)
    assert demos.split == (None,) * 3 and demos.active_end == (None,) * 3
    with pytest.raises(ValueError, match=r"y\.npz.*no 'split'"):
        demos.train


def _bad(tmp_path):
    a = _arrays()
    cases = {}

    def case(name, match, **change):
        b = dict(a)
        for k, v in change.items():
            if v is None:
                del b[k]
            else:
                b[k] = v
        cases[name] = (b, match)

    case("no_offsets", r"missing key\(s\) \['offsets'\]", offsets=None)
    case("no_human", r"missing key\(s\) \['human'\]", human=None)
    dec = a["offsets"].copy()
    dec[1], dec[2] = dec[2], dec[1]
    case("offsets_not_increasing", r"'offsets' is not increasing: offsets\[1\]=41 then offsets\[2\]=20", offsets=dec)
    short = a["offsets"].copy()
    short[-1] -= 1
    case("offsets_short", r"'offsets' must run from 0 to the 63 rows", offsets=short)
    case("robot_rows", r"'robot' has 62 rows but 'human' has 63", robot=a["robot"][:-1])
    case("task_length", r"'task' has shape \(2,\), expected \(3,\)", task=a["task"][:2])
    case("split_value", r"'split' holds \['val'\]", split=np.array(["train", "val", "test"]))
    case("active_end_outside", r"active_end\[1\] = 99 is outside interaction 1 \(21 samples\)",
         active_end=np.array([5, 99, 5]))
    nan = a["human"].copy()
    nan[25:26 + 50, 7] = np.nan   # interaction 1 is rows 20..40: NaN from its row 5 to its end and on into 2
    case("nan", r"'human' has NaN/inf in every row of interaction 2 \(22 rows\)", human=nan)
    gap = np.repeat(a["human"][:1], 200, axis=0)   # one long interaction: 0.6 s of NaN in the middle
    gap[50:110, 6] = np.inf
    case("long_gap", r"'human' has NaN/inf in interaction 0 at rows 50\.\.109 \(0\.6 s at 100 Hz; at most "
                     r"max_gap_s = 0\.5 s is filled", human=gap, offsets=np.array([0, 200]), robot=None, task=None,
         split=None, active_end=None)
    case("human_1d", r"'human' must be a 2-D numeric array", human=a["human"][:, 0])
    return cases


@pytest.mark.parametrize("name", list(_bad(None)))
def test_bad_file_is_an_error_naming_the_file_and_the_problem(tmp_path, name):
    arrays, match = _bad(tmp_path)[name]
    path = _write(tmp_path / f"{name}.npz", **arrays)
    with pytest.raises(ValueError, match=match) as exc:
        load_interactions(path)
    assert f"{name}.npz" in str(exc.value)


def test_columns_out_of_range_not_an_npz_and_pickles_are_rejected(tmp_path):
    path = _write(tmp_path / "ok.npz", **_arrays())
    with pytest.raises(ValueError, match=r"ok\.npz.*columns \[9\] out of range: human has 9 columns"):
        load_interactions(path, columns=[0, 9])
    with pytest.raises(ValueError, match=r"ok\.npz.*unknown column selection 'leg'"):
        load_interactions(path, columns="leg")
    text = tmp_path / "t.npz"
    text.write_text("not a zip")
    with pytest.raises(ValueError, match=r"t\.npz.*not an npz"):
        load_interactions(text)
    a = _arrays()
    a["task"] = np.array(["a", None, "b"], dtype=object)
    with pytest.raises(ValueError, match=r"obj\.npz.*pickled data"):
        load_interactions(_write(tmp_path / "obj.npz", **a))
    with pytest.raises(FileNotFoundError, match="nope.npz"):
        load_interactions(tmp_path / "nope.npz")


def test_short_runs_of_missing_samples_are_filled_by_interpolation_with_a_warning(tmp_path):
    """A tracker that lost the joint: NaN/inf runs up to max_gap_s (0.5 s) in the selected human columns or the robot
    columns are interpolated linearly (held at an interaction's ends) and a GapWarning counts them; NaN in a column
    not selected is ignored; max_gap_s=0 refuses any, a negative one is an error."""
    a = _arrays()
    clean = load_interactions(_write(tmp_path / "clean.npz", **a))
    human, robot = a["human"].copy(), a["robot"].copy()
    human[25:27, 7] = np.nan          # interaction 1, rows 5-6, a hand column
    human[20, 8] = np.inf             # interaction 1, its first row: held from row 1
    human[3, 0] = np.nan              # interaction 0, a shoulder column: not selected
    robot[45, 2] = np.nan             # interaction 2, row 4
    path = _write(tmp_path / "gaps.npz", **dict(a, human=human, robot=robot))
    with pytest.warns(GapWarning, match=r"gaps\.npz.*filled 3 run\(s\) of NaN/inf samples by linear interpolation "
                                        r"\(longest 2 row\(s\), 0\.02 s\) in interaction\(s\) \[1, 2\]: human 2, robot 1"):
        demos = load_interactions(path)
    d = demos[1].human
    for r in (5, 6):
        expected = a["human"][24, 6:9] + (r - 4) / 3 * (a["human"][27, 6:9] - a["human"][24, 6:9])
        np.testing.assert_allclose(d[r, 1], expected[1], rtol=1e-12)
    assert d[0, 2] == a["human"][21, 8]
    np.testing.assert_allclose(demos[2].robot[4, 2], 0.5 * (a["robot"][44, 2] + a["robot"][46, 2]), rtol=1e-12)
    # the valid readings of a partly lost row stay as they were
    np.testing.assert_array_equal(d[5:7, [0, 2]], a["human"][25:27][:, [6, 8]])
    np.testing.assert_array_equal(demos[2].robot[4, [0, 1, 3, 4, 5, 6]], a["robot"][45, [0, 1, 3, 4, 5, 6]])
    np.testing.assert_array_equal(d[0, :2], a["human"][20, 6:8])
    np.testing.assert_array_equal(demos[0].human, clean[0].human)   # the unselected NaN changed nothing
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_interactions(_write(tmp_path / "shoulder.npz", **dict(a, human=np.where(
            np.arange(9) == 0, np.nan, a["human"]))))   # NaN only in the shoulder: silent
    with pytest.raises(ValueError, match=r"gaps\.npz.*'human' has NaN/inf in interaction 1 at rows 0\.\.0 \(0\.01 s"):
        load_interactions(path, max_gap_s=0)
    with pytest.raises(ValueError, match=r"max_gap_s must be >= 0, got -1"):
        load_interactions(path, max_gap_s=-1)


def test_the_hand_of_a_file_that_holds_a_wrist_only_is_its_three_columns(tmp_path):
    """The default selection ("hand", columns 6:9 of the buetepage_hr layout) on a file whose human array has 3
    columns takes those 3; another named selection there is an error naming the file."""
    a = _arrays()
    a["human"] = a["human"][:, 6:9].copy()
    path = _write(tmp_path / "wrist.npz", **a)
    demos = load_interactions(path)
    np.testing.assert_array_equal(demos[1].human, a["human"][20:41])
    np.testing.assert_array_equal(load_interactions(path, columns="wrist")[0].human, demos[0].human)
    for name in ("elbow", "shoulder", "arm"):
        with pytest.raises(ValueError, match=rf"wrist\.npz.*'{name}' picks none of the 3 human columns"):
            load_interactions(path, columns=name)
