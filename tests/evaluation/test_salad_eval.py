"""The salad experiment (issue 6) at reduced size: structure and sanity, never specific accuracies.

The library's defaults and the scene are being tuned, so these tests check what must hold
whatever the numbers are: identical results for any number of workers, fractions in
[0, 1] that sum to 1, every file written, figures that are real PNGs.
"""
import json
import math
from collections import Counter
from dataclasses import replace

import numpy as np
import pytest

from drake_skills.evaluation.common import use_agg
from drake_skills.evaluation.labeled import CORRECT, UNKNOWN, WRONG, LabeledLibrary
from drake_skills.evaluation.salad import evaluate_salad
from drake_skills.evaluation.salad_data import SaladSettings, load_salad_data, shared_workspace
from drake_skills.evaluation.salad_personal import earliest_fraction, observed_prefix, response_errors
from drake_skills.library.incremental import Update
from drake_skills.sim.models import FlangeKinematics

use_agg()

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
TABLES = ("classification", "classification_matrix", "components_per_subject", "kl_vs_demos",
          "components_per_task", "components_per_task_matrix", "transfer", "response_vs_fraction",
          "earliest_decision", "anticipation", "commits")
FIGURES = ("classification", "kl_vs_demos", "components_per_task", "transfer", "response_vs_fraction")


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("salad-cache")


@pytest.fixture(scope="module")
def reports(cache):
    s = SaladSettings.quick(seed=3)
    one = evaluate_salad(s, workers=1, progress=False, cache_dir=cache)
    # the second run is compared table by table (its figures are the first run's code): none drawn
    two = evaluate_salad(SaladSettings.quick(seed=3), workers=2, progress=False, cache_dir=cache, figures=False)
    return s, one, two


def _same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


def test_quick_settings_are_small():
    s = SaladSettings.quick(seed=5)
    assert s.seed == 5
    assert s.n_subjects <= 3 and s.n_demos <= 5 and s.trials <= 3
    assert 1 <= s.train_per_task < s.n_demos
    assert s.grid()[-1] == 1.0


def test_one_and_two_workers_give_identical_tables(reports):
    _, one, two = reports
    assert list(one.tables) == list(two.tables) == list(TABLES)
    for key in TABLES:
        a, b = one.tables[key], two.tables[key]
        assert a.columns == b.columns, key
        assert len(a.rows) == len(b.rows), key
        for ra, rb in zip(a.rows, b.rows):
            assert all(_same(x, y) for x, y in zip(ra, rb)), (key, ra, rb)
    sa = {k: v for k, v in one.summary.items() if k != "seconds"}
    sb = {k: v for k, v in two.summary.items() if k != "seconds"}
    assert json.dumps(sa, sort_keys=True, default=str) == json.dumps(sb, sort_keys=True, default=str)


@pytest.mark.parametrize("key", ["classification", "transfer", "response_vs_fraction"])
def test_correct_wrong_unknown_are_fractions_that_sum_to_one(reports, key):
    _, rep, _ = reports
    t = rep.tables[key]
    c, w, u = (np.array(t.column(name), float) for name in ("correct", "wrong", "unknown"))
    assert len(c) > 0
    for a in (c, w, u):
        assert ((a >= 0) & (a <= 1)).all(), key
    np.testing.assert_allclose(c + w + u, 1.0, rtol=0, atol=1e-9)


def test_classification_has_a_row_per_subject_and_task(reports):
    s, rep, _ = reports
    t = rep.tables["classification"]
    assert len(t.rows) == s.n_subjects * (len(s.tasks) + 1) + 1
    n_test = s.n_demos - s.train_per_task
    per_task = [r for r in t.rows if r[1] in s.tasks]
    assert all(r[-1] == s.trials * n_test for r in per_task)
    m = rep.tables["classification_matrix"]
    assert m.columns == ["subject", *s.tasks] and len(m.rows) == s.n_subjects


def test_component_distributions_sum_to_one(reports):
    s, rep, _ = reports
    t = rep.tables["components_per_subject"]
    assert len(t.rows) == s.n_subjects
    for r in t.rows:
        d = np.array(r[2:], float)
        assert ((d >= 0) & (d <= 1)).all()
        assert abs(d.sum() - 1) < 1e-9
        assert r[1] >= 1
    t = rep.tables["components_per_task"]
    assert len(t.rows) == 3 * len(s.tasks)
    for r in t.rows:
        d = np.array(r[2:-1], float)
        assert ((d >= 0) & (d <= 1)).all() and abs(d.sum() - 1) < 1e-9
        assert r[-1] >= 1


def test_kl_table_is_finite_and_covers_every_demo_count(reports):
    s, rep, _ = reports
    t = rep.tables["kl_vs_demos"]
    assert t.column("demos per task") == list(range(1, s.kl_per_task + 1))
    inc, em = (np.array(t.column(name), float) for name in ("KL inc mean", "KL EM mean"))
    assert np.isfinite(inc).all() and np.isfinite(em).all()
    # more demonstrations per task bring the library closer to the labeled baseline (observed: 172 -> 133)
    assert inc[-1] < inc[0], inc
    # batch EM with the true K and all the data lands on (nearly) the labeled solution (observed: |KL| < 1e-10);
    # the incremental library, one demonstration at a time, is farther away
    assert (np.abs(em) < 0.5).all() and (inc > em).all(), (inc, em)


def test_response_errors_are_non_negative_and_earliest_fraction_is_on_the_grid(reports):
    s, rep, _ = reports
    t = rep.tables["response_vs_fraction"]
    assert t.column("observed fraction") == list(s.grid())
    for name in t.columns[4:]:
        v = np.array(t.column(name), float)
        assert (v[np.isfinite(v)] >= 0).all(), name
    e = rep.tables["earliest_decision"]
    assert [r[0] for r in e.rows] == [*s.tasks, "all"]
    for r in e.rows:
        assert r[1] == "never" or r[1] in s.grid()
        assert 0 <= r[3] <= 1


def test_report_writes_tables_plots_and_summary(reports, tmp_path):
    s, rep, _ = reports
    paths = rep.write(tmp_path)
    assert all(p.is_file() for p in paths)
    for key in TABLES:
        assert (tmp_path / f"{key}.md").read_text().startswith(f"## {key}")
        assert (tmp_path / f"{key}.csv").stat().st_size > 0
    for key in FIGURES:
        data = (tmp_path / f"{key}.png").read_bytes()
        assert data[:8] == PNG_MAGIC and len(data) > 5000, key
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["settings"]["n_train"] == s.train_per_task
    assert summary["subjects"] == [f"subject{i}" for i in range(1, s.n_subjects + 1)]
    assert abs(sum(summary["personal_correct_wrong_unknown"]) - 1) < 1e-9


def test_cached_data_equals_generated_data(cache):
    s = SaladSettings.quick()
    s.n_subjects = 2
    fresh = load_salad_data(s)
    cached = load_salad_data(s, cache_dir=cache)  # written by the module's reports
    again = load_salad_data(s, cache_dir=cache)
    assert len(list(cache.rglob("*.npz"))) >= s.n_subjects * (len(s.tasks) * s.n_demos + 1)
    for a, b, c in zip(fresh, cached, again):
        assert a.subject.name == b.subject.name == c.subject.name
        for m, n in zip(a.calibration, c.calibration):
            np.testing.assert_array_equal(m, n)
        assert len(a.demos) == len(c.demos) == len(s.tasks) * s.n_demos
        for d, e in zip(a.demos, c.demos):
            assert (d.task, d.subject, d.name) == (e.task, e.subject, e.name)
            np.testing.assert_array_equal(d.t, e.t)
            np.testing.assert_array_equal(d.human, e.human)
            np.testing.assert_array_equal(d.robot, e.robot)


def test_observed_prefix_covers_the_fraction_of_the_path_length():
    rng = np.random.default_rng(0)
    human = np.cumsum(rng.normal(size=(200, 3)), axis=0)

    def length(y):
        return np.linalg.norm(np.diff(y, axis=0), axis=1).sum()

    for f in (0.05, 0.1, 0.37, 0.5, 0.99):
        p = observed_prefix(human, f)
        assert p.shape[0] >= 2
        np.testing.assert_array_equal(p[:-1], human[:p.shape[0] - 1])
        assert abs(length(p) - f * length(human)) < 1e-9 * length(human)
    assert observed_prefix(human, 1.0) is human
    with pytest.raises(ValueError, match="fraction"):
        observed_prefix(human, 0.0)


def test_labeled_library_moves_votes_with_merges_and_drops_deleted_components():
    lab = LabeledLibrary()
    updates = iter([Update(0, None, created=(0,)), Update(1, None, created=(1,)),
                    Update(2, 0, updated=(0, 1)), Update(3, 1, updated=(1,), merged=((1, 0),)),
                    Update(4, None, created=(2,), deleted=(1,))])
    lab.library.partial_fit = lambda demo, workspace=None: next(updates)

    class Demo:
        def __init__(self, task):
            self.task = task

    lab.teach(Demo("bowl"))
    lab.teach(Demo("tomato"))
    lab.teach(Demo("bowl"))
    assert lab.votes == {0: Counter(bowl=2), 1: Counter(tomato=1, bowl=1)}
    lab.teach(Demo("tomato"))
    assert lab.votes == {1: Counter(tomato=2, bowl=3)}
    assert lab.label_of(1) == "bowl"
    assert lab.outcome(1, "bowl") == CORRECT and lab.outcome(1, "tomato") == WRONG
    assert lab.outcome(None, "bowl") == UNKNOWN
    lab.teach(Demo("standup"))
    assert lab.votes == {2: Counter(standup=1)}
    assert lab.label_of(1) is None and lab.outcome(1, "bowl") == WRONG


def test_earliest_fraction_needs_the_target_at_every_larger_fraction():
    grid = (0.1, 0.2, 0.3, 0.4, 1.0)
    assert earliest_fraction(grid, [0.2, 0.96, 0.5, 0.95, 1.0], 0.95) == 0.4
    assert earliest_fraction(grid, [0.99, 0.96, 0.97, 0.95, 1.0], 0.95) == 0.1
    assert earliest_fraction(grid, [1.0, 1.0, 1.0, 1.0, 0.9], 0.95) is None
    assert earliest_fraction(grid, [1.0, 1.0, 1.0, float("nan"), 1.0], 0.95) == 1.0


def test_response_errors_are_nan_exactly_where_the_motion_is_unknown(cache):
    s = replace(SaladSettings.quick(), n_subjects=2)
    data = load_salad_data(s, cache_dir=cache)[0]
    ws = data.workspace()
    lab = LabeledLibrary()
    train = [d for t in s.tasks[:2] for d in data.by_task(t)[:3]]
    for d in train:
        lab.teach(d, ws)
    grid = s.grid()
    fk = FlangeKinematics()
    for demo in (data.by_task(s.tasks[0])[3], data.by_task(s.tasks[-1])[3]):  # a known and an unseen task
        r = response_errors(lab, demo, ws, grid, fk)
        answered = np.isin(r.outcome, [CORRECT, WRONG])  # unknown and undecided are not executed
        for k in ("rmse", "flange", "prior_rmse", "prior_flange"):
            e = getattr(r, k)
            assert e.shape == (len(grid),)
            assert np.isfinite(e[answered]).all() and (e[answered] >= 0).all()
            assert np.isnan(e[~answered]).all()
        if demo.task not in s.tasks[:2]:
            assert (r.outcome != CORRECT).all()


def test_each_subject_model_has_its_own_data_and_cache(cache):
    s = replace(SaladSettings.quick(), n_subjects=2, n_demos=2, tasks=("tomato",), subject_model="classic")
    classic = load_salad_data(s, cache_dir=cache)
    styled = load_salad_data(replace(s, subject_model="styled"), cache_dir=cache)
    assert all(d.subject.style is None for d in classic) and all(d.subject.style is not None for d in styled)
    assert not np.array_equal(classic[0].demos[0].human, styled[0].demos[0].human)
    assert {p.name for p in next(cache.glob("salad-*")).iterdir()} >= {"classic", "styled"}
    again = load_salad_data(s, cache_dir=cache)  # read back from its own cache
    np.testing.assert_array_equal(again[1].demos[1].human, classic[1].demos[1].human)


def test_shared_workspace_contains_every_personal_workspace(cache):
    s = SaladSettings.quick()
    data = load_salad_data(s, cache_dir=cache)
    shared = shared_workspace(data, z_factor=None)
    for d in data:
        ws = d.workspace(z_factor=None)
        assert (shared.lower <= ws.lower).all() and (shared.upper >= ws.upper).all()
    # the default keeps 90 % of the (shared) z range, as for a personal workspace
    shrunk = shared_workspace(data)
    np.testing.assert_allclose(shrunk.upper[2] - shrunk.lower[2], 0.9 * (shared.upper[2] - shared.lower[2]))


@pytest.mark.parametrize("change, message", [
    (dict(n_subjects=1), "n_subjects"), (dict(n_train=4), "n_train"), (dict(fractions=(0.0, 1.0)), "fractions"),
    (dict(tasks=("board", "soup")), "tasks"), (dict(transfer_test=9), "transfer_test"),
    (dict(subject_model="stylish"), "subject_model")])
def test_inconsistent_settings_are_rejected_with_the_setting_named(change, message):
    with pytest.raises(ValueError, match=message):
        replace(SaladSettings.quick(), **change)


def test_cli_eval_salad_quick_writes_its_artifacts(tmp_path, capsys):
    from drake_skills.cli import main

    out = tmp_path / "salad"
    assert main(["eval", "salad", "--quick", "--out", str(out), "--no-progress", "--workers", "2"]) == 0
    for key in TABLES:
        assert (out / f"{key}.md").is_file() and (out / f"{key}.csv").is_file()
    for key in FIGURES:
        assert (out / f"{key}.png").read_bytes()[:8] == PNG_MAGIC
    summary = json.loads((out / "summary.json").read_text())
    assert summary["command"].startswith("drake-skills eval salad")
    assert summary["settings"]["n_subjects"] == SaladSettings.quick().n_subjects
    assert any((out / "cache").rglob("*.npz"))
    assert "## classification" in capsys.readouterr().out


def test_anticipation_table_counts_four_outcomes_and_the_phase_error(reports):
    """Prefixes recognized without the fraction: the four outcomes sum to one, and on whole motions the estimated
    phase is within 0.1 of 1 (measured: 0.97-1.0)."""
    rep = reports[1]
    t = rep.tables["anticipation"]
    assert t.columns[:5] == ["true observed fraction", "correct", "wrong", "unknown", "undecided"]
    for row in t.rows:
        assert abs(sum(row[1:5]) - 1.0) < 1e-9
    full = [r for r in t.rows if r[0] == 1.0][0]
    assert full[5] == pytest.approx(1.0, abs=0.1) and full[6] < 0.1
    assert full[2] == 0.0  # no wrong answer on whole motions


def test_commits_table_replays_the_decision_logic_on_the_first_splits(reports):
    """The commits table: one row per task and 'all', test motions of the first commit_splits splits per subject
    (quick: 3 subjects x 2 splits x 2 test motions per task), first commits correct + wrong = 1 over commits,
    path shares at commit in (0, 1], executed outcomes summing to 1; the summary carries the same numbers."""
    s, rep, _ = reports
    t = rep.tables["commits"]
    assert [r[0] for r in t.rows] == [*s.tasks, "all"]
    per_task = s.n_demos - s.train_per_task
    expected = s.n_subjects * min(s.commit_splits, s.trials) * per_task
    for row in t.rows:
        n, committed, right, wrong, mean_share, median_share = row[1:7]
        assert n == (expected * len(s.tasks) if row[0] == "all" else expected)
        assert 0.0 <= committed <= 1.0
        if committed > 0:
            assert right + wrong == pytest.approx(1.0) and 0.0 < median_share <= 1.0 and 0.0 < mean_share <= 1.0
        assert sum(row[7:10]) == pytest.approx(1.0)
    assert rep.summary["commits"]["all"]["median_commit_share"] == t.rows[-1][6]


def test_a_salad_run_with_commit_splits_0_replays_nothing(cache):
    from drake_skills.evaluation.salad_data import SaladContext
    from drake_skills.evaluation.salad_personal import PersonalContext, personal_trial

    none = replace(SaladSettings.quick(seed=3), commit_splits=0)
    ctx = SaladContext.of(none, load_salad_data(none, cache_dir=cache))
    trial = personal_trial(PersonalContext(ctx), (0, 0))
    assert trial.first_commit.size == 0 and trial.commit_share.size == 0 and trial.outcome.shape[0] > 0


def test_commit_splits_must_be_a_non_negative_integer():
    with pytest.raises(ValueError, match=r"SaladSettings.commit_splits must be an integer >= 0"):
        SaladSettings(commit_splits=-1)
