"""One config tree: SimConfig -> LibraryConfig, DecisionRule, read with Drake's yaml_load_typed and validated."""
import numpy as np
import pytest

from drake_skills import LibraryConfig
from drake_skills.data.workspace import Workspace
from drake_skills.sim.config import SimConfig, load_config, load_library_config
from drake_skills.systems.decision_rule import DecisionRule


def _write(tmp_path, text, name="cfg.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_sim_config_file_sets_the_library_and_the_decision_rule(tmp_path):
    p = _write(tmp_path, """
seed: 3
library:
  n_basis_human: 8
  novelty_test: loglik
  workspace: {lower: [0.0, -1.0, 0.5], upper: [1.0, 1.0, 1.5]}
decision:
  timeout: 4.0
  decision_time: 1.5
""")
    cfg = load_config(p)
    assert cfg.seed == 3 and cfg.trials == SimConfig().trials
    assert isinstance(cfg.library, LibraryConfig) and cfg.library.n_basis_human == 8
    assert cfg.library.novelty_test == "loglik" and cfg.library.ridge == LibraryConfig().ridge
    assert isinstance(cfg.library.workspace, Workspace)
    np.testing.assert_array_equal(cfg.library.workspace.upper, [1.0, 1.0, 1.5])
    assert cfg.decision == DecisionRule(timeout=4.0, decision_time=1.5)


def test_a_file_of_library_fields_alone_is_the_library_config(tmp_path):
    p = _write(tmp_path, "prior_scale: 0.4\nprior_floor: 0.2\n")
    assert load_library_config(p) == LibraryConfig(prior_scale=0.4, prior_floor=0.2)
    assert load_config(p).seed == 0
    assert load_config(None) == SimConfig()


@pytest.mark.parametrize("text, message", [
    ("library:\n  prior_scale: -1.0\n", "prior_scale must be positive"),
    ("decision:\n  timeout: 0.0\n", "timeout must be positive"),
    ("trials: 0\n", "trials"),
    ("library:\n  novelty_test: magic\n", "novelty_test"),
    ("library:\n  workspace: {lower: [0.0], upper: [0.0]}\n", "empty along axes"),
    ("seed: 1\nprior_scale: 0.5\n", "under 'library:'"),
    ("library:\n  n_basis: 3\n", "n_basis"),
    ("- 1\n- 2\n", "not a mapping"),
    ("library:\n  workspace: {lower: [], upper: []}\n", "too short"),
    ("subject_model: stylish\n", "subject_model must be one of"),
    # a cold review ran these to a crash inside Drake or to the end with nonsense figures
    ("controller:\n  kp: -100.0\n", "ControllerConfig.kp must be positive"),
    ("controller:\n  ki: .nan\n", "ControllerConfig.ki must be >= 0"),
    ("time_step: .inf\n", "SimConfig.time_step must be positive and finite"),
    ("log_period: .inf\n", "SimConfig.log_period must be positive and finite"),
    ("meshcat:\n  publish_period: -1.0\n", "MeshcatConfig.publish_period must be positive"),
    ("meshcat:\n  camera_target: [0.0, 1.0]\n", "MeshcatConfig.camera_target must be three finite numbers"),
    # not YAML at all: a clean error, not the parser's traceback (found by a cold review)
    (": : bad yaml [\n", "is not valid YAML: .*line 1"),
    ("ridge: 0.1\n\tn_samples: 5\n", "is not valid YAML: .*'\\\\t'"),
    ("library:\n  ridge: [1, 2\n", "is not valid YAML"),
    # a section or a value of the wrong kind: Drake's loader stops with a bare AssertionError (a cold review)
    ("workspace: 5\n", "'workspace' must be a mapping of WorkspaceBounds fields, got 5"),
    ("library: 5\n", "'library' must be a mapping of LibraryConfig fields"),
    ("decision: 3\n", "'decision' must be a mapping of DecisionRule fields"),
    ("lcm: x\n", "'lcm' must be a mapping of LcmConfig fields"),
    ("faults: [1]\n", "'faults' must be a mapping of TrackerFaults fields"),
    ("prior_scale: abc\n", "'prior_scale' must be a number, got 'abc'"),
    ("decision: {end_phase: x}\n", "'decision.end_phase' must be a number"),
    ("n_basis_robot: twenty\n", "'n_basis_robot' must be an integer"),
    ("trials: 3.5\n", "'trials' must be an integer, got 3.5"),
    ("library:\n  adapt_to_noise: 3\n", "'library.adapt_to_noise' must be true or false"),
    ("subject_model: 3\n", "'subject_model' must be text"),
    ("library:\n  ridge:\n", "'library.ridge' has no value"),
    ("", "the file is empty"),
    ("meshcat:\n  camera_position: 5\n", "'meshcat.camera_position' must be a list, got 5"),
    ("library:\n  workspace: {lower: 0, upper: [1, 1, 1]}\n", "'library.workspace.lower' must be a list"),
    ("n_steps: 100.5\n", "'n_steps' must be an integer, got 100.5"),
])
def test_bad_settings_are_errors_naming_the_file_and_the_field(tmp_path, text, message):
    p = _write(tmp_path, text, "bad.yaml")
    with pytest.raises(ValueError, match=message) as e:
        load_config(p)
    assert "bad.yaml" in str(e.value)


def test_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.yaml' does not exist"):
        load_config(tmp_path / "nope.yaml")
    with pytest.raises(FileNotFoundError, match=f"config '{tmp_path}' is a directory, not a YAML file"):
        load_config(tmp_path)


def test_the_library_file_keeps_a_config_read_from_yaml(tmp_path):
    from drake_skills import SkillLibrary
    from synthetic import synthetic_demo

    text = "n_basis_robot: 12\nworkspace: {lower: [-8, -8, -8], upper: [8, 8, 8]}\n"
    cfg = load_library_config(_write(tmp_path, text))
    lib = SkillLibrary(cfg)
    lib.partial_fit(synthetic_demo(0, np.random.default_rng(0)))
    back = SkillLibrary.load(lib.save(tmp_path / "lib.npz")).config
    assert back.n_basis_robot == 12 and back.workspace.dict() == cfg.workspace.dict()


def test_numbers_written_as_text_that_the_loader_reads_stay_numbers(tmp_path):
    """YAML 1.1 reads 1e-9 as text; Drake's loader makes it the number, and the shape check lets it through."""
    p = _write(tmp_path, "novelty_quantile: 1e-9\nn_samples: '50'\n", "ok.yaml")
    cfg = load_config(p).library
    assert cfg.novelty_quantile == 1e-9 and cfg.n_samples == 50
    # what loaded before the shape check still loads: a whole float for an integer, a quoted boolean
    p = _write(tmp_path, "n_steps: 100.0\nrobot_scene_contact: 'true'\ndecision:\n  confirmations: 2.0\n", "ok2.yaml")
    c = load_config(p)
    assert c.n_steps == 100 and c.robot_scene_contact is True and c.decision.confirmations == 2


def test_every_field_of_every_section_loads_from_yaml(tmp_path):
    """Each scalar field of each SimConfig section, written with its default value, loads back (a module with
    ``from __future__ import annotations`` hides its field types from Drake's loader: `wrist:` could not be read
    at all, a cold review found)."""
    import dataclasses
    import typing

    from drake_skills.sim.config import SimConfig

    checked = 0
    for section in dataclasses.fields(SimConfig):
        default = getattr(SimConfig(), section.name)
        if not dataclasses.is_dataclass(default):
            continue
        hints = typing.get_type_hints(type(default))
        for f in dataclasses.fields(default):
            value = getattr(default, f.name)
            if hints[f.name] not in (int, float, bool, str) or isinstance(value, str) and not value:
                continue
            text = str(value).lower() if isinstance(value, bool) else repr(value)
            p = _write(tmp_path, f"{section.name}:\n  {f.name}: {text}\n", f"{section.name}_{f.name}.yaml")
            loaded = getattr(load_config(p), section.name)
            assert getattr(loaded, f.name) == value, (section.name, f.name)
            checked += 1
    assert checked >= 40
