"""``drake_skills.tuning`` and ``drake-skills tune``: a tiny cross-validated search on a local Ray.

One local Ray (2 CPUs, no dashboard) serves the whole module; while it runs, every socket
its processes listen on must be on the loopback interface.
"""
import ipaddress
import json
import sys

import numpy as np
import pytest

from drake_skills.data.demos import save_npz
from drake_skills.library.config import LibraryConfig
from drake_skills.sim.config import load_library_config
from drake_skills.tuning import (EXTRA_COMPONENT_COST, SEARCH_SPACE, WRONG_COST, _import_ray, ray_session,
                                 sample_configs, score_config, stratified_folds, tune)
from synthetic import WORKSPACE, synthetic_demo


def _demos(per_task=4, seed=0):
    rng = np.random.default_rng(seed)
    return [synthetic_demo(task, rng) for task in range(3) for _ in range(per_task)]


@pytest.fixture(scope="module")
def ray():
    with ray_session(num_cpus=2) as r:
        yield r


def _listening_addresses():
    import psutil

    me = psutil.Process()
    procs = [me] + me.children(recursive=True)
    out = []
    for p in procs:
        try:
            conns = p.net_connections(kind="inet")
        except (psutil.NoSuchProcess, psutil.AccessDenied):
            continue
        out += [(p.name(), c.laddr.ip) for c in conns if c.status == psutil.CONN_LISTEN]
    return out


def _loopback(ip: str) -> bool:
    a = ipaddress.ip_address(ip)
    if isinstance(a, ipaddress.IPv6Address) and a.ipv4_mapped is not None:
        a = a.ipv4_mapped
    return a.is_loopback


def test_local_ray_listens_on_loopback_only(ray):
    listening = _listening_addresses()
    assert len(listening) >= 3, listening  # gcs, raylet, workers: the check looked at something
    assert all(_loopback(ip) for _, ip in listening), listening


def test_tiny_tune_keeps_the_defaults_unless_a_trial_scores_higher_and_writes_a_config_that_loads(ray, tmp_path):
    demos = _demos()
    res = tune(demos, workspace=WORKSPACE, n_trials=3, seed=1, n_folds=2, n_orders=1)
    assert isinstance(res.config, LibraryConfig)
    assert len(res.trials.rows) == 3 and res.trials.column("trial") == [0, 1, 2]
    scores = res.trials.column("score")
    assert res.best == int(np.argmax(scores)) and scores[res.best] >= scores[0]
    assert res.trials.rows[0][1:1 + len(SEARCH_SPACE)] == [getattr(LibraryConfig(), n) for n in SEARCH_SPACE]
    for name in SEARCH_SPACE:
        assert getattr(res.config, name) == res.trials.rows[res.best][1 + list(SEARCH_SPACE).index(name)]
    # these 3 well separated synthetic skills: the defaults recognize every held-out reach
    assert res.trials.rows[0][res.trials.columns.index("correct")] == 1.0
    path = res.write_yaml(tmp_path / "tuned.yaml")
    back = load_library_config(path)
    assert back.dict() == res.config.dict()
    np.testing.assert_array_equal(back.workspace.lower, WORKSPACE.lower)


def test_results_do_not_depend_on_ray_scheduling(ray):
    demos = _demos(per_task=3, seed=3)
    a = tune(demos, workspace=WORKSPACE, n_trials=2, seed=4, n_folds=3, n_orders=1)
    b = tune(demos, workspace=WORKSPACE, n_trials=2, seed=4, n_folds=3, n_orders=1)
    assert a.trials.rows == b.trials.rows


def test_cli_tune_writes_config_trials_and_summary(ray, tmp_path, capsys):
    from drake_skills.cli import main

    d = tmp_path / "demos"
    for i, demo in enumerate(_demos(per_task=3, seed=5)):
        save_npz(demo, d / f"{i:02d}.npz")
    out = tmp_path / "tune"
    assert main(["tune", str(d), "--trials", "2", "--folds", "3", "--orders", "1", "--no-progress",
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_trials"] == 2 and summary["best_trial"] in (0, 1)
    cfg = load_library_config(out / "config.yaml")
    assert cfg.dict() == LibraryConfig.from_dict(summary["config"]).dict()
    assert len((out / "trials.csv").read_text().splitlines()) == 3
    assert "use it with --config" in capsys.readouterr().out


def test_a_wrong_answer_costs_ten_correct_ones_and_extra_components_a_little():
    """The objective on a library that merges everything (one component for 3 tasks) vs the defaults."""
    demos = _demos(per_task=4, seed=6)
    folds = stratified_folds([d.task for d in demos], 2, seed=0)
    good = score_config(LibraryConfig(), demos, folds, WORKSPACE, n_orders=1)
    assert good.correct == 1.0 and good.score == pytest.approx(1.0 - EXTRA_COMPONENT_COST * max(0, good.components - 3))
    # (the names off: with keep_tasks_apart the tasks would stay apart, and a component taught as several tasks
    # would be undecided, not wrong)
    merged = score_config(LibraryConfig(prior_scale=50.0, prior_floor=50.0, mixed_task_share=1.0,
                                        keep_tasks_apart=False, same_task_reach=1.0), demos, folds,
                          WORKSPACE, n_orders=1)
    assert merged.wrong > 0.3  # two of three tasks answered with the one component's label
    assert merged.score == pytest.approx(merged.correct - WRONG_COST * merged.wrong, abs=1e-9)


def test_folds_are_stratified_and_configs_reproducible():
    tasks = ["a"] * 5 + ["b"] * 4 + ["c"] * 2
    folds = stratified_folds(tasks, 2, seed=0)
    assert sorted(np.concatenate(folds).tolist()) == list(range(len(tasks)))
    for f in folds:
        assert {tasks[i] for i in f} == {"a", "b", "c"}
    a, b = sample_configs(LibraryConfig(), 6, seed=3), sample_configs(LibraryConfig(), 6, seed=3)
    assert [c.dict() for c in a] == [c.dict() for c in b] and a[0].dict() == LibraryConfig().dict()
    assert all(c.split_quantile > c.merge_quantile for c in a)


def test_bad_input_is_a_clear_error():
    demos = _demos(per_task=2)
    with pytest.raises(ValueError, match="labeled"):
        tune([type(demos[0])(t=demos[0].t, human=demos[0].human)], n_trials=1)
    with pytest.raises(ValueError, match=r"at least 2 demonstrations per task.*\['9'\]"):
        tune(demos + [_relabel(demos[1], "9")], n_trials=1)


def _relabel(d, task):
    return type(d)(t=d.t, human=d.human, robot=d.robot, task=task, name=d.name)


def test_missing_ray_is_a_helpful_import_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)
    with pytest.raises(ImportError, match=r"pip install 'drake-skills\[tune\]'"):
        _import_ray("auto")
