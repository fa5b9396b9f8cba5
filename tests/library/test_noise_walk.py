"""The library walks a human motion with its own ``adapt_to_noise``, in learning and in recognition."""
import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.data.demonstration import Demonstration
from drake_skills.promp.preprocessing import vertex_path

from synthetic import synthetic_demo


def _noisy(task, rng, sigma):
    d = synthetic_demo(task, rng)
    return Demonstration(t=d.t, human=d.human + rng.normal(0, sigma, d.human.shape), robot=d.robot, task=d.task,
                         name=d.name)


@pytest.mark.parametrize("adapt", [True, False])
def test_learning_and_recognition_walk_the_motion_as_the_config_says(adapt):
    """Noise of 3 tolerances (0.3 normalized units) on a synthetic reach: the adapted and the plain walk differ
    by more than 2x in length, and the library's path (recognition) and its component's path length (learning,
    one demonstration) are the walk of its own setting to 1e-12."""
    rng = np.random.default_rng(0)
    cfg = LibraryConfig(adapt_to_noise=adapt)
    d = _noisy(0, rng, 3 * cfg.resample_tolerance)
    y = d.human - d.human[0]
    lengths = {a: vertex_path(y, cfg.resample_tolerance, adapt_to_noise=a)[2][-1] for a in (True, False)}
    assert lengths[False] > 2 * lengths[True]
    lib = SkillLibrary(cfg)
    assert lib.path_length(d.human) == pytest.approx(lengths[adapt], rel=1e-12)
    lib.partial_fit(d)
    assert lib.components[0].path_length == pytest.approx(lengths[adapt], rel=1e-12)


def test_positions_too_large_for_the_noise_check_are_refused_clearly_and_leave_the_library_as_it_was():
    rng = np.random.default_rng(1)
    lib = SkillLibrary(LibraryConfig())
    lib.partial_fit(synthetic_demo(0, rng))
    before = lib.state()
    d = _noisy(1, rng, 0.3)
    huge = Demonstration(t=d.t, human=1e155 * d.human, robot=d.robot, task=d.task, name="huge")
    with pytest.raises(ValueError, match="too large"):
        lib.partial_fit(huge)
    with pytest.raises(ValueError, match="too large"):
        lib.recognize(huge.human)
    after = lib.state()
    assert after.n_seen == before.n_seen and len(after.components) == len(before.components)
    np.testing.assert_array_equal(after.components[0].cluster.mean, before.components[0].cluster.mean)


def test_a_glitch_on_the_first_sample_does_not_offset_the_motion_it_starts():
    """Eq. (14) subtracts the first sample: a first sample 2 units off (a tracker's glitch) would shift every
    weight by it. The library replaces it first, so the glitched motion is recognized as the clean one (d^2 to
    each component within 5 %; without the replacement it is unknown to all)."""
    rng = np.random.default_rng(2)
    lib = SkillLibrary(LibraryConfig())
    for k in range(9):
        lib.partial_fit(synthetic_demo(k % 3, rng))
    d = synthetic_demo(1, rng)
    g = d.human.copy()
    g[0] += np.array([2.0, 0.0, 0.0])
    clean, glitched = lib.recognize(d.human, observed_fraction=1.0), lib.recognize(g, observed_fraction=1.0)
    assert glitched.status == clean.status == "skill" and glitched.component == clean.component
    np.testing.assert_allclose(glitched.mahalanobis_sq, clean.mahalanobis_sq, rtol=0.05)
    rng = np.random.default_rng(2)
    plain = SkillLibrary(LibraryConfig(adapt_to_noise=False))
    for k in range(9):
        plain.partial_fit(synthetic_demo(k % 3, rng))
    assert plain.recognize(g, observed_fraction=1.0).status == "unknown"
