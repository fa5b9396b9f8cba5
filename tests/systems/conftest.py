"""Fixtures for the systems tests: a small library from synthetic 3-D human + 7-joint robot demos."""
import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary
from synthetic import WORKSPACE, synthetic_demo


@pytest.fixture(scope="session")
def library() -> SkillLibrary:
    """Four synthetic skills, four demonstrations each (seeded)."""
    rng = np.random.default_rng(0)
    lib = SkillLibrary(LibraryConfig())
    for rep in range(4):
        for task in range(4):
            lib.partial_fit(synthetic_demo(task, rng), workspace=WORKSPACE)
    return lib


@pytest.fixture
def demo():
    """A held-out demonstration of synthetic skill 1."""
    return synthetic_demo(1, np.random.default_rng(123))
