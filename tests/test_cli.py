"""The command line: --help everywhere, learn -> recognize on a generated dataset, clear errors."""
import json
import shutil

import numpy as np
import pytest

from drake_skills import SkillLibrary
from drake_skills.cli import build_parser, main
from drake_skills.data.demos import load_demo, save_npz
from drake_skills.scenario.salad import TASKS


COMMANDS = ["demo", "learn", "recognize", "generate", "plot-demos", "eval", "bench"]


def test_parser_has_the_design_commands():
    import argparse

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    assert set(COMMANDS) <= set(sub.choices)


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_has_help(command, capsys):
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args([command, "--help"])
    assert exc.value.code == 0
    assert "usage: drake-skills" in capsys.readouterr().out


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """Subject 1, 4 demos per task: 3 per task to learn from, the 4th held out (with the calibration)."""
    root = tmp_path_factory.mktemp("cli")
    assert main(["generate", "salad", "--subjects", "1", "--demos", "4", "--out", str(root / "all")]) == 0
    subject = root / "all" / "subject1"
    train, held = root / "train" / "subject1", root / "held"
    train.mkdir(parents=True)
    held.mkdir()
    for f in sorted(subject.iterdir()):
        if f.name.endswith("_03.npz"):
            shutil.copy(f, held / f.name)
        elif f.suffix == ".npz":
            shutil.copy(f, train / f.name)
    shutil.copy(subject / "calibration.npz", held / "calibration.npz")
    return root


def test_learn_then_recognize_held_out_demonstrations(dataset, capsys):
    lib_path = dataset / "lib.npz"
    assert main(["learn", str(dataset / "train"), "--out", str(lib_path)]) == 0
    lib = SkillLibrary.load(lib_path)
    summary = json.loads(lib_path.with_suffix(".json").read_text())
    assert summary["n_demos"] == 3 * len(TASKS) and summary["n_components"] == lib.n_components
    assert lib.n_components == len(TASKS)  # one skill per task for this subject
    components = {}
    for task in TASKS:
        demo_file = dataset / "held" / f"{task}_03.npz"
        out = dataset / "rec" / task
        assert main(["recognize", str(lib_path), str(demo_file), "--out", str(out)]) == 0
        rec = json.loads((out / "recognition.json").read_text())
        assert rec["component"] is not None, f"{task} held out: unknown"
        components[task] = rec["component"]
        pred = np.load(out / "prediction.npz", allow_pickle=False)
        demo = load_demo(demo_file)
        # the conditioned final pose is close to the held-out demonstration's (observed: < 0.05 rad)
        assert np.abs(pred["robot_mean"][-1] - demo.robot[-1]).max() < 0.15, task
    assert len(set(components.values())) == len(TASKS)  # five different skills
    assert "component" in capsys.readouterr().out


def test_learn_rejects_a_bad_file_naming_it_and_writes_nothing(dataset, tmp_path, capsys):
    bad_dir = tmp_path / "demos"
    shutil.copytree(dataset / "train" / "subject1", bad_dir)
    demo = load_demo(bad_dir / "bowl_00.npz")
    human = demo.human.copy()
    human[12:15] = np.nan
    np.savez(bad_dir / "broken.npz", t=demo.t, human=human, robot=demo.robot)
    out = tmp_path / "lib.npz"
    assert main(["learn", str(bad_dir), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "broken.npz" in err and "NaN" in err, err
    assert not out.exists()


def test_recognize_rejects_a_truncated_library(dataset, tmp_path, capsys):
    lib_path = dataset / "lib.npz"
    if not lib_path.exists():
        assert main(["learn", str(dataset / "train"), "--out", str(lib_path)]) == 0
    bad = tmp_path / "truncated.npz"
    bad.write_bytes(lib_path.read_bytes()[:300])
    assert main(["recognize", str(bad), str(dataset / "held" / "bowl_03.npz"), "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "truncated.npz" in err and "truncated" in err, err


def test_learn_extends_an_existing_library(dataset, tmp_path):
    first = tmp_path / "first.npz"
    assert main(["learn", str(dataset / "train"), "--out", str(first), "--in-order"]) == 0
    more = tmp_path / "more"
    more.mkdir()
    save_npz(load_demo(dataset / "held" / "tomato_03.npz"), more / "tomato_03.npz")
    second = tmp_path / "second.npz"
    assert main(["learn", str(more), "--library", str(first), "--out", str(second)]) == 0
    a, b = SkillLibrary.load(first), SkillLibrary.load(second)
    assert b.n_seen == a.n_seen + 1 and b.n_components >= a.n_components


def test_missing_directory_is_a_clear_error(tmp_path, capsys):
    assert main(["learn", str(tmp_path / "nope")]) == 1
    assert "does not exist" in capsys.readouterr().err


LIBRARY_COMMANDS = [["demo"], ["learn", "DIR"], ["bench"], ["eval", "letters"], ["eval", "salad"],
                    ["eval", "sensitivity"], ["eval", "scale"]]


@pytest.mark.parametrize("command", LIBRARY_COMMANDS, ids=lambda c: " ".join(c[:2]))
def test_every_command_that_builds_a_library_takes_a_config(command, capsys):
    args = build_parser().parse_args(command + ["--config", "c.yaml"])
    assert str(args.config) == "c.yaml"
    with pytest.raises(SystemExit):
        build_parser().parse_args(command + ["--help"])
    assert "LibraryConfig" in capsys.readouterr().out.replace("\n", " ")


def test_learn_reads_the_library_part_of_a_sim_config(dataset, tmp_path):
    cfg = tmp_path / "sim.yaml"
    cfg.write_text("seed: 5\nlibrary:\n  n_basis_robot: 12\n  prior_scale: 0.25\n")
    out = tmp_path / "lib.npz"
    assert main(["learn", str(dataset / "train"), "--out", str(out), "--config", str(cfg)]) == 0
    config = SkillLibrary.load(out).config
    assert config.n_basis_robot == 12 and config.prior_scale == 0.25


def test_a_bad_config_is_an_error_naming_the_file(dataset, tmp_path, capsys):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text("library:\n  ridge: -1\n")
    assert main(["learn", str(dataset / "train"), "--out", str(tmp_path / "x.npz"), "--config", str(cfg)]) == 1
    err = capsys.readouterr().err
    assert "bad.yaml" in err and "ridge" in err, err


def test_a_command_that_fails_to_import_is_a_loud_error(monkeypatch):
    import drake_skills.cli as cli

    monkeypatch.setattr(cli, "COMMAND_MODULES", cli.COMMAND_MODULES + ["no_such_command"])
    with pytest.raises(RuntimeError, match="drake_skills.commands.no_such_command failed to import"):
        cli.build_parser()
