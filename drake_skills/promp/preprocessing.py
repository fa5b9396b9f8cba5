"""Preprocessing: arc-length resampling and personal-workspace normalization (Eq. 14).

Human motions are resampled at equidistant points along their path, so the
representation does not depend on the speed of the demonstration; robot
trajectories are resampled uniformly in time.  Positions are normalized to
[0, 10] with a subject's workspace, found from calibration motions, and the
normalized start position is subtracted (Eq. 14).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from drake_skills._checks import as_finite_array, check_increasing

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
    tol2 = tol * tol
    for i in range(1, len(rows)):
        r = rows[i]
        if sum((a - b) * (a - b) for a, b in zip(r, last)) > tol2:
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


@dataclass(frozen=True, eq=False)
class Workspace:
    """A subject's personal workspace: per-axis bounds mapped to [0, scale].

    Parameters
    ----------
    lower, upper : array, shape (D,)
        Per-axis bounds (``upper > lower``).
    scale : float
        Normalized range is ``[0, scale]`` (the paper uses 10).
    """

    lower: np.ndarray
    upper: np.ndarray
    scale: float = 10.0

    def __post_init__(self):
        lo = as_finite_array(self.lower, "workspace lower bound", ndim=1)
        hi = as_finite_array(self.upper, "workspace upper bound", shape=lo.shape)
        if (hi <= lo).any():
            axes = np.nonzero(hi <= lo)[0].tolist()
            raise ValueError(f"workspace is empty along axes {axes}: upper <= lower")
        if not np.isfinite(self.scale) or self.scale <= 0:
            raise ValueError(f"scale must be positive, got {self.scale!r}")
        lo.setflags(write=False)
        hi.setflags(write=False)
        object.__setattr__(self, "lower", lo)
        object.__setattr__(self, "upper", hi)
        object.__setattr__(self, "scale", float(self.scale))

    @property
    def dim(self) -> int:
        return int(self.lower.shape[0])

    @classmethod
    def from_calibration(cls, motions: Sequence, *, z_factor: float | None = None, z_axis: int = 2,
                         scale: float = 10.0) -> "Workspace":
        """Bounds from calibration motions (per-axis min and max, Sec. 4.2.2).

        Parameters
        ----------
        motions : sequence of arrays, shape (T_i, D)
            E.g. the half circles in the x-y and z-y planes.
        z_factor : float, optional
            Keep only this fraction of the range along ``z_axis``, shrunk about
            its centre (the paper uses 0.9: people stretch out more when
            calibrating than when working).
        """
        if len(motions) == 0:
            raise ValueError("no calibration motions given")
        arrays = [as_finite_array(m, f"calibration motion {i}", ndim=2, min_rows=2)
                  for i, m in enumerate(motions)]
        dims = {a.shape[1] for a in arrays}
        if len(dims) != 1:
            raise ValueError(f"calibration motions have different dimensions: {sorted(dims)}")
        data = np.concatenate(arrays)
        lo, hi = data.min(axis=0), data.max(axis=0)
        if z_factor is not None:
            if not 0 < z_factor <= 1:
                raise ValueError(f"z_factor must be in (0, 1], got {z_factor!r}")
            if not 0 <= z_axis < lo.shape[0]:
                raise ValueError(f"z_axis {z_axis} out of range for {lo.shape[0]}-D data")
            c, half = 0.5 * (lo[z_axis] + hi[z_axis]), 0.5 * z_factor * (hi[z_axis] - lo[z_axis])
            lo[z_axis], hi[z_axis] = c - half, c + half
        return cls(lo, hi, scale)

    def normalize(self, y, *, subtract_start: bool = True) -> np.ndarray:
        """Eq. (14): ``scale (y - lower) / (upper - lower)``, minus its first point.

        Parameters
        ----------
        y : array, shape (T, D)

        Returns
        -------
        y_norm : array, shape (T, D)
        """
        y = as_finite_array(y, "trajectory", shape=(None, self.dim))
        yn = self.scale * (y - self.lower) / (self.upper - self.lower)
        if subtract_start:
            yn = yn - yn[0]
        return yn

    def denormalize(self, y_norm, *, start=None) -> np.ndarray:
        """Inverse of :meth:`normalize`.

        Parameters
        ----------
        y_norm : array, shape (T, D)
        start : array, shape (D,), optional
            The raw start position that was subtracted; omit if
            ``subtract_start=False`` was used.
        """
        yn = as_finite_array(y_norm, "normalized trajectory", shape=(None, self.dim))
        if start is not None:
            start = as_finite_array(start, "start", shape=(self.dim,))
            yn = yn + self.scale * (start - self.lower) / (self.upper - self.lower)
        return self.lower + yn * (self.upper - self.lower) / self.scale

    def dict(self) -> dict:
        return {"lower": self.lower.tolist(), "upper": self.upper.tolist(), "scale": self.scale}

    @classmethod
    def from_dict(cls, d: dict) -> "Workspace":
        return cls(np.asarray(d["lower"], float), np.asarray(d["upper"], float), float(d.get("scale", 10.0)))

    def __repr__(self) -> str:
        return f"Workspace(lower={self.lower.round(4).tolist()}, upper={self.upper.round(4).tolist()})"
