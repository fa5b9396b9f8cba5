"""The sensitivity experiment at reduced size: structure, sanity, worker independence, CLI."""
import json
import subprocess
import sys
from dataclasses import replace

import pytest

from drake_skills.evaluation.sensitivity import CONFIGS, SensitivitySettings, evaluate_sensitivity


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    cache = tmp_path_factory.mktemp("sens-cache")
    one = evaluate_sensitivity(SensitivitySettings.quick(seed=1), workers=1, progress=False, cache_dir=cache)
    two = evaluate_sensitivity(SensitivitySettings.quick(seed=1), workers=2, progress=False, cache_dir=cache)
    return one, two


def test_one_row_per_configuration_with_fractions_that_sum_to_one(reports):
    rep, _ = reports
    t = rep.tables["sensitivity"]
    assert t.column("configuration") == list(CONFIGS)[:2]
    for name, row in rep.summary["configs"].items():
        assert 0.0 <= row["letters_one_per_shape"] <= 1.0
        parts = [row["salad_correct"], row["salad_wrong"], row["salad_unknown"]]
        assert all(0.0 <= p <= 1.0 for p in parts)
        assert abs(sum(parts) - 1.0) < 1e-9
        assert 1 <= row["salad_components"] <= 4 * 5  # at most one component per training demo
        assert row["overrides"] == CONFIGS[name]


def test_results_do_not_depend_on_the_number_of_workers(reports):
    one, two = reports
    assert one.summary["configs"] == two.summary["configs"]


def test_bad_overrides_fail_before_any_work():
    with pytest.raises(ValueError, match="gating_flor"):
        replace(SensitivitySettings.quick(), configs={"typo": {"gating_flor": 0.5}})
    with pytest.raises(ValueError, match="are gone"):
        replace(SensitivitySettings.quick(), configs={"old": {"gating_floor": 0.5}})
    with pytest.raises(ValueError, match="n_train"):
        replace(SensitivitySettings.quick(), n_train=9)


def test_cli_writes_the_table(tmp_path):
    out = tmp_path / "sens"
    r = subprocess.run([sys.executable, "-m", "drake_skills.cli", "eval", "sensitivity", "--quick", "--trials", "2",
                        "--no-progress", "--workers", "1", "--out", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "| default |" in r.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["settings"]["letter_orders"] == 2
    assert (out / "sensitivity.csv").read_text().startswith("configuration,")
