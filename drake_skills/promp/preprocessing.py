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

from drake_skills._checks import as_finite_array, check_increasing
from drake_skills.data.workspace import Workspace

__all__ = ["Workspace", "arc_length", "path_vertices", "resample_by_arc_length", "resample_in_time",
           "vertex_indices"]

#: Points closer than this (in the trajectory's units, relative to the path
#: length) count as standing still and are dropped before resampling.
_STILL_TOLERANCE = 1e-9


def path_vertices(y, tolerance: float = 0.0) -> np.ndarray:
    """The samples that carry a path on: noise and standing still removed.

    Walks the samples in order and keeps one when it lies more than
    ``tolerance`` from the last kept one; the first sample is always kept and
    the last one whenever it moved at all. Sensor noise while the hand stands
    still (or moves slowly) then adds no path length: with noise of 0.5 mm at
    150 Hz, the raw arc length of a simulated salad reach is 20-40 % longer
    than its path and grows with every sample of the hold at the end. The walk is causal, so a
    prefix of a motion keeps a prefix of the vertices, and an observed prefix is
    parametrized exactly as the start of the whole motion.

    Parameters
    ----------
    y : array, shape (T, D)
    tolerance : float
        In the units of ``y``; 0 keeps every sample that moves at all (only
        exact repeats are dropped).

    Returns
    -------
    vertices : array, shape (M, D), M >= 1
    """
    y = as_finite_array(y, "trajectory", ndim=2, min_rows=2)
    return y[vertex_indices(y, tolerance)]


def vertex_indices(y, tolerance: float = 0.0) -> np.ndarray:
    """Indices of the samples :func:`path_vertices` keeps (increasing, first is 0)."""
    y = as_finite_array(y, "trajectory", ndim=2, min_rows=2)
    tol = float(tolerance)
    if not (np.isfinite(tol) and tol >= 0):
        raise ValueError(f"tolerance must be a finite number >= 0, got {tolerance!r}")
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


def arc_length(y, tolerance: float = 0.0):
    """Path vertices and their cumulative arc length (see :func:`path_vertices`).

    Returns
    -------
    vertices : array, shape (M, D)
    s : array, shape (M,)
        ``s[0] = 0``, non-decreasing; ``s[-1]`` is the path length.
    """
    v = path_vertices(y, tolerance)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(v, axis=0), axis=1))])
    return v, s


def resample_by_arc_length(y, n_samples: int, tolerance: float = 0.0) -> np.ndarray:
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
    v, s = arc_length(y, tolerance)
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
