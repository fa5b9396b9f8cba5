"""The scale experiment (issue 19) at reduced size: tables, the library finds the skills it is shown, CLI."""
import json
from dataclasses import replace

import numpy as np
import pytest

from drake_skills.data.lasa import LASA_SHAPES
from drake_skills.evaluation.scale import EVENTS, OUTCOMES, ScaleSettings, evaluate_scale, tally_events
from drake_skills.library.views import Update


@pytest.fixture(scope="module")
def report():
    return evaluate_scale(ScaleSettings.quick(seed=1), progress=False)


def test_synthetic_libraries_find_one_component_per_skill_and_recognize_new_demonstrations(report):
    t = report.tables["synthetic"]
    assert t.column("skills") == [10, 10, 30, 30] and t.column("order") == ["random", "row"] * 2
    assert t.column("components") == t.column("skills")
    for row in report.summary["synthetic"]:
        parts = [row[k] for k in OUTCOMES]
        assert sum(parts) == pytest.approx(1.0, abs=1e-12)
        assert row["correct"] >= 0.95 and row["wrong"] == 0.0  # skills 1.5 apart, scatter 0.03
        assert row["ms_update"] > 0 and row["ms_recognize"] > 0 and row["ms_prefix"] > 0
        ev = row["events"]  # the components' account balances
        assert set(ev) == set(EVENTS) and ev["novel firsts"] <= row["skills"]
        assert ev["novel firsts"] + ev["novel repeats"] + ev["splits"] - ev["merges"] - ev["deletions"] \
            == row["components"], ev
    assert t.column("novel firsts") == [r["events"]["novel firsts"] for r in report.summary["synthetic"]]


def test_the_event_tally_counts_each_kind_of_change_of_a_stream():
    ev = dict.fromkeys(EVENTS, 0)
    tally_events(ev, Update(0, None, created=(0,)), repeat=False)
    tally_events(ev, Update(1, 0, updated=(0,)), repeat=True)
    tally_events(ev, Update(2, None, created=(1,), merged=((0, 1),)), repeat=True)
    tally_events(ev, Update(3, 0, updated=(0,), split=((0, 2), (3, 4)), deleted=(5,)), repeat=True)
    assert ev == {"novel firsts": 1, "novel repeats": 1, "splits": 2, "merges": 1, "deletions": 1}


def test_lasa_in_one_library_is_scored_on_the_held_out_demonstrations(report):
    t = report.tables["lasa"]
    assert t.column("order") == ["order 0", "mean"]
    s = report.summary["lasa"]
    assert s["shapes"] == 6
    assert sum(s[f"{k}_mean"] for k in OUTCOMES) == pytest.approx(1.0, abs=1e-12)
    assert 5 <= s["components_mean"] <= 8 and s["correct_mean"] >= 0.8, s
    for ev, n in zip(s["events_per_order"], s["components_per_order"]):
        assert ev["novel firsts"] <= 6 and sum(ev[e] for e in EVENTS[:3]) - ev["merges"] - ev["deletions"] == n, ev
    assert t.column("novel firsts")[0] == s["events_per_order"][0]["novel firsts"]
    per = s["components_per_shape"]  # every component belongs to exactly one shape
    assert len(per) == 6 and [sum(v[i] for v in per.values()) for i in range(1)] == s["components_per_order"]
    assert report.tables["lasa_shapes"].column("shape") == list(per)
    assert "scale" in report.figures
    # each shape's held-out outcomes are fractions that sum to 1; their sum over shapes is the order's table
    shapes = report.tables["lasa_shapes"]
    per_shape = np.array([shapes.column(k) for k in OUTCOMES], float).T
    np.testing.assert_allclose(per_shape.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(per_shape.mean(axis=0), [s[f"{k}_mean"] for k in OUTCOMES], rtol=0, atol=1e-12)
    # no Multi_Models shape among the six: the single-pattern figures are the whole table's
    assert s["single_pattern_shapes"] == 6
    assert [s[f"single_pattern_{k}"] for k in OUTCOMES] == pytest.approx([s[f"{k}_mean"] for k in OUTCOMES], abs=1e-12)


def test_multi_model_shapes_are_told_apart_by_their_name():
    from drake_skills.evaluation.scale import is_multi_model

    assert [s for s in LASA_SHAPES if is_multi_model(s)] == [f"Multi_Models_{i}" for i in range(1, 5)]


def test_the_same_seed_gives_the_same_libraries_and_answers(report):
    again = evaluate_scale(replace(ScaleSettings.quick(seed=1), lasa_orders=0, sizes=(10,)), progress=False,
                           figures=False)
    first = [r for r in report.summary["synthetic"] if r["skills"] == 10]
    for a, b in zip(first, again.summary["synthetic"]):
        assert {k: a[k] for k in ("components", *OUTCOMES)} == {k: b[k] for k in ("components", *OUTCOMES)}


def test_bad_settings_fail_before_any_work():
    with pytest.raises(ValueError, match="orders"):
        replace(ScaleSettings.quick(), orders=("sideways",))
    with pytest.raises(ValueError, match="lasa_train"):
        replace(ScaleSettings.quick(), lasa_train=7)
    with pytest.raises(ValueError, match="sizes"):
        replace(ScaleSettings.quick(), sizes=(1,))


def test_cli_writes_the_tables_the_plot_and_the_summary(tmp_path):
    from drake_skills.cli import main

    out = tmp_path / "scale"
    assert main(["eval", "scale", "--quick", "--orders", "1", "--sizes", "10", "--no-progress", "--out", str(out)]) == 0
    for name in ("lasa.md", "lasa.csv", "synthetic.md", "synthetic.csv", "scale.png", "summary.json"):
        assert (out / name).exists(), name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["command"].startswith("drake-skills eval scale") and summary["synthetic"][0]["skills"] == 10
    assert np.isfinite(summary["lasa"]["components_mean"])


def test_shapes_option_names_the_halves_the_defaults_were_chosen_and_reported_on():
    """--shapes half-a / half-b are every other LASA shape (disjoint, together all 30); bad names are refused."""
    from drake_skills.commands.evaluate import _lasa_shapes

    a, b = _lasa_shapes("half-a"), _lasa_shapes("half-b")
    assert len(a) == len(b) == 15 and not set(a) & set(b) and set(a) | set(b) == set(LASA_SHAPES)
    assert a[0] == LASA_SHAPES[0] and b[0] == LASA_SHAPES[1]
    assert _lasa_shapes(None) is None and _lasa_shapes("all") == tuple(LASA_SHAPES)
    assert _lasa_shapes(f"{LASA_SHAPES[3]}, {LASA_SHAPES[5]},{LASA_SHAPES[3]}") == (LASA_SHAPES[3], LASA_SHAPES[5])
    with pytest.raises(ValueError, match="unknown LASA shapes \\['Nope'\\]"):
        _lasa_shapes("Nope")


def test_with_a_multi_model_shape_the_single_pattern_figures_leave_it_out():
    """Angle and Multi_Models_2, one order: the single-pattern figures are Angle's row of lasa_shapes, the caption
    says them, and a set of Multi_Models shapes only has none (null in the summary, not NaN)."""
    s = replace(ScaleSettings.quick(seed=2), lasa_shapes=("Angle", "Multi_Models_2"), sizes=(10,),
                orders=("random",))
    rep = evaluate_scale(s, progress=False, figures=False)
    summary = rep.summary["lasa"]
    shapes = rep.tables["lasa_shapes"]
    angle = shapes.rows[shapes.column("shape").index("Angle")]
    assert summary["single_pattern_shapes"] == 1
    assert [summary[f"single_pattern_{k}"] for k in OUTCOMES] == [angle[shapes.columns.index(k)] for k in OUTCOMES]
    assert "The 1 single-pattern shapes (all but Multi_Models)" in rep.tables["lasa"].caption
    only = evaluate_scale(replace(s, lasa_shapes=("Multi_Models_2",)), progress=False, figures=False)
    assert only.summary["lasa"]["single_pattern_shapes"] == 0
    assert all(only.summary["lasa"][f"single_pattern_{k}"] is None for k in OUTCOMES)
    json.dumps(only.summary, allow_nan=False)


def test_by_motion_a_held_out_motion_never_taught_is_rightly_unknown():
    """Multi_Models_1 (3 motions) with one demonstration taught: the held-out demonstrations of its other two motions
    are "unknown", which counts as correct by motion and only there; nothing else moves between the counts."""
    s = replace(ScaleSettings.quick(seed=3), lasa_shapes=("Angle", "Multi_Models_1"), lasa_train=1, lasa_orders=3,
                sizes=(10,), orders=("random",))
    rep = evaluate_scale(s, progress=False, figures=False)
    summary = rep.summary["lasa"]
    t = rep.tables["lasa"]
    assert t.column("motions taught") == [2, 2, 2, 2.0] and summary["motions_taught_mean"] == 2.0
    assert summary["motions_per_shape"] == {"Angle": [1, 1, 1], "Multi_Models_1": [1, 1, 1]}
    assert summary["components_per_shape"] == summary["motions_per_shape"]
    # at least 4 of Multi_Models_1's 6 held-out demonstrations draw a motion not taught (its motions have 3, 2, 2)
    assert summary["unknown_mean"] >= 4 / 12 - 1e-12 and summary["wrong_mean"] == 0.0
    assert summary["by_motion_correct_mean"] == pytest.approx(1.0, abs=1e-12)
    assert t.column("correct by motion")[-1] == pytest.approx(summary["by_motion_correct_mean"], abs=1e-12)
    moved = summary["by_motion_correct_mean"] - summary["correct_mean"]
    assert moved == pytest.approx(summary["unknown_mean"] - summary["by_motion_unknown_mean"], abs=1e-12)
    for k in ("wrong", "undecided"):
        assert summary[f"by_motion_{k}_mean"] == summary[f"{k}_mean"]
    shapes = rep.tables["lasa_shapes"]
    assert shapes.column("orders with 1 per motion taught") == [3, 3]


def test_single_pattern_shapes_count_the_same_by_motion(report):
    s = report.summary["lasa"]
    assert s["motions_taught_mean"] == 6.0
    assert [s[f"by_motion_{k}_mean"] for k in OUTCOMES] == [s[f"{k}_mean"] for k in OUTCOMES]
