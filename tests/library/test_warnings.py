"""The library's data warnings: a query without the workspace it was trained with, and data in other
units (the units guard), each once per library; whether it was trained with a workspace is kept in its file."""
import inspect
import json
import warnings

import numpy as np
import pytest

from drake_skills import Demonstration, SkillLibrary, Workspace
from drake_skills.library.incremental import UNITS_RANGE, DataWarning, UnitsWarning, WorkspaceWarning

from shared_data import require
from synthetic import synthetic_demo


def _reach(length_m: float, seed: int = 0, T: int = 120) -> Demonstration:
    """A reach of ``length_m`` (metres, or whatever unit) forward with a small bend, and 7 joints."""
    rng = np.random.default_rng(seed)
    z = np.linspace(0.0, 1.0, T)
    s = 10 * z ** 3 - 15 * z ** 4 + 6 * z ** 5
    human = np.stack([s, 0.3 * np.sin(np.pi * z), 0.1 * s], axis=1) * length_m + rng.normal(0, 1e-3 * length_m,
                                                                                            (T, 3))
    return Demonstration(t=1.2 * z, human=human, robot=np.outer(s, np.linspace(0.2, 1.0, 7)))


#: A seated person's workspace in metres.
WS_M = Workspace([-0.1, -0.3, -0.2], [0.5, 0.3, 0.3])


def _caught(fn):
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        fn()
    return [w for w in got if issubclass(w.category, DataWarning)]


def test_a_reach_in_metres_without_a_workspace_warns_once_naming_what_to_pass():
    lib = SkillLibrary()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for i in range(3):  # called from this frame itself (a lambda or a comprehension is a frame on this line too)
            line = inspect.currentframe().f_lineno + 1
            lib.partial_fit(_reach(0.3, seed=i))
    got = [w for w in caught if issubclass(w.category, DataWarning)]
    assert len(got) == 1 and got[0].category is UnitsWarning
    msg = str(got[0].message)
    assert "spans 0.3" in msg and "far below" in msg and "workspace=" in msg and "Workspace.from_calibration" in msg
    assert (got[0].filename, got[0].lineno) == (__file__, line)  # it points at the caller's line, not the library's
    assert lib.n_seen == 3  # a warning, not an error: the library learned


def test_the_same_reach_in_millimetres_warns_that_it_is_far_above():
    got = _caught(lambda: SkillLibrary().partial_fit(_reach(300.0)))
    assert len(got) == 1 and got[0].category is UnitsWarning and "far above" in str(got[0].message)


def test_no_units_warning_for_normalized_data_or_raw_data_with_its_workspace():
    rng = np.random.default_rng(0)
    lib = SkillLibrary()
    assert _caught(lambda: [lib.partial_fit(synthetic_demo(i % 3, rng)) for i in range(9)]) == []
    lib_m = SkillLibrary()
    assert _caught(lambda: [lib_m.partial_fit(_reach(0.3, seed=i), workspace=WS_M) for i in range(3)]) == []
    assert _caught(lambda: lib_m.recognize(_reach(0.3, seed=9).human, workspace=WS_M, observed_fraction=1.0)) == []


def test_the_units_guard_bounds_are_a_tenth_and_ten_times_the_workspace_scale():
    assert UNITS_RANGE == (0.1, 10.0)
    # a reach of length L spans L units: 1.1 and 95 pass, 0.9 and 105 warn
    assert _caught(lambda: [SkillLibrary().partial_fit(_reach(L)) for L in (1.1, 95.0)]) == []
    assert len(_caught(lambda: SkillLibrary().partial_fit(_reach(0.9)))) == 1
    assert len(_caught(lambda: SkillLibrary().partial_fit(_reach(105.0)))) == 1


def test_a_workspace_in_other_units_than_the_data_warns():
    ws_mm = Workspace(WS_M.lower * 1000, WS_M.upper * 1000)
    got = _caught(lambda: SkillLibrary().partial_fit(_reach(0.3), workspace=ws_mm))
    assert len(got) == 1 and "same units" in str(got[0].message)


def test_a_prefix_may_span_little_but_a_whole_motion_may_not():
    lib = SkillLibrary()
    for i in range(3):
        lib.partial_fit(synthetic_demo(0, np.random.default_rng(i)))
    start = synthetic_demo(0, np.random.default_rng(5)).human[:12]  # the first tenth of a reach
    assert _caught(lambda: lib.recognize(start)) == []  # phase estimated: may be a prefix
    assert _caught(lambda: lib.recognize(start, observed_fraction=0.1)) == []
    got = _caught(lambda: lib.recognize(start, observed_fraction=1.0))
    assert len(got) == 1 and got[0].category is UnitsWarning


def test_a_query_without_the_workspace_the_library_was_trained_with_warns_once():
    lib = SkillLibrary()
    for i in range(4):
        lib.partial_fit(_reach(0.3, seed=i), workspace=WS_M)
    assert lib.trained_with_workspace is True
    human = _reach(0.3, seed=7).human
    got = _caught(lambda: [lib.recognize(human, observed_fraction=1.0), lib.recognize(human),
                           lib.predict_robot(human, 1.0, component=lib.components[0].id)])
    assert [w.category for w in got] == [WorkspaceWarning]  # once, and not repeated as a units warning
    msg = str(got[0].message)
    assert "without a workspace" in msg and "workspace=" in msg and "normalized=True" in msg
    # what it warns about is real: without the workspace the motion is unknown, with it a skill
    assert lib.recognize(human, observed_fraction=1.0).status == "unknown"
    assert lib.recognize(human, observed_fraction=1.0, workspace=WS_M).status == "skill"


def test_normalized_queries_and_a_config_workspace_do_not_warn():
    lib = SkillLibrary()
    for i in range(3):
        lib.partial_fit(_reach(0.3, seed=i), workspace=WS_M)
    y = WS_M.normalize(_reach(0.3, seed=8).human)
    assert _caught(lambda: lib.recognize(y, normalized=True, observed_fraction=1.0)) == []
    from drake_skills import LibraryConfig

    lib_c = SkillLibrary(LibraryConfig(workspace=WS_M))
    for i in range(3):
        lib_c.partial_fit(_reach(0.3, seed=i))
    assert lib_c.trained_with_workspace is True
    assert _caught(lambda: lib_c.recognize(_reach(0.3, seed=8).human, observed_fraction=1.0)) == []


def test_teaching_without_a_workspace_after_teaching_with_one_warns():
    lib = SkillLibrary()
    lib.partial_fit(_reach(0.3), workspace=WS_M)
    got = _caught(lambda: lib.partial_fit(_reach(0.3, seed=1)))
    assert [w.category for w in got] == [WorkspaceWarning] and "partial_fit()" in str(got[0].message)


def test_the_library_file_remembers_whether_it_was_trained_with_a_workspace(tmp_path):
    with_ws, without = SkillLibrary(), SkillLibrary()
    rng = np.random.default_rng(0)
    for i in range(3):
        with_ws.partial_fit(_reach(0.3, seed=i), workspace=WS_M)
        without.partial_fit(synthetic_demo(i, rng))
    a = SkillLibrary.load(with_ws.save(tmp_path / "a.npz"))
    b = SkillLibrary.load(without.save(tmp_path / "b.npz"))
    assert (a.trained_with_workspace, b.trained_with_workspace) == (True, False)
    assert len(_caught(lambda: a.recognize(_reach(0.3).human, observed_fraction=1.0))) == 1  # warns after loading
    # a schema-3 file written before the flag existed reads as "not known" and never warns about it
    old = tmp_path / "old.npz"
    with np.load(tmp_path / "a.npz", allow_pickle=False) as f:
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(str(arrays["metadata"]))
    del meta["trained_with_workspace"]
    arrays["metadata"] = np.array(json.dumps(meta))
    np.savez(old, **arrays)
    c = SkillLibrary.load(old)
    assert c.trained_with_workspace is None and meta["schema_version"] == 3
    got = _caught(lambda: c.recognize(_reach(0.3).human, observed_fraction=1.0))
    assert all(w.category is not WorkspaceWarning for w in got)
    bad = dict(arrays, metadata=np.array(json.dumps({**meta, "trained_with_workspace": "yes"})))
    np.savez(tmp_path / "bad.npz", **bad)
    with pytest.raises(ValueError, match="bad.npz.*trained_with_workspace"):
        SkillLibrary.load(tmp_path / "bad.npz")


def test_real_interactions_with_the_training_workspace_do_not_warn():
    """buetepage_hr, hand columns, workspace = bounding box of the training wrists: no false alarm."""
    z = np.load(require("buetepage_hr.npz"), allow_pickle=False)
    off = z["offsets"]
    demos = [Demonstration(t=np.arange(off[i + 1] - off[i]) / 100.0, human=z["human"][off[i]:off[i + 1], 6:9],
                           robot=z["robot"][off[i]:off[i + 1]]) for i in range(len(off) - 1)]
    train = [d for d, s in zip(demos, z["split"]) if s == "train"]
    ws = Workspace.from_calibration([d.human for d in train])
    lib = SkillLibrary()
    assert _caught(lambda: [lib.partial_fit(d, workspace=ws) for d in train]) == []
    test = [d for d, s in zip(demos, z["split"]) if s == "test"]
    assert _caught(lambda: [lib.recognize(d.human, workspace=ws, observed_fraction=1.0) for d in test]) == []
    # ... and the same recordings in metres without the workspace are caught
    assert [w.category for w in _caught(lambda: SkillLibrary().partial_fit(train[0]))] == [UnitsWarning]


# --- refusals: the slips a warning cannot undo (a cold review taught a library mm data with a metres
#     workspace, and robot joints in degrees; both were taken with at most a warning) ---

def _taught_in_metres():
    lib = SkillLibrary()
    for i in range(4):
        lib.partial_fit(_reach(0.3 + 0.01 * i, seed=i), workspace=WS_M)
    return lib


def _same_file(lib, tmp_path, name):
    path = tmp_path / name
    lib.save(path)
    return path.read_bytes()


def test_millimetres_with_a_workspace_in_metres_are_refused_and_change_nothing(tmp_path):
    lib = _taught_in_metres()
    before = _same_file(lib, tmp_path, "before.npz")
    mm = _reach(300.0, seed=9)  # 0.3 m in millimetres: 5000 normalized units in a 0.6 m box
    with pytest.raises(ValueError, match=r"more than 10 times its workspace's scale .*different units.*unchanged"):
        lib.partial_fit(mm, workspace=WS_M)
    assert _same_file(lib, tmp_path, "after.npz") == before
    # ten workspaces (100 normalized units) is the line: 95 units are taught, 105 refused
    box_m = float(np.ptp(WS_M.normalize(_reach(0.3, seed=9).human), axis=0).max())  # normalized span of 0.3 m
    ok, bad = _reach(0.3 * 95.0 / box_m, seed=9), _reach(0.3 * 105.0 / box_m, seed=9)
    taught = _taught_in_metres()
    taught.partial_fit(ok, workspace=WS_M)
    assert taught.n_seen == 5
    with pytest.raises(ValueError, match="different units"):
        _taught_in_metres().partial_fit(bad, workspace=WS_M)
    with pytest.warns(UnitsWarning, match="same units"):
        lib.partial_fit(mm, workspace=WS_M, check_units=False)  # asked for: taught, with the warning
    assert lib.n_seen == 5


@pytest.mark.parametrize("factor, refused", [(np.degrees(1.0), True), (1e150, True), (25.0, False)])
def test_robot_values_far_larger_than_all_so_far_are_refused_and_change_nothing(tmp_path, factor, refused):
    """Degrees for radians (57x) and absurd values are refused; 25x, inside the 30x factor, is taught."""
    lib = _taught_in_metres()
    before = _same_file(lib, tmp_path, "before.npz")
    d = _reach(0.3, seed=7)
    scaled = Demonstration(t=d.t, human=d.human, robot=d.robot * factor, name="deg.csv")
    if refused:
        with pytest.raises(ValueError, match=r"demo 'deg.csv': the robot's values are .* times larger .*unchanged"):
            lib.partial_fit(scaled, workspace=WS_M)
        assert _same_file(lib, tmp_path, "after.npz") == before
        if factor < 1e3:
            lib.partial_fit(scaled, workspace=WS_M, check_units=False)  # asked for: taught
            assert lib.n_seen == 5
    else:
        lib.partial_fit(scaled, workspace=WS_M)
        assert lib.n_seen == 5


def test_the_robot_units_factor_leaves_room_over_the_spread_of_real_responses():
    """Within one data set the robot weights' RMS differs by at most 2.7x (guards.ROBOT_UNITS_FACTOR's note)."""
    from drake_skills.library.guards import ROBOT_UNITS_FACTOR

    assert ROBOT_UNITS_FACTOR == 30.0
    lib = SkillLibrary()
    rms = [np.sqrt(np.mean(lib.encode(d)[lib.config.n_basis_human * 3:] ** 2))
           for d in (synthetic_demo(k % 4, np.random.default_rng(k)) for k in range(8))]
    assert max(rms) / min(rms) < ROBOT_UNITS_FACTOR / 5


def test_a_query_warning_does_not_silence_the_warning_about_a_demonstration():
    """Warned once per kind for queries and once for teaching: before, any units warning (a tiny query)
    silenced the one about a demonstration in millimetres taught next."""
    lib = SkillLibrary()
    for i in range(3):
        lib.partial_fit(synthetic_demo(0, np.random.default_rng(i)))
    tiny = synthetic_demo(0, np.random.default_rng(5)).human[:12]
    assert len(_caught(lambda: lib.recognize(tiny, observed_fraction=1.0))) == 1
    got = _caught(lambda: lib.partial_fit(_reach(300.0)))
    assert len(got) == 1 and got[0].category is UnitsWarning and "above" in str(got[0].message)


def test_a_workspace_given_to_a_library_trained_without_one_warns_and_a_first_one_does_not():
    """A library taught as it was (learn --raw-units, or data already normalized) then asked with a workspace
    answered 'unknown' without a word (a cold review); the first demonstration of a new library may bring one."""
    lib = SkillLibrary()
    for i in range(3):
        lib.partial_fit(synthetic_demo(0, np.random.default_rng(i)))  # already normalized: no workspace
    ws = Workspace([-5.0, -5.0, -5.0], [15.0, 15.0, 15.0])
    query = synthetic_demo(0, np.random.default_rng(7)).human
    got = _caught(lambda: lib.recognize(query, workspace=ws, observed_fraction=1.0))
    assert len(got) == 1 and got[0].category is WorkspaceWarning and "trained without one" in str(got[0].message)
    assert _caught(lambda: lib.recognize(query, observed_fraction=1.0)) == []  # as it was taught: no warning
    assert _caught(lambda: SkillLibrary().partial_fit(_reach(0.3), workspace=WS_M)) == []
