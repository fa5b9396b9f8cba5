"""The LCM commands: demo --transport lcm writes the same artifacts; control fails clearly on a silent bus.

Only the in-process bus memq:// is used.
"""
import json

import pytest

from drake_skills import SkillLibrary
from drake_skills.cli import main


def test_demo_over_lcm_writes_summary_library_and_recording(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--transport", "lcm", "--quick", "--trials", "1", "--lcm-latency", "0.01",
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["transport"] == "lcm" and summary["lcm"]["url"] == "memq://"
    assert summary["lcm"]["latency"] == 0.01 and summary["trials"] == 1
    assert summary["unknown"] == 1 and summary["within_limits"]  # an empty library answers unknown
    assert SkillLibrary.load(out / "library.npz").n_components >= 1
    assert (out / "demo.html").stat().st_size > 100_000
    assert "over LCM (memq://)" in capsys.readouterr().out


def test_lcm_options_need_the_lcm_transport(tmp_path, capsys):
    assert main(["demo", "--lcm-url", "memq://", "--out", str(tmp_path)]) == 1
    assert "need --transport lcm" in capsys.readouterr().err


def test_control_on_a_silent_bus_says_which_channels_are_silent(tmp_path, capsys):
    lib = tmp_path / "lib.npz"
    SkillLibrary().save(lib)
    code = main(["control", "--library", str(lib), "--subject", "1", "--lcm-url", "memq://", "--wait", "0.1",
                 "--out", str(tmp_path / "control")])
    err = capsys.readouterr().err
    assert code == 1
    assert "no message within 0.1 s on 'IIWA_STATUS' (lcmt_iiwa_status), 'DRAKE_SKILLS_WRIST'" in err


def test_control_needs_a_workspace_and_an_existing_library(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["control", "--library", str(tmp_path / "missing.npz"), "--subject", "1"])
    assert exc.value.code == 2 and "is not a file" in capsys.readouterr().err
    lib = tmp_path / "lib.npz"
    SkillLibrary().save(lib)
    with pytest.raises(SystemExit):
        main(["control", "--library", str(lib)])  # neither --calibration nor --subject
