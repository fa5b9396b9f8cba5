"""benchmarks/false_starts.py (the experiment behind RESULTS.md's "False starts"), at a reduced size."""

import numpy as np

from drake_skills import LibraryConfig
from drake_skills.data.lasa import lasa_workspace, load_lasa

from bench_scripts import load


def _script():
    return load("false_starts")


def test_a_false_start_is_out_and_back_to_where_the_motion_begins_then_the_motion_itself():
    fs = _script()
    d = load_lasa(["GShape"], 1, subsample=5)[0]
    m, begin = fs.with_false_start(d, np.random.default_rng(0))
    miss = m.human[begin] - d.human[0]
    np.testing.assert_allclose(m.human[begin:], d.human + miss)      # the motion itself, from `begin` on, moved ...
    extent = np.linalg.norm(d.human - d.human[0], axis=1).max()
    assert np.linalg.norm(miss) <= 0.05 * extent + 1e-9             # ... to where the false start came back near
    np.testing.assert_allclose(m.human[0], d.human[0])                # out from where it begins
    assert np.all(np.diff(m.t) > 0) and m.task == d.task


def test_with_the_setting_on_false_starts_are_answered_as_the_clean_motions_and_off_they_are_unknown():
    """Two LASA shapes, 4 taught and 3 held out: whole motions after a false start of their own are answered as
    the clean ones with the setting on, and are all unknown with it off."""
    fs = _script()
    demos = load_lasa(["GShape", "Sine"], 7, subsample=5)
    taught = [d for i, d in enumerate(demos) if i % 7 < 4]
    held = [d for i, d in enumerate(demos) if i % 7 >= 4]
    counts = fs.evaluate([(taught, held)], LibraryConfig(workspace=lasa_workspace(demos)), orders=1)
    np.testing.assert_array_equal(counts[(True, "same", 1.0)], counts[(True, "clean", 1.0)])
    assert counts[(True, "clean", 1.0)][0] >= 5                  # 5-6 of 6 held out right
    assert counts[(False, "same", 1.0)][2] == len(held)          # all unknown without it
