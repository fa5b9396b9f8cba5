"""The evaluation cuts a noisy motion's prefixes where the library's own walk of them reaches the fraction."""
import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.data.workspace import Workspace
from drake_skills.evaluation.interaction import prefix_end
from drake_skills.evaluation.salad_personal import observed_prefix

from synthetic import synthetic_demo


@pytest.fixture(scope="module")
def noisy():
    """A synthetic reach of 600 samples in metres with 2 cm of white noise in a 1 m box: 2 tolerances of noise."""
    rng = np.random.default_rng(1)
    d = synthetic_demo(1, rng, T=600)
    human = 0.1 * d.human + rng.normal(0, 0.02, d.human.shape)
    ws = Workspace(human.min(axis=0) - 0.5, human.min(axis=0) + 0.5)
    return human, ws


@pytest.mark.parametrize("fraction", [0.2, 0.5, 0.8])
def test_prefix_end_and_observed_prefix_give_the_fraction_the_library_measures(noisy, fraction):
    """The library walks the prefix with its own noise estimate: its length over the whole's is the fraction
    asked or just above (measured 0.2125, 0.5158, 0.8138; asserted within 0.02: a step of this walk, whose
    tolerance has grown to 2.5 base tolerances (0.25 units) for the noise, is 3 % of its 8.3 units, and with
    ``average_holds`` a prefix one sample longer can measure a little less, its last vertex a mean). Cut on the
    whole motion's walk instead, as before, the library measured 0.316, 0.589 and 0.816."""
    human, ws = noisy
    lib = SkillLibrary(LibraryConfig(workspace=ws))
    whole = lib.path_length(human)
    m = prefix_end(human, ws, fraction, lib.config.resample_tolerance)
    share = lib.path_length(human[:m]) / whole
    assert fraction * (1 - 1e-9) <= share <= fraction + 0.02
    p = observed_prefix(human, fraction, ws, lib.config.resample_tolerance)
    assert fraction * (1 - 1e-9) <= lib.path_length(p) / whole <= fraction + 0.02
    # the defaults of both are the library's default (adapt_to_noise on)
    assert m == prefix_end(human, ws, fraction, lib.config.resample_tolerance, adapt_to_noise=True)


@pytest.mark.parametrize("fraction", [0.2, 0.5, 0.8])
def test_a_library_that_walks_with_vertices_at_samples_gets_its_prefixes_cut_by_its_own_walk(noisy, fraction):
    """``average_holds=False`` (a library file written before it): prefix_end and observed_prefix given the
    library's setting cut where that library's walk reaches the fraction (within 0.02), where the default walk's
    cut gave it 0.296 / 0.523 / 0.761 (a cold review: 0.761 is below the fraction asked)."""
    human, ws = noisy
    lib = SkillLibrary(LibraryConfig(workspace=ws, average_holds=False))
    tol = lib.config.resample_tolerance
    whole = lib.path_length(human)
    m = prefix_end(human, ws, fraction, tol, average_holds=False)
    assert fraction * (1 - 1e-9) <= lib.path_length(human[:m]) / whole <= fraction + 0.02
    p = observed_prefix(human, fraction, ws, tol, average_holds=False)
    assert fraction * (1 - 1e-9) <= lib.path_length(p) / whole <= fraction + 0.02
