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


@pytest.mark.parametrize("width", [0.3, 1.0, 2.0])
def test_the_noise_left_after_smoothing_is_the_kernels_norm(width):
    """_noise_gain is the standard deviation white noise keeps through gaussian_filter1d(width): checked on
    200000 samples (relative error of the estimate ~0.2 %), within 1 %; 2 samples keep 0.375, 1 keeps 0.53."""
    from scipy.ndimage import gaussian_filter1d

    from drake_skills.promp.preprocessing import _noise_gain

    n = np.random.default_rng(0).normal(0.0, 1.0, 200_000)
    kept = gaussian_filter1d(n, width, mode="nearest").std()
    assert _noise_gain(width) == pytest.approx(kept, rel=0.01)
    assert 0.3 < _noise_gain(2.0) < 0.4 < 0.5 < _noise_gain(1.0) < 0.6


def test_the_adapted_tolerance_keeps_the_noise_left_at_the_share():
    """Noise of 0.5 tolerance: smoothed by (0.5 / 0.3)^2 / (2 sqrt(pi)) = 0.78 samples, which leaves about 0.3 of
    the tolerance, so the tolerance stays within 10 % of itself; noise of 3 tolerances: 2 samples (the cap) leave
    1.15, walked with 1.15 / 0.3 = 3.8 tolerances. A hold of 900 samples then makes 79 and 33 vertices (the plain
    walk: 531 and 897) and 8.9 and 13.5 units of path (plain: 77 and 609): asserted at most 10 % of the hold's
    samples and a fifth of the plain walk's path. Not none: the tolerance is 3.3 times the noise left, and two
    noisy 3-D samples lie that far apart about once in ten."""
    from drake_skills.promp.preprocessing import _denoised

    rng = np.random.default_rng(4)
    for sigma, tol_min, tol_max in ((0.5, 1.0, 1.1), (3.0, 3.4, 4.2)):
        y = np.vstack([_helix(), np.repeat(_helix()[-1:], 1000, axis=0)]) + rng.normal(0, sigma * TOL, (1500, 3))
        _, tol, smoothed = _denoised(y, TOL)
        assert smoothed
        assert tol_min * TOL <= tol <= tol_max * TOL, tol / TOL
        hold = {}
        for adapt in (False, True):
            idx, _, s = vertex_path(y, TOL, adapt_to_noise=adapt)
            k = np.searchsorted(idx, 600)
            hold[adapt] = (np.sum(idx >= 600), s[-1] - s[k - 1])
        assert hold[True][0] <= 0.1 * 900 and hold[True][1] <= 0.2 * hold[False][1], hold


def test_noise_level_refuses_what_is_not_a_trajectory_and_reads_more_than_20_dimensions():
    with pytest.raises(ValueError, match="trajectory"):
        noise_level(np.full((50, 3), np.nan))
    with pytest.raises(ValueError, match="trajectory"):
        noise_level(np.arange(50.0))
    # a whole skeleton (25 joints x 3): the chi quantile comes from scipy beyond the table
    rng = np.random.default_rng(5)
    y = np.repeat(_helix(), 25, axis=1) + rng.normal(0, 0.1, (500, 75))
    assert noise_level(y) == pytest.approx(0.1, rel=0.15)


def test_held_frames_are_smoothed_as_frames_so_holding_does_not_change_the_adapted_path():
    """A tracker at a third of the rate, each frame repeated 3 times: the adapted walk of the held stream
    measures the path of the unheld frames within 5 % (the plain walk: the same path either way, 10x too long)."""
    rng = np.random.default_rng(6)
    frames = _helix(300) + rng.normal(0, 2 * TOL, (300, 3))
    held = np.repeat(frames, 3, axis=0)
    a = vertex_path(frames, TOL, adapt_to_noise=True)[2][-1]
    b = vertex_path(held, TOL, adapt_to_noise=True)[2][-1]
    assert b == pytest.approx(a, rel=0.05)
    assert vertex_path(held, TOL)[2][-1] > 5 * a


def test_a_prefix_of_a_noisy_motion_is_cut_where_its_own_walk_reaches_the_fraction():
    """prefix_samples searches the first prefix whose adapted walk covers the fraction of the whole's (the
    adapted walk is not causal); on a clean motion it is the plain walk's vertex rule, unchanged."""
    from drake_skills.promp.preprocessing import prefix_samples, walk_is_causal

    rng = np.random.default_rng(7)
    noisy = _helix() + rng.normal(0, 1.5 * TOL, (500, 3))
    whole = vertex_path(noisy, TOL, adapt_to_noise=True)[2][-1]
    assert not walk_is_causal(noisy, TOL, adapt_to_noise=True) and walk_is_causal(noisy, TOL)
    for f in (0.1, 0.3, 0.5, 0.8, 1.0):
        m = prefix_samples(noisy, f, TOL, adapt_to_noise=True)
        assert vertex_path(noisy[:m], TOL, adapt_to_noise=True)[2][-1] >= f * whole * (1 - 1e-12)
        assert vertex_path(noisy[:m - 1], TOL, adapt_to_noise=True)[2][-1] < f * whole or m == 2
    clean = _helix()
    assert walk_is_causal(clean, TOL, adapt_to_noise=True)
    idx, _, s = vertex_path(clean, TOL)
    for f in (0.1, 0.5, 0.9):
        k = int(np.searchsorted(s, f * s[-1] * (1 - 1e-12)))
        assert prefix_samples(clean, f, TOL, adapt_to_noise=True) == idx[k] + 1


def test_prefix_helpers_refuse_what_is_not_a_trajectory_and_keep_their_edges():
    from drake_skills.promp.preprocessing import prefix_samples, walk_is_causal

    for bad in (np.full((50, 3), np.nan), np.arange(50.0), np.zeros((1, 3))):
        for call in (lambda y: prefix_samples(y, 0.5, TOL, adapt_to_noise=True),
                     lambda y: walk_is_causal(y, TOL, adapt_to_noise=True)):
            with pytest.raises(ValueError, match="trajectory"):
                call(bad)
    rng = np.random.default_rng(8)
    noisy = _helix() + rng.normal(0, 1.5 * TOL, (500, 3))
    clean = _helix()
    # the shortest prefix: the searched one's walk has a length (fewer than 5 frames are too few to read the noise
    # and walk plainly; longer prefixes that stay within a tolerance of their mean have none), the plain one's is
    # up to its first vertex; the whole motion: all samples with either walk
    k = prefix_samples(noisy, 1e-9, TOL, adapt_to_noise=True)
    assert vertex_path(noisy[:k], TOL, adapt_to_noise=True)[2][-1] > 0 and k <= 20
    assert prefix_samples(clean, 1e-9, TOL, adapt_to_noise=True) == vertex_path(clean, TOL)[0][1] + 1 > 2
    for y in (noisy, clean):
        assert prefix_samples(y, 1.0, TOL, adapt_to_noise=True) == len(y)
    # tolerance 0 is the paper's raw walk, which never adapts, so it is causal whatever the noise
    assert walk_is_causal(noisy, 0.0, adapt_to_noise=True)


def test_a_motion_whose_beginning_alone_is_noisy_is_not_walked_causally():
    """30 noisy samples at rest (noise 2 tolerances), then 970 clean ones of a long slow motion: the whole
    motion's lowest decile is the clean part's (far below the share), but its prefixes of 5-20 frames read
    the noise, and the library walks such a prefix adapted, so the walk is not causal."""
    from drake_skills.promp.preprocessing import walk_is_causal

    rng = np.random.default_rng(9)
    start = rng.normal(0, 2 * TOL, (30, 3))
    y = np.vstack([start, _helix(970)])
    assert noise_level(y) < NOISE_SHARE * TOL < noise_level(y[:20])
    assert not walk_is_causal(y, TOL, adapt_to_noise=True)
    assert walk_is_causal(_helix(1000), TOL, adapt_to_noise=True)


def _glitched(y, starts, run, size, rng):
    y = y.copy()
    for s in starts:
        v = rng.normal(0, 1, y.shape[1])
        y[s:s + run] += size * v / np.linalg.norm(v)
    return y


@pytest.mark.parametrize("run", [1, 2, 3])
def test_glitches_of_one_to_three_frames_are_found_and_replaced_by_the_line_around_them(run):
    """Glitches of 2 units (20 tolerances) on a clean helix, and on one with noise of 1 tolerance: every glitch
    sample is found and no other; adapted, the walk of the glitched helix is the clean helix's within 2 %."""
    from drake_skills.promp.preprocessing import spike_samples

    rng = np.random.default_rng(10 + run)
    starts = np.arange(40, 460, 60)
    truth = np.zeros(500, bool)
    for s in starts:
        truth[s:s + run] = True
    clean = _helix()
    assert not spike_samples(clean, TOL).any()
    for base in (clean, clean + rng.normal(0, TOL, clean.shape)):
        y = _glitched(base, starts, run, 2.0, rng)
        np.testing.assert_array_equal(spike_samples(y, TOL), truth)
    glitched = _glitched(clean, starts, run, 2.0, rng)
    a = vertex_path(clean, TOL, adapt_to_noise=True)[2][-1]
    b = vertex_path(glitched, TOL, adapt_to_noise=True)[2][-1]
    assert b == pytest.approx(a, rel=0.02)
    assert vertex_path(glitched, TOL)[2][-1] > 1.5 * a          # the plain walk counts each glitch twice


def test_a_step_is_not_a_glitch_and_a_glitch_makes_the_walk_non_causal():
    """A tracker that re-acquires the wrist 4 cm away and stays there (buetepage 017 has one) is motion, not a
    glitch: out without coming back. A glitch makes the walk of a prefix differ from the whole's start."""
    from drake_skills.promp.preprocessing import spike_samples, walk_is_causal

    y = _helix()
    y[250:] += np.array([1.0, 0.0, 0.0])
    assert not spike_samples(y, TOL).any()
    g = _glitched(_helix(), [100], 1, 2.0, np.random.default_rng(0))
    assert spike_samples(g, TOL).sum() == 1 and not walk_is_causal(g, TOL, adapt_to_noise=True)
    assert walk_is_causal(_helix(), TOL, adapt_to_noise=True)
    # the last frame has no frame after it: a prefix that ends in a glitch keeps it
    assert not spike_samples(g[:101], TOL).any()


def test_a_glitch_is_replaced_by_the_line_between_its_neighbours_held_frames_count_once_and_the_first_frame_too():
    from drake_skills.promp.preprocessing import despiked, spike_samples

    y = _helix()
    g = y.copy()
    g[100:102] += np.array([2.0, 0.0, 0.0])                     # two frames
    out = despiked(g, TOL)
    for k, w in ((100, 1 / 3), (101, 2 / 3)):
        np.testing.assert_allclose(out[k], (1 - w) * y[99] + w * y[102], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(np.delete(out, [100, 101], axis=0), np.delete(g, [100, 101], axis=0))
    # the same glitch on a tracker that repeats each frame 3 times: found on all its 6 samples
    held = np.repeat(g, 3, axis=0)
    assert np.flatnonzero(spike_samples(held, TOL)).tolist() == list(range(300, 306))
    # a glitch on the first frame: found, and it takes the second frame's position
    f = y.copy()
    f[0] += np.array([0.0, 2.0, 0.0])
    assert np.flatnonzero(spike_samples(f, TOL)).tolist() == [0]
    np.testing.assert_array_equal(despiked(f, TOL)[0], y[1])
    with pytest.raises(ValueError, match="tolerance"):
        spike_samples(y, float("nan"))


def test_despiked_takes_a_precomputed_mask_of_the_right_shape_only():
    from drake_skills.promp.preprocessing import despiked, spike_samples

    g = _glitched(_helix(), [100], 1, 2.0, np.random.default_rng(3))
    mask = spike_samples(g, TOL)
    np.testing.assert_array_equal(despiked(g, TOL, glitches=mask), despiked(g, TOL))
    with pytest.raises(ValueError, match=r"glitches must be a mask of shape \(500,\)"):
        despiked(g, TOL, glitches=mask[:-1])
    # a walk told the glitches are removed does not look for them
    assert vertex_path(g, TOL, adapt_to_noise=True, glitches_removed=True)[2][-1] > \
        1.1 * vertex_path(g, TOL, adapt_to_noise=True)[2][-1]


def test_despiked_checks_the_motion_itself_when_given_a_mask_and_reads_a_0_1_mask_as_booleans():
    from drake_skills.promp.preprocessing import despiked, spike_samples

    g = _glitched(_helix(), [100], 1, 2.0, np.random.default_rng(3))
    mask = spike_samples(g, TOL)
    np.testing.assert_array_equal(despiked(g, TOL, glitches=mask.astype(int)), despiked(g, TOL))
    bad = g.copy()
    bad[5, 0] = np.nan
    for y in (bad, g[:, 0], g[:0]):
        with pytest.raises(ValueError, match="trajectory"):
            despiked(y, TOL, glitches=np.zeros(len(y), bool))


def test_the_averaging_walk_puts_each_vertex_at_the_mean_of_its_samples_ends_included():
    """Tolerance 0.2 along a line: 0, 0.05, 0.1 stay within 0.2 of their mean (0.05), 0.5 leaves it; 0.5 and 0.55
    make one vertex (0.525), 1.2 and 1.25 the next (1.225). The indices are each vertex's first sample."""
    from drake_skills.promp.preprocessing import _averaging_walk

    x = np.array([0.0, 0.05, 0.1, 0.5, 0.55, 1.2, 1.25])
    idx, v = _averaging_walk(np.stack([x, np.zeros_like(x)], axis=1), 0.2)
    np.testing.assert_array_equal(idx, [0, 3, 5])
    np.testing.assert_allclose(v[:, 0], [0.05, 0.525, 1.225], atol=1e-12)
    assert np.all(v[:, 1] == 0.0)
    # nothing leaves the tolerance of the mean: one vertex, no path
    idx, v = _averaging_walk(np.array([[0.0], [0.1], [0.15], [0.2]]), 0.2)
    np.testing.assert_array_equal(idx, [0])
    np.testing.assert_allclose(v[:, 0], [0.1125])


@pytest.mark.parametrize("sigma", [0.5, 1.0, 3.0])
def test_averaged_holds_add_almost_no_path_where_vertices_at_samples_add_a_quarter_to_three_quarters(sigma):
    """A helix (true length L) and a hold of 1000 samples, noise ``sigma`` tolerances. Vertices at the smoothed
    samples (``average_holds=False``): the motion measures 1.07-1.24 L and the hold adds 0.24-0.75 L. Averaged:
    1.04-1.08 L and 0.03-0.09 L (seed 4). Asserted: the motion within 1.1 L, the hold below 0.12 L and below a
    quarter of what the sample walk adds."""
    rng = np.random.default_rng(4)
    true_length = arc_length(_helix(), TOL)[1][-1]
    y = np.vstack([_helix(), np.repeat(_helix()[-1:], 1000, axis=0)]) + rng.normal(0, sigma * TOL, (1500, 3))
    out = {}
    for average in (False, True):
        idx, v, s = vertex_path(y, TOL, adapt_to_noise=True, average_holds=average)
        assert len(idx) == len(v) == len(s) and idx[0] == 0 and np.all(np.diff(idx) > 0)
        k = np.searchsorted(idx, 600)
        out[average] = (s[k - 1] / true_length, (s[-1] - s[k - 1]) / true_length)
    assert out[True][0] < 1.1 and out[True][1] < 0.12 and out[True][1] < 0.25 * out[False][1], out
    assert out[False][1] > 0.2, out   # what the averaging is for


def test_a_longer_rest_at_the_end_of_a_noisy_motion_adds_less_than_half_the_path_it_did():
    """The library's own path length (normalized units) of a noisy reach followed by a rest of 1 s or of 4 s at
    100 Hz (noise 0.5 tolerances, so the walk adapts; the same noise for both walks). Seed 11: the 3 s more of
    rest add 1.2 units (5.7 %) with the default walk, 2.8 (13 %) with vertices at the samples. Asserted: below 8 %
    and below half of what the sample walk adds."""
    from drake_skills import LibraryConfig, SkillLibrary

    rng = np.random.default_rng(11)
    reach = _helix(300)
    ys = {}
    for rest in (100, 400):
        y = np.vstack([reach, np.repeat(reach[-1:], rest, axis=0)]) + rng.normal(0, 0.5 * TOL, (300 + rest, 3))
        ys[rest] = y - y[0]
    added = {}
    for average in (True, False):
        lib = SkillLibrary(LibraryConfig(average_holds=average))
        short, long = (lib.path_length(ys[r], normalized=True) for r in (100, 400))
        added[average] = (long - short, long / short)
    assert added[True][1] < 1.08 and added[True][0] < 0.5 * added[False][0], added


def test_a_clean_motion_whose_glitch_is_replaced_is_walked_plainly_with_its_vertices_at_samples():
    """A glitch replaced on an otherwise clean line (below the noise share, so nothing is smoothed): the walk is
    the plain walk of the despiked line, its vertices samples of it, whatever ``average_holds`` says (a cold
    review: no test held that the averaging acts only on smoothed motions)."""
    from drake_skills.promp.preprocessing import despiked, spike_samples

    y = np.stack([np.linspace(0.0, 3.0, 200), np.zeros(200), np.zeros(200)], axis=1)
    y[80] += [0.0, 1.0, 0.0]                       # one frame 10 tolerances off the line, then back
    assert spike_samples(y, TOL).sum() == 1
    plain = vertex_path(despiked(y, TOL), TOL)
    for average in (True, False):
        idx, v, s = vertex_path(y, TOL, adapt_to_noise=True, average_holds=average)
        np.testing.assert_array_equal(idx, plain[0])
        np.testing.assert_array_equal(v, despiked(y, TOL)[idx])
        np.testing.assert_array_equal(s, plain[2])
