"""Preprocessing: arc-length resampling and personal-workspace normalization (Eq. 14).

Human motions are resampled at equidistant points along their path, so the
representation does not depend on the speed of the demonstration; robot
trajectories are resampled uniformly in time.  Positions are normalized to
[0, 10] with a subject's workspace, found from calibration motions, and the
normalized start position is subtracted (Eq. 14): :class:`Workspace` lives with
the data types (:mod:`drake_skills.data.workspace`, the calibration is data) and
is re-exported here.
"""
from __future__ import annotations

import math

import numpy as np

from scipy.ndimage import gaussian_filter1d

from drake_skills._checks import as_finite_array, check_increasing
from drake_skills.data.workspace import Workspace

__all__ = ["Workspace", "arc_length", "noise_level", "path_vertices", "prefix_samples", "resample_by_arc_length",
           "resample_in_time", "despiked", "restart_vertex", "spike_samples", "vertex_indices", "vertex_path",
           "walk_is_causal"]

#: Tracker noise (per axis, :func:`noise_level`) may reach this share of the arc-length tolerance
#: before the path adapts to it (``adapt_to_noise``), and the walk keeps the noise it leaves at
#: this share of its tolerance. Chosen on the buetepage training split with 0-20 mm of added
#: noise (RESULTS.md, "Tracker noise"): 0.4 let 3 mm through with wrong answers, 0.25 answered
#: less often right.
NOISE_SHARE = 0.3
#: Widest smoothing (Gaussian standard deviation, in samples) that ``adapt_to_noise`` applies:
#: a few samples average tracker noise, more blur the motion itself (chosen on the buetepage
#: training split: 3 gave fewer right answers; a cap from the motion's speed per sample was
#: worse on both that split and LASA).
MAX_SMOOTHING = 2.0
#: A tracker's glitch (a joint detected far away for 1-3 frames, then back): a run of at most
#: ``SPIKE_RUN`` frames leaving the line between the frames before and after it by more than
#: ``SPIKE_FACTOR`` times the motion's own 0.9-quantile second difference (and ``SPIKE_FLOOR``
#: tolerances, and ``SPIKE_NOISE`` times the noise), while those two frames lie closer
#: together than that (out and back, not a step). Chosen so that no sample of any clean data set we have is one (buetepage at 100, 33
#: and 20 Hz, LASA-30, salad subjects 1-10, synthetic skills), while 10-30 cm glitches on
#: buetepage are all found (RESULTS.md, "Tracker noise").
SPIKE_FACTOR = 5.0
SPIKE_FLOOR = 2.0
SPIKE_RUN = 3
#: ... and at least this many times the tracker's white noise per axis (:func:`noise_level`; its
#: own excursions from the line between two neighbours stay below 6 times it in 99.99 % of
#: frames), the noise's 0.9-quantile second difference being taken off the motion's.
SPIKE_NOISE = 8.0
#: The quantile of the second differences that :func:`noise_level` reads, and the same
#: quantile of the chi distribution with 1..20 degrees of freedom (norm of a D-dimensional
#: standard normal), precomputed (scipy.stats.chi.ppf(0.1, D)).
_NOISE_QUANTILE = 0.1
_CHI_Q10 = (0.12566, 0.45904, 0.76444, 1.03132, 1.26898, 1.48463, 1.68318, 1.86803, 2.04161, 2.20572,
            2.36173, 2.51074, 2.65358, 2.79097, 2.92348, 3.0516, 3.17572, 3.2962, 3.41334, 3.52741)
_CHI_Q90 = (1.64485, 2.14597, 2.50028, 2.78916, 3.03914, 3.26261, 3.46656, 3.65535, 3.83193, 3.9984,
            4.15632, 4.3069, 4.45106, 4.58957, 4.72304, 4.85199, 4.97685, 5.09798, 5.2157, 5.33029)

#: A false start (:func:`restart_vertex`): the wrist is back at its start within this share of the
#: farthest the motion gets from it ...
RESTART_NEAR = 0.1
#: ... and an excursion from the start counts when it reaches this share of that farthest distance
#: (and :data:`RESTART_MIN_TOLERANCES` walk tolerances). Set by the construction, not tuned: a
#: person's return to where they began lies within a few centimetres of a 40-60 cm motion
#: (buetepage_hr test interaction 037: back within 2.3 cm after 14 cm, then 56 cm), and a fifth of the
#: motion is well above the wrist's drift at rest. On every clean data set we have (LASA-30, the
#: buetepage interactions, salad subjects 1-10 in both models) only interaction 037 has two such
#: excursions; of 3000 synthetic demonstrations (random paths from the origin) 115 do.
RESTART_EXCURSION = 0.2
RESTART_MIN_TOLERANCES = 5.0

#: Points closer than this (in the trajectory's units, relative to the path
#: length) count as standing still and are dropped before resampling.
_STILL_TOLERANCE = 1e-9


def path_vertices(y, tolerance: float = 0.0, *, adapt_to_noise: bool = False, average_holds: bool = True
                  ) -> np.ndarray:
    """The samples that carry a path on: noise and standing still removed.

    Walks the samples in order and keeps one when it lies more than
    ``tolerance`` from the last kept one; the first sample is always kept and
    the last one whenever it moved at all. Sensor noise while the hand stands
    still (or moves slowly) then adds no path length: with noise of 0.5 mm at
    150 Hz, the raw arc length of a simulated salad reach is 20-40 % longer
    than its path and grows with every sample of the hold at the end. The plain walk is causal,
    so a prefix of a motion keeps a prefix of the vertices, and an observed prefix is
    parametrized exactly as the start of the whole motion; the walk adapted to noise
    (``adapt_to_noise``, :func:`vertex_path`) is not, see :func:`prefix_samples`. When that
    walk smooths a noisy motion, its vertices are smoothed samples, or with ``average_holds``
    the means of the samples each stands for (the path then starts and ends at means, and a
    motion that never leaves the tolerance of its mean has one vertex).

    Parameters
    ----------
    y : array, shape (T, D)
    tolerance : float
        In the units of ``y``; 0 keeps every sample that moves at all (only
        exact repeats are dropped).
    adapt_to_noise, average_holds : bool
        See :func:`vertex_path`.

    Returns
    -------
    vertices : array, shape (M, D), M >= 1
    """
    return vertex_path(y, tolerance, adapt_to_noise=adapt_to_noise, average_holds=average_holds)[1]


def noise_level(y) -> float:
    """Estimated white tracker noise of a motion, per axis, in the units of ``y``.

    From the second differences of the samples that moved (a tracker that repeats its last
    value between frames adds none): for white noise of standard deviation sigma per axis a
    second difference is sigma sqrt(6) times a chi-distributed norm, and a smooth motion
    sampled densely adds little to it at its slowest tenth (rests, constant speed). The
    lowest decile read as the noise is therefore an upper bound that is tight for noise
    above the motion's own curvature per sample, and 0 for a motion without noise. Noise the
    tracker smoothed or interpolated in time has small second differences and reads low
    (RESULTS.md, "Tracker noise"). Returns 0 for fewer than 5 moving samples.

    Parameters
    ----------
    y : array, shape (T, D)
        Finite.
    """
    y = as_finite_array(y, "trajectory", ndim=2, min_rows=1)
    return _frame_noise(_frames(y)[0])


def _frames(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The samples that moved (a held frame counts once) and, per sample, the index of its frame."""
    moved = np.concatenate([[True], np.any(y[1:] != y[:-1], axis=1)])
    return (y, np.arange(len(y))) if moved.all() else (y[moved], np.cumsum(moved) - 1)


def _chi_quantile(dim: int, q: float = _NOISE_QUANTILE) -> float:
    """The ``q`` (0.1 or 0.9) quantile of the norm of a ``dim``-dimensional standard normal."""
    table = _CHI_Q10 if q == _NOISE_QUANTILE else _CHI_Q90
    if dim <= len(table):
        return table[dim - 1]
    from scipy.stats import chi  # noqa: PLC0415 (slow to import; only for more than 20 dimensions)

    return float(chi.ppf(q, dim))


def _second_sq(frames: np.ndarray) -> np.ndarray:
    """Squared norms of the second differences of ``frames`` (huge values: inf, refused by the walk's caller)."""
    d = np.diff(frames, axis=0)
    d2 = d[1:] - d[:-1]
    with np.errstate(over="ignore", invalid="ignore"):
        return np.einsum("ij,ij->i", d2, d2)


def _frame_noise(frames: np.ndarray) -> float:
    if len(frames) < 5:
        return 0.0
    return _level_of(_second_sq(frames), frames.shape[1])


def _level_of(sq: np.ndarray, dim: int) -> float:
    """The noise level from the squared norms of a motion's second differences (see :func:`noise_level`)."""
    k = int(_NOISE_QUANTILE * (len(sq) - 1))        # the lower order statistic at the quantile
    return math.sqrt(float(np.partition(sq, k)[k])) / (math.sqrt(6.0) * _chi_quantile(dim))


def _noise_gain(width: float) -> float:
    """Standard deviation of white noise after ``gaussian_filter1d(width)``, per unit before (the kernel's norm)."""
    radius = int(4.0 * width + 0.5)                 # scipy's truncation at 4 standard deviations
    impulse = np.zeros(2 * radius + 1)
    impulse[radius] = 1.0
    return float(np.linalg.norm(gaussian_filter1d(impulse, width, mode="constant")))


def _denoised(y: np.ndarray, tol: float, sigma: float | None = None) -> tuple[np.ndarray, float, bool]:
    """The samples and the tolerance the path walk uses when it adapts to the tracker's noise.

    Unchanged while the noise is at most ``NOISE_SHARE`` of the tolerance (every data set
    we have: its clean motions lie at 0-0.1 of it). Above, a Gaussian of at most
    ``MAX_SMOOTHING`` frames (a held frame counts once) averages the noise towards that
    share, and the tolerance grows to 1 / NOISE_SHARE times what is left, so that a hold
    adds a ninth to a fiftieth of the path it adds to the plain walk (not none: two 3-D
    samples of the noise left lie that far apart about once in ten;
    ``tests/promp/test_noise_adaptation.py``). ``sigma``: the noise level of ``y``'s frames, if known.
    Returns the samples, the tolerance and whether they were smoothed.
    """
    frames, frame_of = _frames(y)
    if sigma is None:
        sigma = _frame_noise(frames)
    if not sigma > NOISE_SHARE * tol:
        return y, tol, False
    ratio = sigma / (NOISE_SHARE * tol)
    width = MAX_SMOOTHING if ratio > 10.0 else min(MAX_SMOOTHING, ratio ** 2 / (2.0 * math.sqrt(math.pi)))
    with np.errstate(over="ignore", invalid="ignore"):
        smooth = gaussian_filter1d(frames, width, axis=0, mode="nearest")
    return smooth[frame_of], max(tol, sigma * _noise_gain(width) / NOISE_SHARE), True


def prefix_samples(y, fraction: float, tolerance: float = 0.0, *, adapt_to_noise: bool = False,
                   average_holds: bool = True) -> int:
    """How many leading samples of ``y`` the walk measures as ``fraction`` of the whole path.

    The walk of the plain path is causal (a prefix keeps a prefix of the vertices), so this
    is the sample of the first vertex at or past the fraction, plus one. An adapted walk
    (:func:`vertex_path`) smooths and estimates the noise over the samples it is given, so a
    prefix is not walked as the start of the whole; then the count is searched (bisection)
    for a prefix whose own walk reaches the fraction of the whole's while the one a sample
    shorter does not: what the library sees when it is given those samples. The lengths of
    such prefixes are not monotone in the count (the noise estimate, and with
    ``average_holds`` the last vertex's mean, move as samples arrive), so this can be a few
    samples past the first that reaches it. At least 2.
    """
    y = as_finite_array(y, "trajectory", ndim=2, min_rows=2)
    f = float(fraction)
    idx, _, s = vertex_path(y, tolerance, adapt_to_noise=adapt_to_noise, average_holds=average_holds)
    target = f * s[-1] * (1 - 1e-12)
    if walk_is_causal(y, tolerance, adapt_to_noise=adapt_to_noise):
        k = int(np.searchsorted(s, target))
        return max(2, int(idx[min(k, len(idx) - 1)]) + 1)
    lo, hi = 2, len(y)                                # the walk of y[:hi] reaches the target
    while lo < hi:
        mid = (lo + hi) // 2
        if vertex_path(y[:mid], tolerance, adapt_to_noise=True, average_holds=average_holds)[2][-1] >= target:
            hi = mid
        else:
            lo = mid + 1
    return lo


def walk_is_causal(y, tolerance: float = 0.0, *, adapt_to_noise: bool = False) -> bool:
    """Is the walk of ``y`` the plain one, so that its prefixes are walked as its start?

    True without ``adapt_to_noise`` or a tolerance; otherwise when the walk adapts to
    neither the whole motion nor its prefixes of 5, 10, 20, ... frames (a prefix can read
    noisier than the whole: its slowest tenth is another tenth; the doubling lengths are a
    check, not a proof, for the lengths between them).
    """
    tol = float(tolerance)
    if not adapt_to_noise or not tol > 0:
        return True
    y = as_finite_array(y, "trajectory", ndim=2, min_rows=2)
    if spike_samples(y, tol).any():
        return False
    frames = _frames(y)[0]
    whole = _frame_noise(frames)
    n = 5
    while n < len(frames):
        if _frame_noise(frames[:n]) > NOISE_SHARE * tol:
            return False
        n *= 2
    return not whole > NOISE_SHARE * tol


def spike_samples(y, tolerance: float) -> np.ndarray:
    """Which samples belong to a tracker's glitch (see ``SPIKE_FACTOR``): a boolean mask, shape (T,).

    Samples a tracker repeats count as one frame. The first frame is one when it lies farther
    than the threshold from the second and the motion goes on smoothly from the second (3
    times the next two steps); the last frame never is (out and back needs the frame after),
    so a prefix that ends in a glitch keeps it until the next frame arrives.
    """
    y = as_finite_array(y, "trajectory", ndim=2, min_rows=1)
    tol = float(tolerance)
    if not (math.isfinite(tol) and tol >= 0):
        raise ValueError(f"tolerance must be a finite number >= 0, got {tolerance!r}")
    return _glitches(y, tol)[0]


def _glitches(y: np.ndarray, tol: float) -> tuple[np.ndarray, float]:
    """:func:`spike_samples` of a checked ``y``, and the noise level of its frames (:func:`noise_level`)."""
    frames, frame_of = _frames(y)
    n = len(frames)
    if n < 5:
        return np.zeros(len(y), bool), 0.0
    sq = _second_sq(frames)
    sigma = _level_of(sq, frames.shape[1])
    if not tol > 0:
        return np.zeros(len(y), bool), sigma
    with np.errstate(over="ignore", invalid="ignore"):
        k = int(0.9 * (len(sq) - 1))                # the lower order statistic at the quantile
        q90 = math.sqrt(float(np.partition(sq, k)[k]))
        d2 = np.sqrt(sq)
        noise_q90 = math.sqrt(6.0) * _chi_quantile(frames.shape[1], 0.9) * sigma
        motion = max(q90 - noise_q90, 0.0)
        threshold = max(SPIKE_FACTOR * motion, SPIKE_NOISE * sigma, SPIKE_FLOOR * tol)
        glitch = np.zeros(n, bool)
        for j in np.flatnonzero(d2 > threshold) + 1:
            if glitch[j] or glitch[j - 1]:
                continue
            for r in range(1, SPIKE_RUN + 1):
                a, b = j - 1, j + r
                if b >= n:
                    break
                seg = frames[b] - frames[a]
                length_sq = float(seg @ seg)
                pts = frames[j:b] - frames[a]
                u = np.clip(pts @ seg / length_sq, 0.0, 1.0) if length_sq > 0 else np.zeros(r)
                away = np.linalg.norm(pts - u[:, None] * seg, axis=1)
                excursion = float(away.max())
                # every frame of the run is away (not the last frame before it), and the run comes back
                if away.min() > 0.5 * threshold and excursion > threshold and math.sqrt(length_sq) < excursion:
                    glitch[j:b] = True
                    break
        # the first frame has no frame before it: a glitch if it lies far from the second while the motion
        # goes on smoothly from there (a jump of more than the threshold, 3 times the next two steps)
        jump = float(np.linalg.norm(frames[1] - frames[0]))
        steps = np.linalg.norm(np.diff(frames[1:4], axis=0), axis=1)
        if not glitch[1] and jump > threshold and jump > 3.0 * float(steps.max()):
            glitch[0] = True
    return glitch[frame_of], sigma


def despiked(y, tolerance: float, *, glitches: np.ndarray | None = None) -> np.ndarray:
    """``y`` with each glitch (:func:`spike_samples`) replaced by the line between the frames around it.

    A glitch on the first frame takes the second frame's position. ``y`` itself when there is none.
    ``glitches``: the mask :func:`spike_samples` gave for ``y`` (not computed again).
    """
    y = as_finite_array(y, "trajectory", ndim=2, min_rows=1)
    bad = spike_samples(y, tolerance) if glitches is None else np.asarray(glitches, bool)
    if bad.shape != (len(y),):
        raise ValueError(f"glitches must be a mask of shape ({len(y)},), got {bad.shape}")
    return _replaced(y, bad)


def _replaced(y: np.ndarray, bad: np.ndarray) -> np.ndarray:
    """``y`` with the samples of the mask ``bad`` on the line between the good ones around them (``y`` if none)."""
    if not bad.any():
        return y
    good = np.flatnonzero(~bad)
    out = y.copy()
    for d in range(y.shape[1]):
        out[bad, d] = np.interp(np.flatnonzero(bad), good, y[good, d])
    return out


def vertex_path(y, tolerance: float = 0.0, *, adapt_to_noise: bool = False, glitches_removed: bool = False,
                average_holds: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The path walk of :func:`path_vertices` with the indices of its vertices and its arc length.

    With ``adapt_to_noise`` (and a positive ``tolerance``) the tracker's glitches
    (:func:`spike_samples`) are first replaced by the line between the frames around them,
    and a motion whose tracker noise (:func:`noise_level`) exceeds ``NOISE_SHARE`` of the
    tolerance is smoothed over at most ``MAX_SMOOTHING`` samples and walked with a tolerance
    of 1 / ``NOISE_SHARE`` times the noise left, so the vertices are smoothed samples (a
    deviation from the paper, which resamples the raw positions; RESULTS.md, "Tracker
    noise"). Without glitches and below that share the walk is exactly the plain one.
    ``glitches_removed``: the caller has already passed ``y`` through :func:`despiked`.
    ``average_holds`` (``LibraryConfig.average_holds``): a smoothed motion is walked with each
    vertex at the mean of the samples it stands for, not at its first sample, so that a hold
    adds almost no path (:func:`_averaging_walk`); the plain walk's vertices are noisy samples,
    and two of them lie a tolerance apart often enough that a rest of a few seconds adds 7-28 %
    to a buetepage interaction's path at 2 mm of noise (RESULTS.md, "Tracker noise").

    Returns
    -------
    indices : array, shape (M,)
        Of the samples the walk keeps (increasing, first is 0); with ``average_holds`` on a
        smoothed motion, the first sample of each vertex.
    vertices : array, shape (M, D)
    s : array, shape (M,)
        Cumulative arc length, ``s[0] = 0``.
    """
    y = as_finite_array(y, "trajectory", ndim=2, min_rows=2)
    tol = float(tolerance)
    if not (np.isfinite(tol) and tol >= 0):
        raise ValueError(f"tolerance must be a finite number >= 0, got {tolerance!r}")
    smoothed = False
    if adapt_to_noise and tol > 0:
        if glitches_removed:
            y, tol, smoothed = _denoised(y, tol)
        else:
            bad, sigma = _glitches(y, tol)
            y, tol, smoothed = (_denoised(_replaced(y, bad), tol) if bad.any() else _denoised(y, tol, sigma))
    if smoothed and average_holds and math.isfinite(tol) and np.isfinite(y).all():
        idx, v = _averaging_walk(y, tol)  # (what overflowed: the plain walk carries it into the length, refused)
    else:
        idx = _walk(y, tol)
        v = y[idx]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(v, axis=0), axis=1))])
    return idx, v, s


def vertex_indices(y, tolerance: float = 0.0, *, adapt_to_noise: bool = False, average_holds: bool = True
                   ) -> np.ndarray:
    """Indices of the samples :func:`path_vertices` keeps (increasing, first is 0; with ``average_holds`` on a
    smoothed motion, the first sample of each vertex)."""
    return vertex_path(y, tolerance, adapt_to_noise=adapt_to_noise, average_holds=average_holds)[0]


def _averaging_walk(y: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """The walk whose vertices are the means of the samples they stand for (``average_holds``).

    A sample joins the current vertex while it lies within ``tol`` of the mean of the samples
    that vertex holds; otherwise it starts the next vertex. The indices are the first sample of
    each vertex; the path starts at the mean of the first vertex's samples and ends at the mean
    of the last's (a motion that never leaves the tolerance has one vertex and no length). At a
    hold the mean settles on the true position, so the noise left after smoothing
    (``NOISE_SHARE`` tolerances per axis) reaches ``tol`` about once in 90 samples in 3-D (the
    chi-square tail; measured on noisy rests once in 60-190), where against a single noisy
    sample (sqrt(2) times as far) it does about once in 10. Samples a tracker repeats weigh as
    often as they are repeated. The
    ends as means, not samples, were chosen on LASA half A with 2-4 mm of noise (RESULTS.md,
    "Tracker noise: a rest adds no path"): with the first and last sample as the ends it
    answered 4-16 % wrong instead of 2-8 %.
    """
    rows = y.tolist()
    starts, means = [0], []
    n, mean = 1, rows[0]
    dist = math.dist
    for i in range(1, len(rows)):
        r = rows[i]
        if dist(r, mean) > tol:
            means.append(mean)
            starts.append(i)
            n, mean = 1, r
        else:
            n += 1
            mean = [m + (v - m) / n for m, v in zip(mean, r)]  # a running mean: no sum to overflow
    means.append(mean)
    return np.asarray(starts, dtype=int), np.asarray(means, dtype=float)


def _walk(y: np.ndarray, tol: float) -> np.ndarray:
    step = np.linalg.norm(np.diff(y, axis=0), axis=1)
    total = step.sum()
    if tol == 0.0:
        keep = np.concatenate([[True], step > _STILL_TOLERANCE * total]) if total > 0 else np.zeros(len(y), bool)
        keep[0] = True
        return np.flatnonzero(keep)
    rows = y.tolist()
    kept = [0]
    last = rows[0]
    dist = math.dist
    for i in range(1, len(rows)):
        r = rows[i]
        if dist(r, last) > tol:
            kept.append(i)
            last = r
    if kept[-1] != len(rows) - 1 and np.any(y[-1] != y[kept[-1]]):
        kept.append(len(rows) - 1)
    return np.asarray(kept, dtype=int)


def restart_vertex(vertices, tolerance: float = 0.0) -> int:
    """Where a motion that set off more than once last set off from its start: the vertex, or 0.

    An *excursion* is a run of vertices farther from the first vertex than
    :data:`RESTART_NEAR` times the farthest any vertex gets (``d_max``); it counts when it
    reaches :data:`RESTART_EXCURSION` ``d_max`` and :data:`RESTART_MIN_TOLERANCES`
    ``tolerance``. With two or more that count, the motion's start before the last one
    (a false start: the person set off, came back and set off again) is the vertex of the
    run near the start just before it that lies nearest the start; otherwise 0 (one
    excursion, possibly back to the start at the end, is the usual motion).

    Parameters
    ----------
    vertices : array, shape (M, D)
        A path's vertices (:func:`vertex_path`), or samples.
    tolerance : float
        The walk's tolerance (the units of ``vertices``).

    Returns
    -------
    int
        Index into ``vertices``; 0 when the motion did not set off more than once.
    """
    v = as_finite_array(vertices, "vertices", ndim=2, min_rows=1)
    d = np.linalg.norm(v - v[0], axis=1)
    d_max = float(d.max())
    if not d_max > 0:
        return 0
    away = d > RESTART_NEAR * d_max
    # runs of vertices away from the start: [begin, end) pairs
    edges = np.flatnonzero(np.diff(np.concatenate([[False], away, [False]]).astype(np.int8)))
    begins, ends = edges[0::2], edges[1::2]
    reach = max(RESTART_EXCURSION * d_max, RESTART_MIN_TOLERANCES * float(tolerance))
    counted = [b for b, e in zip(begins, ends) if d[b:e].max() >= reach]
    if len(counted) < 2:
        return 0
    last = counted[-1]
    first = int(ends[ends < last][-1])   # the run near the start before it begins where an excursion ended
    return first + int(np.argmin(d[first:last]))


def arc_length(y, tolerance: float = 0.0, *, adapt_to_noise: bool = False, glitches_removed: bool = False,
               average_holds: bool = True):
    """Path vertices and their cumulative arc length (see :func:`path_vertices`).

    Returns
    -------
    vertices : array, shape (M, D)
    s : array, shape (M,)
        ``s[0] = 0``, non-decreasing; ``s[-1]`` is the path length.
    """
    _, v, s = vertex_path(y, tolerance, adapt_to_noise=adapt_to_noise, glitches_removed=glitches_removed,
                          average_holds=average_holds)
    return v, s


def resample_by_arc_length(y, n_samples: int, tolerance: float = 0.0, *, adapt_to_noise: bool = False,
                           average_holds: bool = True) -> np.ndarray:
    """Resample a path at ``n_samples`` points equally spaced along its length.

    Robust to standing still (repeated points) at the start, the end or in
    between: those samples add no arc length and are dropped. With a positive
    ``tolerance`` (in the units of ``y``) the path is the polyline through
    :func:`path_vertices`, so noise smaller than the tolerance, also while
    standing still, adds no length either.

    Parameters
    ----------
    y : array, shape (T, D)
    n_samples : int
    tolerance : float

    Returns
    -------
    y_resampled : array, shape (n_samples, D)
    """
    y = as_finite_array(y, "trajectory", ndim=2, min_rows=2)
    if n_samples < 2:
        raise ValueError(f"n_samples must be >= 2, got {n_samples}")
    v, s = arc_length(y, tolerance, adapt_to_noise=adapt_to_noise, average_holds=average_holds)
    if not s[-1] > 0:
        raise ValueError("trajectory does not move: its path length is 0")
    grid = np.linspace(0.0, s[-1], n_samples)
    return np.stack([np.interp(grid, s, v[:, d]) for d in range(v.shape[1])], axis=1)


def resample_in_time(t, y, n_samples: int) -> np.ndarray:
    """Resample ``y(t)`` at ``n_samples`` times evenly spaced over ``[t0, tT]``.

    Parameters
    ----------
    t : array, shape (T,)
    y : array, shape (T, D)

    Returns
    -------
    y_resampled : array, shape (n_samples, D)
    """
    t = as_finite_array(t, "t", ndim=1, min_rows=2)
    check_increasing(t)
    y = as_finite_array(y, "trajectory", shape=(t.shape[0], None))
    if n_samples < 2:
        raise ValueError(f"n_samples must be >= 2, got {n_samples}")
    grid = np.linspace(t[0], t[-1], n_samples)
    return np.stack([np.interp(grid, t, y[:, d]) for d in range(y.shape[1])], axis=1)
