"""The path walk adapts to a tracker's noise (``adapt_to_noise``) and leaves clean motions alone."""
import numpy as np
import pytest

from drake_skills.promp.preprocessing import NOISE_SHARE, arc_length, noise_level, vertex_path

TOL = 0.1


def _helix(n=500):
    u = np.linspace(0, 2 * np.pi, n)
    return np.stack([3 * np.cos(u), 3 * np.sin(u), 0.5 * u], axis=1)


@pytest.mark.parametrize("sigma", [0.02, 0.05, 0.2])
def test_noise_level_reads_white_noise_within_15_percent(sigma):
    y = _helix() + np.random.default_rng(0).normal(0, sigma, (500, 3))
    assert noise_level(y) == pytest.approx(sigma, rel=0.15)


def test_noise_level_of_a_clean_motion_is_far_below_the_tolerance_and_repeats_add_nothing():
    assert noise_level(_helix()) < 0.01 * TOL
    y = _helix() + np.random.default_rng(1).normal(0, 0.05, (500, 3))
    held = np.repeat(y, 3, axis=0)                       # a tracker that repeats each frame twice
    assert noise_level(held) == noise_level(y)
    assert noise_level(y[:4]) == 0.0                     # too few samples to tell
    assert noise_level(np.ones((50, 3))) == 0.0


def test_below_the_share_the_walk_is_exactly_the_plain_one():
    y = _helix() + np.random.default_rng(2).normal(0, 0.5 * NOISE_SHARE * TOL, (500, 3))
    plain, adapted = vertex_path(y, TOL), vertex_path(y, TOL, adapt_to_noise=True)
    for a, b in zip(plain, adapted):
        np.testing.assert_array_equal(a, b)
    # tolerance 0 (the paper's raw arc length) never adapts, whatever the noise
    y = _helix() + np.random.default_rng(3).normal(0, 1.0, (500, 3))
    for a, b in zip(vertex_path(y, 0.0), vertex_path(y, 0.0, adapt_to_noise=True)):
        np.testing.assert_array_equal(a, b)


def test_noise_twice_the_tolerance_no_longer_makes_the_path_or_the_hold_long():
    """Noise of 2 tolerances on a helix (true length 19.1) followed by a hold of 300 samples.

    The plain walk counts nearly every sample: 217 units by the end of the motion, 140 more in
    the hold. Adapted (smoothed over 2 samples, tolerance 1 / NOISE_SHARE times the noise left)
    it measures 22.7 at the end of the motion and the hold adds 3.3: asserted within 1.3x and
    0.35x of the true length.
    """
    y = _helix()
    true_length = arc_length(y, TOL)[1][-1]
    held = np.vstack([y, np.repeat(y[-1:], 300, axis=0)])
    noisy = held + np.random.default_rng(0).normal(0, 2 * TOL, held.shape)
    for adapt, motion_max, hold_max in ((False, None, None), (True, 1.3, 0.35)):
        idx, v, s = vertex_path(noisy, TOL, adapt_to_noise=adapt)
        at_end = s[np.searchsorted(idx, len(y)) - 1]
        if adapt:
            assert at_end < motion_max * true_length and s[-1] - at_end < hold_max * true_length
            assert len(idx) == len(v) == len(s) and idx[0] == 0 and np.all(np.diff(idx) > 0)
        else:
            assert at_end > 10 * true_length and s[-1] - at_end > 5 * true_length
