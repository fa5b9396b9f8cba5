"""The command line: --help everywhere, learn -> recognize on a generated dataset, clear errors."""
import json
import shutil

import numpy as np
import pytest

from drake_skills import SkillLibrary
from drake_skills.cli import build_parser, main
from drake_skills.data.demos import load_demo, save_npz
from drake_skills.data.salad import TASKS


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


@pytest.fixture(scope="module")
def learned(dataset):
    """The library learned from the training demonstrations (learned once for the tests below)."""
    lib_path = dataset / "lib.npz"
    if not lib_path.exists():
        assert main(["learn", str(dataset / "train"), "--out", str(lib_path)]) == 0
    return lib_path


def test_main_without_a_command_prints_help_and_returns_2(capsys):
    assert main([]) == 2
    out = capsys.readouterr().out
    assert out.startswith("usage: drake-skills") and "learn" in out and "recognize" in out


def test_learn_on_an_empty_directory_is_a_clear_error(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("no demonstrations here")
    out = tmp_path / "lib.npz"
    assert main(["learn", str(tmp_path / "empty"), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert f"drake-skills learn: error: no demonstrations (.npz or .csv) found under '{tmp_path / 'empty'}'" in err
    assert not out.exists()


def test_learn_config_sets_the_new_librarys_hyperparameters(dataset, tmp_path, capsys):
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("n_basis_human: 6\nsigma_init_human: 0.4\nnovelty_test: loglik\n")
    out = tmp_path / "lib.npz"
    assert main(["learn", str(dataset / "train"), "--out", str(out), "--config", str(cfg), "--in-order"]) == 0
    lib = SkillLibrary.load(out)
    assert (lib.config.n_basis_human, lib.config.sigma_init_human, lib.config.novelty_test) == (6, 0.4, "loglik")
    assert lib.n_human == 18 and lib.n_seen == 3 * len(TASKS)
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["n_demos"] == 3 * len(TASKS) and summary["created"] >= lib.n_components
    assert f"wrote {out}" in capsys.readouterr().out
    empty_cfg = tmp_path / "empty.yaml"
    empty_cfg.write_text("")  # an empty file is the default configuration
    assert main(["learn", str(dataset / "train"), "--out", str(tmp_path / "b.npz"), "--config", str(empty_cfg)]) == 0
    assert SkillLibrary.load(tmp_path / "b.npz").config == SkillLibrary().config


def test_learn_rejects_a_config_for_an_existing_library_and_unknown_fields(dataset, learned, tmp_path, capsys):
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("n_basis_human: 6\n")
    assert main(["learn", str(dataset / "train"), "--library", str(learned), "--config", str(cfg),
                 "--out", str(tmp_path / "x.npz")]) == 1
    assert ("--config applies to a new library only; the existing library keeps its own"
            in capsys.readouterr().err)
    cfg.write_text("magic: 1\n")
    assert main(["learn", str(dataset / "train"), "--config", str(cfg), "--out", str(tmp_path / "x.npz")]) == 1
    assert "unknown LibraryConfig fields: ['magic']" in capsys.readouterr().err
    assert not (tmp_path / "x.npz").exists()


def test_recognize_a_prefix_with_fraction(dataset, learned, capsys):
    out = dataset / "rec_prefix"
    demo_file = dataset / "held" / "board_03.npz"
    assert main(["recognize", str(learned), str(demo_file), "--fraction", "0.5", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    rec = json.loads((out / "recognition.json").read_text())
    lib = SkillLibrary.load(learned)
    assert rec["ids"] == [c.id for c in lib.components] and len(rec["responsibilities"]) == lib.n_components
    assert "(dof 150)" in printed  # half of the 100 samples, 3-D: the prefix was compared, not the whole motion
    assert (out / "prediction.npz").exists() == (rec["component"] is not None)


def test_recognize_with_an_explicit_calibration_equals_the_one_found_beside_the_demo(dataset, learned, tmp_path):
    lonely = tmp_path / "lonely"
    lonely.mkdir()
    shutil.copy(dataset / "held" / "bowl_03.npz", lonely / "bowl_03.npz")
    assert main(["recognize", str(learned), str(dataset / "held" / "bowl_03.npz"), "--out", str(tmp_path / "a")]) == 0
    assert main(["recognize", str(learned), str(lonely / "bowl_03.npz"), "--out", str(tmp_path / "b"),
                 "--calibration", str(dataset / "held" / "calibration.npz")]) == 0
    a = json.loads((tmp_path / "a" / "recognition.json").read_text())
    b = json.loads((tmp_path / "b" / "recognition.json").read_text())
    assert a["component"] is not None and a["component"] == b["component"]
    np.testing.assert_allclose(a["mahalanobis_sq"], b["mahalanobis_sq"], rtol=1e-12)
    # without the subject's workspace the raw metres are compared with normalized skills: another answer
    assert main(["recognize", str(learned), str(lonely / "bowl_03.npz"), "--out", str(tmp_path / "c")]) == 0
    c = json.loads((tmp_path / "c" / "recognition.json").read_text())
    assert not np.allclose(c["mahalanobis_sq"], a["mahalanobis_sq"], rtol=0.1)


def test_recognize_of_an_untaught_task_says_unknown_and_predicts_nothing(dataset, tmp_path, capsys):
    part = tmp_path / "part" / "subject1"
    part.mkdir(parents=True)
    for f in sorted((dataset / "train" / "subject1").iterdir()):
        if not f.name.startswith("standup"):
            shutil.copy(f, part / f.name)
    lib_path = tmp_path / "part.npz"
    assert main(["learn", str(tmp_path / "part"), "--out", str(lib_path)]) == 0
    capsys.readouterr()
    out = tmp_path / "rec"
    assert main(["recognize", str(lib_path), str(dataset / "held" / "standup_03.npz"), "--out", str(out)]) == 0
    assert "unknown (ask for a demonstration)" in capsys.readouterr().out
    rec = json.loads((out / "recognition.json").read_text())
    assert rec["component"] is None and len(rec["ids"]) == len(TASKS) - 1
    assert not (out / "prediction.npz").exists()
