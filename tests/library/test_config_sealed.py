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
