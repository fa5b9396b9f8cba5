"""The ``Demonstration`` type: one coupled human (+ robot) trajectory, and how it is written to a file.

The writers are here so that ``Demonstration.save`` needs nothing above this module;
the readers, folders and calibration files are in :mod:`drake_skills.data.demos`,
which also documents the layouts.
"""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drake_skills._checks import as_finite_array, check_increasing
from drake_skills._io import atomic_write

#: Fewest samples a demonstration may have (the basis fit needs a few points).
MIN_SAMPLES = 5


@dataclass(frozen=True, eq=False)
class Demonstration:
    """One demonstration: the observed agent (human) and, optionally, the robot.

    Parameters
    ----------
    t : array, shape (T,)
        Time stamps in seconds, strictly increasing.
    human : array, shape (T, D_h)
        Observed-agent positions (wrist in metres, D_h = 3; pen tip, D_h = 2).
    robot : array, shape (T, D_r), optional
        Controlled-agent positions (joint angles in radians), or None for
        human-only data (letters).
    task, subject : str, optional
        Labels, used only by evaluation; the library never reads them.
    name : str, optional
        Where the demonstration came from (file name), used in error messages.

    All arrays are validated (finite, finite spans, matching lengths, monotonic
    time, at least ``MIN_SAMPLES`` samples) and stored as read-only copies.
    """

    t: np.ndarray
    human: np.ndarray
    robot: np.ndarray | None = None
    task: str | None = None
    subject: str | None = None
    name: str | None = field(default=None, compare=False)

    def __post_init__(self):
        where = f"demo {self.name!r}" if self.name else "demonstration"
        t = as_finite_array(self.t, "t", ndim=1, min_rows=MIN_SAMPLES, where=where)
        check_increasing(t, "t", where=where)
        human = as_finite_array(self.human, "human", ndim=2, where=where)
        if human.shape[0] != t.shape[0]:
            raise ValueError(f"{where}: human has {human.shape[0]} rows but t has {t.shape[0]}")
        if human.shape[1] < 1:
            raise ValueError(f"{where}: human has no columns")
        robot = None
        if self.robot is not None:
            robot = as_finite_array(self.robot, "robot", ndim=2, where=where)
            if robot.shape[0] != t.shape[0]:
                raise ValueError(f"{where}: robot has {robot.shape[0]} rows but t has {t.shape[0]}")
            if robot.shape[1] < 1:
                raise ValueError(f"{where}: robot has no columns")
        with np.errstate(over="ignore", invalid="ignore"):
            spans = [("t", float(t[-1] - t[0]))] + [
                (label, float(np.ptp(a, axis=0).max())) for label, a in (("human", human), ("robot", robot))
                if a is not None]
        for label, span in spans:
            if not np.isfinite(span):
                raise ValueError(f"{where}: {label} spans more than the largest float "
                                 f"({'duration' if label == 't' else 'range'} {span}); check the units")
        # own read-only copies: the caller's arrays stay writable, and a later write to them
        # (or to the array they view) cannot change a demonstration the library has learned
        t, human = np.array(t, copy=True), np.array(human, copy=True)
        robot = None if robot is None else np.array(robot, copy=True)
        for a in (t, human, robot):
            if a is not None:
                a.setflags(write=False)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "human", human)
        object.__setattr__(self, "robot", robot)
        for label in ("task", "subject"):
            v = getattr(self, label)
            if v is not None:
                object.__setattr__(self, label, str(v))

    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def dim_human(self) -> int:
        return int(self.human.shape[1])

    @property
    def dim_robot(self) -> int:
        return 0 if self.robot is None else int(self.robot.shape[1])

    def save(self, path: str | Path) -> Path:
        """Write the demonstration to ``path``, as ``.npz`` or ``.csv`` by its suffix.

        npz: arrays ``t`` (T,), ``human`` (T, D_h), ``robot`` (T, D_r) if any, and the
        labels as 0-d strings; CSV: header ``t,hx,hy,hz,q1,...,q7[,task,subject]``
        (``h1..hD`` for more than 3 human columns), 17 significant digits, so both
        read back exactly with :func:`drake_skills.data.demos.load_demo`. The write
        is atomic.

        Returns
        -------
        Path
            The written file.
        """
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix == ".npz":
            return save_npz(self, path)
        if suffix == ".csv":
            return save_csv(self, path)
        raise ValueError(f"demo '{path}': cannot save as {path.suffix or 'a file without suffix'}; "
                         f"use .npz or .csv")

    def __repr__(self) -> str:
        r = "None" if self.robot is None else f"{self.robot.shape}"
        return (f"Demonstration(T={self.n_samples}, human={self.human.shape}, robot={r}, "
                f"task={self.task!r}, subject={self.subject!r})")


def human_columns(d: int) -> list[str]:
    """CSV names of ``d`` human columns: ``hx, hy, hz`` (up to 3), else ``h1 .. hD``."""
    return list(("hx", "hy", "hz")[:d]) if d <= 3 else [f"h{i + 1}" for i in range(d)]


def save_npz(demo: Demonstration, path: str | Path) -> Path:
    """Write ``demo`` to ``path`` (.npz, uncompressed, no pickled objects).

    Returns
    -------
    Path
        The written file.
    """
    path = Path(path)
    arrays = {"t": demo.t, "human": demo.human}
    if demo.robot is not None:
        arrays["robot"] = demo.robot
    for label in ("task", "subject"):
        value = getattr(demo, label)
        if value is not None:
            arrays[label] = np.array(value, dtype=str)
    atomic_write(path, lambda f: np.savez(f, **arrays))
    return path


def save_csv(demo: Demonstration, path: str | Path) -> Path:
    """Write ``demo`` as CSV with header ``t,hx,hy,hz,q1,...,q7[,task,subject]``.

    Numbers are written with 17 significant digits (exact float64 round trip).
    """
    path = Path(path)
    header = ["t"] + human_columns(demo.dim_human) + [f"q{i + 1}" for i in range(demo.dim_robot)]
    labels = [k for k in ("task", "subject") if getattr(demo, k) is not None]
    header += labels
    cols = [demo.t[:, None], demo.human] + ([demo.robot] if demo.robot is not None else [])
    data = np.concatenate(cols, axis=1)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    extra = [getattr(demo, k) for k in labels]
    for row in data:
        w.writerow([repr(float(x)) for x in row] + extra)
    atomic_write(path, lambda f: f.write(buf.getvalue().encode()))
    return path
