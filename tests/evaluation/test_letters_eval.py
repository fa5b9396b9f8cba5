"""``drake-skills eval letters --quick`` (Sec. 4.1) end to end: structure and sanity, not specific values."""
import json

import numpy as np

from drake_skills.evaluation.common import use_agg

use_agg()

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _rows(path):
    lines = path.read_text().splitlines()
    return lines[0].split(","), [line.split(",") for line in lines[1:]]


def test_cli_eval_letters_quick_writes_kl_table_components_and_plots(tmp_path, capsys):
    from drake_skills.cli import main

    out = tmp_path / "letters"
    assert main(["eval", "letters", "--quick", "--out", str(out), "--no-progress", "--workers", "2"]) == 0
    header, rows = _rows(out / "kl_vs_samples.csv")
    assert [int(r[0]) for r in rows] == list(range(1, 8))  # 1..7 samples per class
    for name in ("KL inc mean", "KL EM mean", "components mean"):
        v = np.array([float(r[header.index(name)]) for r in rows])
        assert np.isfinite(v).all() and (v > -1.0).all(), name
    header, rows = _rows(out / "components.csv")
    fractions = np.array([float(x) for x in rows[0][1:]])
    assert ((fractions >= 0) & (fractions <= 1)).all() and abs(fractions.sum() - 1) < 1e-9
    for key in ("kl_vs_samples", "library_growth", "components_hist"):
        data = (out / f"{key}.png").read_bytes()
        assert data[:8] == PNG_MAGIC and len(data) > 5000, key
    summary = json.loads((out / "summary.json").read_text())
    assert summary["settings"]["trials"] == 4 and len(summary["kl_incremental_mean"]) == 7
    assert "## kl_vs_samples" in capsys.readouterr().out
