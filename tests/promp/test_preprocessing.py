"""Arc-length resampling and workspace normalization (Eq. 14)."""
import numpy as np
import pytest

from drake_skills.promp.preprocessing import (Workspace, arc_length, path_vertices, resample_by_arc_length,
                                              resample_in_time, vertex_indices)


def _path(s):
    """A planar-ish 3-D curve as a function of a path parameter s in [0, 1]."""
    return np.stack([np.cos(3 * s), np.sin(2 * s) + s, 0.5 * s ** 2], axis=1)


def _path_length(y):
    return np.linalg.norm(np.diff(y, axis=0), axis=1).sum()


def test_arc_length_resampling_is_invariant_to_speed():
    u = np.linspace(0, 1, 4000)
    slow_fast = u ** 3  # the same path, traversed with a nonlinear monotone change of speed
    a = resample_by_arc_length(_path(u), 50)
    b = resample_by_arc_length(_path(slow_fast), 50)
    L = _path_length(_path(u))
    assert np.abs(a - b).max() < 1e-3 * L, np.abs(a - b).max() / L


def test_arc_length_samples_are_equidistant_along_the_path():
    # a helix (constant curvature) traversed at a varying speed: chords of equal arcs are equal
    a = 4 * np.pi * np.linspace(0, 1, 4000) ** 2
    y = resample_by_arc_length(np.stack([np.cos(a), np.sin(a), 0.3 * a], axis=1), 30)
    step = np.linalg.norm(np.diff(y, axis=0), axis=1)
    np.testing.assert_allclose(step, step.mean(), rtol=1e-3)


def test_arc_length_resampling_ignores_standing_still_and_repeated_points():
    u = np.linspace(0, 1, 500)
    y = _path(u)
    still = np.concatenate([np.repeat(y[:1], 40, axis=0), y[:200], np.repeat(y[200:201], 7, axis=0), y[200:],
                            np.repeat(y[-1:], 60, axis=0)])
    np.testing.assert_allclose(resample_by_arc_length(still, 40), resample_by_arc_length(y, 40), rtol=0, atol=1e-12)
    out = resample_by_arc_length(still, 40)
    np.testing.assert_allclose(out[0], y[0], atol=1e-12)
    np.testing.assert_allclose(out[-1], y[-1], atol=1e-12)


def test_arc_length_resampling_rejects_motionless_and_bad_input():
    with pytest.raises(ValueError, match="does not move"):
        resample_by_arc_length(np.ones((20, 3)), 10)
    with pytest.raises(ValueError, match="too short"):
        resample_by_arc_length(np.zeros((1, 3)), 10)
    with pytest.raises(ValueError, match="NaN at rows 4"):
        y = _path(np.linspace(0, 1, 10))
        y[4, 0] = np.nan
        resample_by_arc_length(y, 10)
    with pytest.raises(ValueError, match="inf"):
        resample_by_arc_length(np.full((10, 2), np.inf), 10)
    with pytest.raises(ValueError, match="2 dimension"):
        resample_by_arc_length(np.arange(10.0), 10)
    with pytest.raises(ValueError, match="n_samples"):
        resample_by_arc_length(_path(np.linspace(0, 1, 10)), 1)


def test_resample_in_time_is_exact_for_linear_motion_and_rejects_bad_input():
    t = np.array([0.0, 0.1, 0.5, 0.6, 2.0])
    y = np.stack([3 * t + 1, -t], axis=1)
    out = resample_in_time(t, y, 9)
    grid = np.linspace(0, 2, 9)
    np.testing.assert_allclose(out, np.stack([3 * grid + 1, -grid], axis=1), rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="not strictly increasing"):
        resample_in_time([0.0, 0.2, 0.2, 0.3], np.zeros((4, 2)), 5)
    with pytest.raises(ValueError, match="shape"):
        resample_in_time(t, np.zeros((4, 2)), 5)
    with pytest.raises(ValueError, match="t has NaN"):
        resample_in_time([0.0, np.nan, 1.0], np.zeros((3, 2)), 5)
    with pytest.raises(ValueError, match="too short"):
        resample_in_time([0.0], np.zeros((1, 2)), 5)
    with pytest.raises(ValueError, match="n_samples"):
        resample_in_time(t, y, 0)


def test_workspace_normalization_round_trips():
    rng = np.random.default_rng(0)
    ws = Workspace(np.array([-0.3, 0.1, 0.8]), np.array([0.4, 0.9, 1.6]))
    y = rng.uniform(-1, 2, (25, 3))
    np.testing.assert_allclose(ws.denormalize(ws.normalize(y), start=y[0]), y, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ws.denormalize(ws.normalize(y, subtract_start=False)), y, rtol=0, atol=1e-12)
    yn = ws.normalize(y)
    np.testing.assert_array_equal(yn[0], 0.0)


def test_workspace_maps_bounds_to_0_and_scale():
    ws = Workspace([-1.0, 2.0], [1.0, 6.0], scale=10.0)
    out = ws.normalize(np.array([[-1.0, 2.0], [1.0, 6.0], [0.0, 4.0]]), subtract_start=False)
    np.testing.assert_allclose(out, [[0, 0], [10, 10], [5, 5]], rtol=0, atol=1e-12)


def test_from_calibration_takes_bounds_and_shrinks_z():
    xy = np.array([[0.0, 0.0, 1.0], [2.0, 1.0, 1.0]])
    zy = np.array([[1.0, -1.0, 0.0], [1.0, 0.5, 2.0]])
    ws = Workspace.from_calibration([xy, zy])
    np.testing.assert_allclose(ws.lower, [0, -1, 0])
    np.testing.assert_allclose(ws.upper, [2, 1, 2])
    ws9 = Workspace.from_calibration([xy, zy], z_factor=0.9)
    np.testing.assert_allclose(ws9.lower, [0, -1, 0.1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ws9.upper, [2, 1, 1.9], rtol=0, atol=1e-12)
    assert Workspace.from_dict(ws9.dict()).dict() == ws9.dict()


def test_workspace_rejects_bad_input():
    with pytest.raises(ValueError, match="empty along axes"):
        Workspace([0.0, 1.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="lower bound has NaN"):
        Workspace([np.nan, 0.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="shape"):
        Workspace([0.0, 0.0], [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="scale"):
        Workspace([0.0], [1.0], scale=0.0)
    ws = Workspace([0.0, 0.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="shape"):
        ws.normalize(np.zeros((5, 3)))
    with pytest.raises(ValueError, match="inf"):
        ws.normalize(np.full((5, 2), np.inf))
    with pytest.raises(ValueError, match="start"):
        ws.denormalize(np.zeros((5, 2)), start=np.zeros(3))
    with pytest.raises(ValueError, match="no calibration motions"):
        Workspace.from_calibration([])
    with pytest.raises(ValueError, match="different dimensions"):
        Workspace.from_calibration([np.zeros((3, 2)), np.zeros((3, 3))])
    with pytest.raises(ValueError, match="calibration motion 1 has NaN"):
        Workspace.from_calibration([np.eye(3), np.full((3, 3), np.nan)])
    with pytest.raises(ValueError, match="z_factor"):
        Workspace.from_calibration([np.eye(3)], z_factor=1.5)
    with pytest.raises(ValueError, match="z_axis"):
        Workspace.from_calibration([np.eye(2)], z_factor=0.9)


def test_arc_length_with_tolerance_ignores_sensor_noise_and_the_length_of_the_hold():
    """A reach with 0.5 %-of-range noise, held 0.2 s or 1 s at the end: same resampled path within 2 %."""
    rng = np.random.default_rng(0)
    u = np.linspace(0, 1, 300)
    path = _path(u) * 4.0  # a few normalized units long, like a salad reach

    def recorded(hold_samples):
        y = np.vstack([path, np.repeat(path[-1:], hold_samples, axis=0)])
        return y + rng.normal(0, 0.01, y.shape)

    short, long_ = recorded(30), recorded(150)
    raw = [np.sum(np.linalg.norm(np.diff(y, axis=0), axis=1)) for y in (short, long_)]
    true_len = np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1))
    assert raw[1] > 1.3 * true_len  # the raw arc length is dominated by the noise
    a = resample_by_arc_length(short, 50, tolerance=0.1)
    b = resample_by_arc_length(long_, 50, tolerance=0.1)
    ref = resample_by_arc_length(path, 50)
    scale = np.ptp(path, axis=0).max()
    assert np.abs(a - b).max() < 0.02 * scale
    assert np.abs(a - ref).max() < 0.03 * scale
    # without the tolerance the long hold drags the phase: far worse
    c = resample_by_arc_length(short, 50)
    d = resample_by_arc_length(long_, 50)
    assert np.abs(c - d).max() > 3 * np.abs(a - b).max()


def test_path_vertices_of_a_prefix_are_a_prefix_of_the_vertices():
    from drake_skills.promp.preprocessing import path_vertices

    rng = np.random.default_rng(1)
    y = _path(np.linspace(0, 1, 200)) * 4.0 + rng.normal(0, 0.01, (200, 3))
    full = path_vertices(y, 0.1)
    part = path_vertices(y[:120], 0.1)
    np.testing.assert_array_equal(part[:-1], full[: len(part) - 1])
    with pytest.raises(ValueError, match="tolerance"):
        path_vertices(y, -1.0)
    with pytest.raises(ValueError, match="tolerance"):
        path_vertices(y, float("nan"))


# ------------------------------------------------------------------ path vertices, exact indices
def test_vertex_indices_without_tolerance_drop_repeats_and_steps_below_1e_9_of_the_length():
    y = np.array([[0.0, 0.0], [0.0, 0.0], [1000.0, 0.0], [1000.0, 1e-7], [1000.0, 1e-7], [1000.0, 3.0]])
    # a 1e-7 step on a 1003-long path is below 1e-9 * 1003: standing still
    np.testing.assert_array_equal(vertex_indices(y), [0, 2, 5])
    np.testing.assert_array_equal(vertex_indices(y, 0.0), [0, 2, 5])
    short = np.array([[0.0], [0.2], [0.2], [0.5]])  # a path shorter than 1 moves too
    np.testing.assert_array_equal(vertex_indices(short), [0, 1, 3])
    np.testing.assert_array_equal(vertex_indices(np.zeros((4, 2))), [0])  # no motion: the first sample
    assert vertex_indices(y).dtype.kind == "i"


def test_vertex_indices_with_tolerance_keep_samples_farther_than_it_from_the_last_kept():
    y = np.array([[0.0], [0.3], [0.6], [0.7], [1.2], [1.3]])
    # tolerance 0.5: 0 -> 0.6 (0.6 > 0.5) -> 1.2 (0.6 > 0.5); the last sample moved (1.3 != 1.2): kept
    np.testing.assert_array_equal(vertex_indices(y, 0.5), [0, 2, 4, 5])
    y2 = np.array([[0.0], [0.3], [0.6], [0.7], [1.2], [1.2]])  # ends where the last kept one is: not repeated
    np.testing.assert_array_equal(vertex_indices(y2, 0.5), [0, 2, 4])
    y3 = np.array([[0.0], [0.6], [0.7], [1.3]])  # the last sample is kept by the walk itself
    np.testing.assert_array_equal(vertex_indices(y3, 0.5), [0, 1, 3])
    y4 = np.array([[0.0], [0.1], [0.8], [0.9]])  # the second sample is walked past, not kept
    np.testing.assert_array_equal(vertex_indices(y4, 0.5), [0, 2, 3])
    big = np.array([[0.0], [2.0], [3.5], [4.0]])  # tolerance above 1: the distance is compared with tol, not 1
    np.testing.assert_array_equal(vertex_indices(big, 1.6), [0, 1, 3])
    np.testing.assert_array_equal(path_vertices(y, 0.5), y[[0, 2, 4, 5]])


def test_path_functions_default_to_no_tolerance():
    rng = np.random.default_rng(4)
    y = np.cumsum(rng.normal(0, 0.3, (30, 2)), axis=0)
    np.testing.assert_array_equal(path_vertices(y), y)  # every sample moves
    v, s = arc_length(y)
    np.testing.assert_allclose(s[-1], np.linalg.norm(np.diff(y, axis=0), axis=1).sum(), rtol=1e-12)
    assert len(v) == 30 and len(path_vertices(y, 1.0)) < 30


@pytest.mark.parametrize("fn", [path_vertices, vertex_indices, arc_length])
def test_path_functions_messages(fn):
    with pytest.raises(ValueError, match=r"^trajectory must have 2 dimension\(s\), got shape \(5,\)$"):
        fn(np.arange(5.0))
    with pytest.raises(ValueError, match=r"^trajectory is too short: 1 sample\(s\), need at least 2$"):
        fn(np.zeros((1, 2)))
    with pytest.raises(ValueError, match=r"^tolerance must be a finite number >= 0, got -0.1$"):
        fn(np.eye(2), -0.1)
    with pytest.raises(ValueError, match=r"^tolerance must be a finite number >= 0, got nan$"):
        fn(np.eye(2), np.nan)
    assert len(fn(np.eye(2))) == 2


def test_resampling_boundaries_and_messages():
    y = np.array([[0.0, 0.0], [0.3, 0.4]])  # a path of length 0.5
    np.testing.assert_allclose(resample_by_arc_length(y, 2), y, rtol=0, atol=1e-15)
    np.testing.assert_allclose(resample_by_arc_length(y, 3)[1], [0.15, 0.2], rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match=r"^n_samples must be >= 2, got 1$"):
        resample_by_arc_length(y, 1)
    with pytest.raises(ValueError, match=r"^trajectory does not move: its path length is 0$"):
        resample_by_arc_length(np.ones((4, 2)), 5)
    with pytest.raises(ValueError, match=r"^trajectory must have 2 dimension\(s\), got shape \(3,\)$"):
        resample_by_arc_length(np.zeros(3), 5)
    t = np.array([0.0, 1.0])
    np.testing.assert_allclose(resample_in_time(t, y, 2), y, rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match=r"^n_samples must be >= 2, got 1$"):
        resample_in_time(t, y, 1)
    with pytest.raises(ValueError, match=r"^t must have 1 dimension\(s\), got shape \(2, 1\)$"):
        resample_in_time(t[:, None], y, 3)
    with pytest.raises(ValueError, match=r"^t is too short: 1 sample\(s\), need at least 2$"):
        resample_in_time(t[:1], y[:1], 3)
    with pytest.raises(ValueError, match=r"^trajectory must have shape \(2, any\), got \(3, 2\)$"):
        resample_in_time(t, np.zeros((3, 2)), 3)


# ------------------------------------------------------------------ workspace
def test_workspace_stores_read_only_float_bounds_and_scale():
    ws = Workspace([0, 1], [2, 3], scale=5)
    assert ws.lower.dtype == float and ws.upper.dtype == float and type(ws.scale) is float and ws.scale == 5.0
    assert ws.dim == 2
    with pytest.raises(ValueError):
        ws.upper[0] = 9.0
    with pytest.raises(ValueError):
        ws.lower[0] = 9.0
    assert ws.dict() == {"lower": [0.0, 1.0], "upper": [2.0, 3.0], "scale": 5.0}
    assert repr(Workspace([0.123456, 1.0], [2.0, 3.987654])) == "Workspace(lower=[0.1235, 1.0], upper=[2.0, 3.9877])"
    assert Workspace([0.0], [1.0], scale=0.5).scale == 0.5  # any positive scale


def test_workspace_from_dict_reads_the_scale_and_defaults_it_to_10():
    ws = Workspace.from_dict({"lower": [0, 1], "upper": [2, 3], "scale": 4})
    assert ws.scale == 4.0 and ws.lower.tolist() == [0.0, 1.0] and ws.upper.dtype == float
    assert Workspace.from_dict({"lower": [0], "upper": [1]}).scale == 10.0
    assert Workspace([0.0], [1.0]).scale == 10.0
    assert Workspace.from_calibration([np.array([[0.0, 0.0], [1.0, 1.0]])]).scale == 10.0


def test_workspace_messages():
    with pytest.raises(ValueError, match=r"^workspace is empty along axes \[1, 2\]: upper <= lower$"):
        Workspace([0.0, 1.0, 2.0], [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match=r"^workspace lower bound must have 1 dimension\(s\), got shape \(1, 2\)$"):
        Workspace([[0.0, 0.0]], [1.0, 1.0])
    with pytest.raises(ValueError, match=r"^workspace upper bound must have shape \(2\), got \(3,\)$"):
        Workspace([0.0, 0.0], [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match=r"^scale must be positive, got 0.0$"):
        Workspace([0.0], [1.0], scale=0.0)
    with pytest.raises(ValueError, match=r"^scale must be positive, got inf$"):
        Workspace([0.0], [1.0], scale=np.inf)
    ws = Workspace([0.0, 0.0], [1.0, 1.0])
    with pytest.raises(ValueError, match=r"^trajectory must have shape \(any, 2\), got \(5, 3\)$"):
        ws.normalize(np.zeros((5, 3)))
    with pytest.raises(ValueError, match=r"^normalized trajectory must have shape \(any, 2\), got \(5, 3\)$"):
        ws.denormalize(np.zeros((5, 3)))
    with pytest.raises(ValueError, match=r"^start must have shape \(2\), got \(3,\)$"):
        ws.denormalize(np.zeros((5, 2)), start=np.zeros(3))
    with pytest.raises(ValueError, match=r"^no calibration motions given$"):
        Workspace.from_calibration([])
    with pytest.raises(ValueError, match=r"^calibration motion 0 must have 2 dimension\(s\), got shape \(3,\)$"):
        Workspace.from_calibration([np.zeros(3)])
    with pytest.raises(ValueError, match=r"^calibration motion 1 is too short: 1 sample\(s\), need at least 2$"):
        Workspace.from_calibration([np.eye(2), np.zeros((1, 2))])
    with pytest.raises(ValueError, match=r"^z_factor must be in \(0, 1\], got 0$"):
        Workspace.from_calibration([np.eye(3)], z_factor=0)
    with pytest.raises(ValueError, match=r"^z_axis 3 out of range for 3-D data$"):
        Workspace.from_calibration([np.eye(3)], z_factor=0.9, z_axis=3)
    with pytest.raises(ValueError, match=r"^z_axis -1 out of range for 3-D data$"):
        Workspace.from_calibration([np.eye(3)], z_factor=0.9, z_axis=-1)


def test_from_calibration_shrinks_the_chosen_axis_about_its_centre():
    motions = [np.array([[0.0, 2.0, -1.0], [4.0, 6.0, 3.0]])]
    full = Workspace.from_calibration(motions, z_factor=1.0)
    np.testing.assert_allclose(full.lower, [0, 2, -1])
    np.testing.assert_allclose(full.upper, [4, 6, 3])
    y0 = Workspace.from_calibration(motions, z_factor=0.5, z_axis=0)  # x: centre 2, half range 1
    np.testing.assert_allclose(y0.lower, [1, 2, -1])
    np.testing.assert_allclose(y0.upper, [3, 6, 3])
    z = Workspace.from_calibration(motions, z_factor=0.5, scale=2.0)  # z (axis 2): centre 1, half range 1
    np.testing.assert_allclose(z.lower, [0, 2, 0])
    np.testing.assert_allclose(z.upper, [4, 6, 2])
    assert z.scale == 2.0


def test_vertex_indices_keep_only_samples_strictly_farther_than_the_tolerance():
    """Exact binary fractions: 0.5 away from the last kept sample is not farther than 0.5."""
    y = np.array([[0.0], [0.5], [1.0], [1.5]])
    np.testing.assert_array_equal(vertex_indices(y, 0.5), [0, 2, 3])  # 3: the end, where it moved to
    # a motion that never gets farther than the tolerance keeps its first and last samples
    np.testing.assert_array_equal(vertex_indices(np.array([[0.0], [0.1], [0.2]]), 0.5), [0, 2])
    np.testing.assert_array_equal(vertex_indices(np.array([[0.0], [0.1], [0.0]]), 0.5), [0])  # back at the start
