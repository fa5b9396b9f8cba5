"""``Workspace``: a subject's personal workspace, from calibration motions, and Eq. (14).

A data type like :class:`~drake_skills.data.demonstration.Demonstration`: the
calibration motions are recorded with the demonstrations, the workspace is
stored in library files and configs, and every layer above normalizes with
:meth:`Workspace.normalize` (the one implementation of Eq. 14).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from drake_skills._checks import as_finite_array
from drake_skills._io import atomic_write


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
        lo = as_finite_array(self.lower, "workspace lower bound", ndim=1, min_rows=1)
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

    def save(self, path: str | Path) -> Path:
        """Write ``{"lower": [...], "upper": [...], "scale": 10.0}`` as JSON (a ``workspace.json``)."""
        path = Path(path)
        text = json.dumps(self.dict(), indent=1) + "\n"
        atomic_write(path, lambda f: f.write(text.encode()))
        return path

    @classmethod
    def load(cls, path: str | Path) -> "Workspace":
        """Read a workspace written by :meth:`save` (or by hand: ``lower`` and ``upper`` lists, optional ``scale``).

        Raises
        ------
        ValueError
            Naming the file: not JSON, missing or unknown keys, bounds of different
            lengths, not numbers, or an empty range on an axis.
        """
        path = Path(path)
        where = f"workspace '{path}'"
        if not path.is_file():
            raise FileNotFoundError(f"{where}: no such file")
        try:
            d = json.loads(path.read_text())
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ValueError(f"{where}: not a JSON file ({exc})") from None
        if not isinstance(d, dict) or not {"lower", "upper"} <= set(d) or set(d) - {"lower", "upper", "scale"}:
            keys = sorted(d) if isinstance(d, dict) else type(d).__name__
            raise ValueError(f"{where}: expected an object with 'lower', 'upper' (and 'scale'), got {keys}")
        try:
            return cls.from_dict(d)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{where}: {exc}") from None

    def __repr__(self) -> str:
        return f"Workspace(lower={self.lower.round(4).tolist()}, upper={self.upper.round(4).tolist()})"
