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
    col = {name: np.array([float(r[header.index(name)]) for r in rows])
           for name in ("KL inc mean", "KL EM mean", "components mean")}
    # more samples per class bring the incremental library closer to the labeled baseline (observed: 114 -> 64)
    assert (np.diff(col["KL inc mean"]) < 0).all(), col["KL inc mean"]
    # batch EM with the true K recovers the labeled solution on five separable letters (observed: |KL| < 1e-10)
    assert (np.abs(col["KL EM mean"]) < 1e-3).all(), col["KL EM mean"]
    # about one component per letter (observed: exactly 5 at every count)
    assert ((col["components mean"] >= 4) & (col["components mean"] <= 6)).all(), col["components mean"]
    header, rows = _rows(out / "components.csv")
    fractions = np.array([float(x) for x in rows[0][1:]])
    assert ((fractions >= 0) & (fractions <= 1)).all() and abs(fractions.sum() - 1) < 1e-9
    for key in ("kl_vs_samples", "library_growth", "components_hist"):
        data = (out / f"{key}.png").read_bytes()
        assert data[:8] == PNG_MAGIC and len(data) > 5000, key
    summary = json.loads((out / "summary.json").read_text())
    assert summary["settings"]["trials"] == 4 and len(summary["kl_incremental_mean"]) == 7
    assert "## kl_vs_samples" in capsys.readouterr().out
