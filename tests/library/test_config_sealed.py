import re
"""A library's settings cannot change under it: its novelty rule and caches are built from them."""
import dataclasses

import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary

from synthetic import synthetic_demo


def _taught(config):
    lib = SkillLibrary(config)
    rng = np.random.default_rng(0)
    for task in (0, 1, 2, 0, 1, 2):
        lib.partial_fit(synthetic_demo(task, rng))
    return lib


def test_assigning_a_field_of_a_librarys_config_raises_and_changes_nothing():
    lib = _taught(LibraryConfig())
    probe = synthetic_demo(1, np.random.default_rng(5)).human
    before = lib.recognize(probe, observed_fraction=1.0)
    with pytest.raises(AttributeError, match=r"^LibraryConfig\.novelty_quantile of a SkillLibrary cannot change: "
                                             r".*SkillLibrary\(dataclasses\.replace\(lib\.config, "
                                             r"novelty_quantile=\.\.\.\)\)"):
        lib.config.novelty_quantile = 0.5
    assert lib.config.novelty_quantile == LibraryConfig().novelty_quantile
    after = lib.recognize(probe, observed_fraction=1.0)
    assert (after.status, after.component) == (before.status, before.component)
    np.testing.assert_array_equal(after.posterior, before.posterior)


def test_the_callers_config_stays_changeable_and_its_later_changes_do_not_reach_the_library():
    mine = LibraryConfig()
    lib = SkillLibrary(mine)
    mine.ridge = 0.5  # the caller's object is not the library's
    assert lib.config.ridge == LibraryConfig().ridge and lib.config is not mine
    assert lib.config == LibraryConfig() and lib.config.dict() == LibraryConfig().dict()
    other = dataclasses.replace(lib.config, decision_risk=0.2)  # a replace is an ordinary config
    other.decision_risk = 0.1
    assert other.decision_risk == 0.1 and SkillLibrary(other).config.decision_risk == 0.1


def test_a_loaded_or_copied_library_keeps_a_sealed_config(tmp_path):
    lib = _taught(LibraryConfig())
    back = SkillLibrary.load(lib.save(tmp_path / "lib.npz"))
    for other in (back, SkillLibrary.from_state(lib.state())):
        assert other.config == lib.config
        with pytest.raises(AttributeError, match="cannot change"):
            other.config.ridge = 1.0


def test_a_sealed_config_refuses_deletion_and_seals_once():
    lib = SkillLibrary()
    with pytest.raises(AttributeError, match=r"^LibraryConfig\.ridge of a SkillLibrary cannot change"):
        del lib.config.ridge
    assert lib.config.ridge == LibraryConfig().ridge
    assert lib.config.sealed() is lib.config and SkillLibrary(lib.config).config is lib.config


def test_a_librarys_config_writes_as_yaml_and_serves_as_the_defaults_of_a_config_file(tmp_path):
    """The paths that copy a config and then assign its fields (the YAML writer, Drake's YAML loader with
    defaults) start from changeable copies, so a library's sealed config works there."""
    from drake_skills.sim.config import SimConfig, load_config
    from drake_skills.tuning import write_config_yaml

    from synthetic import WORKSPACE

    lib = SkillLibrary(LibraryConfig(workspace=WORKSPACE, ridge=0.02))
    back = load_config(write_config_yaml(lib.config, tmp_path / "lib.yaml")).library
    assert back.dict() == lib.config.dict()
    (tmp_path / "sim.yaml").write_text("library:\n  decision_risk: 0.02\n")
    (tmp_path / "only_lib.yaml").write_text("decision_risk: 0.03\n")
    for name, risk in (("sim.yaml", 0.02), ("only_lib.yaml", 0.03)):
        got = load_config(tmp_path / name, defaults=SimConfig(library=lib.config)).library
        assert got.decision_risk == risk and got.ridge == 0.02 and got.workspace.dict() == WORKSPACE.dict()
    assert lib.config.decision_risk == LibraryConfig().decision_risk


def test_a_changeable_config_deletes_a_field_back_to_its_default():
    cfg = LibraryConfig(ridge=0.5)
    del cfg.ridge  # an ordinary dataclass: the class default shows through
    assert "ridge" not in vars(cfg) and cfg.ridge == LibraryConfig().ridge


@pytest.mark.parametrize("field, value", [("prior_scale", "0.3"), ("ridge", None), ("shrinkage", True),
                                          ("novelty_quantile", [0.999]), ("log_T_nov", "low")])
def test_a_setting_that_is_not_a_number_is_an_error_naming_it(field, value):
    """Before, text reached numpy and came back as "ufunc 'isfinite' not supported" (a cold review)."""
    with pytest.raises(ValueError, match=re.escape(f"LibraryConfig.{field} must be a number, got {value!r}")):
        LibraryConfig(**{field: value})
