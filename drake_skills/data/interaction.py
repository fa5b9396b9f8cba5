"""Recorded interactions stored back to back in one ``.npz``: the layout of ``buetepage_hr.npz``.

Layout (``../shared/data/README.md``)::

    human       (N, D)   the observed person, all interactions concatenated (buetepage_hr:
                         right arm, metres, shoulder xyz | elbow xyz | hand xyz)
    robot       (N, R)   optional: the robot's joints, aligned row by row with ``human``
    offsets     (M + 1,) interaction i is rows offsets[i]:offsets[i + 1]; offsets[0] = 0,
                         offsets[-1] = N, strictly increasing
    task        (M,)     optional: task name per interaction
    split       (M,)     optional: "train" or "test" (the source's split), per interaction
    active_end  (M,)     optional: sample index (within the interaction) after which the
                         person is at rest

The samples are uniform in time; the file does not store the rate, so
:func:`load_interactions` takes it (buetepage_hr: not stated by the source, 100 Hz
assumed). Nothing is copied: the file is read from its path, with
``allow_pickle=False``, and every problem raises ``ValueError`` naming the file.
"""
from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import Sequence

import numpy as np

from drake_skills.data.demonstration import MIN_SAMPLES, Demonstration
from drake_skills.data.demos import _read_npz

#: Named column selections of ``human`` in the buetepage_hr layout (shoulder, elbow, hand xyz).
COLUMNS = {"hand": slice(6, 9), "wrist": slice(6, 9), "arm": slice(0, 9), "elbow": slice(3, 6),
           "shoulder": slice(0, 3)}
#: Values of the optional ``split`` array.
SPLITS = ("train", "test")
#: Environment variable naming the shared folder (the one holding ``data/``) when it is not beside the repository.
SHARED_ENV = "DRAKE_SKILLS_SHARED"


def shared_data_path(name: str = "buetepage_hr.npz") -> Path:
    """Where a shared data file is expected: ``$DRAKE_SKILLS_SHARED/data/<name>``, else ``../shared/data/<name>``.

    ``$DRAKE_SKILLS_SHARED`` names the shared folder (the one that holds ``data/``); a
    folder holding the file itself also works. Without it the file is looked for beside
    the repository root (``<repo>/../shared/data``, the layout of the project's machines
    and CI), then relative to the working directory. The path is returned whether or not
    the file exists (callers say which path is missing).
    """
    env = os.environ.get(SHARED_ENV)
    if env:
        base = Path(env).expanduser()
        direct = base / name
        return direct if direct.is_file() and not (base / "data" / name).is_file() else base / "data" / name
    repo = Path(__file__).resolve().parents[2]
    candidates = [repo.parent / "shared" / "data" / name, Path.cwd().parent / "shared" / "data" / name]
    return next((c for c in candidates if c.is_file()), candidates[0])


class Interactions(list):
    """The interactions of one file: a ``list`` of :class:`Demonstration`, plus what the file says of each.

    Attributes
    ----------
    path : Path
        The file read.
    split : tuple of str or None, shape (M,)
        "train" / "test" per interaction (None everywhere if the file has no ``split``).
    active_end : tuple of int or None, shape (M,)
        Sample index after which the person is at rest (None if the file has no ``active_end``).
    columns : tuple of int
        The columns of the file's ``human`` array each demonstration holds.
    rate_hz : float
        The sampling rate the time stamps were made with.
    """

    def __init__(self, demos: Sequence[Demonstration], *, path: Path, split, active_end, columns, rate_hz: float):
        super().__init__(demos)
        self.path = Path(path)
        self.split = tuple(split)
        self.active_end = tuple(active_end)
        self.columns = tuple(int(c) for c in columns)
        self.rate_hz = float(rate_hz)

    def subset(self, split: str) -> list[Demonstration]:
        """The demonstrations of one split ("train" or "test"), in file order."""
        if split not in SPLITS:
            raise ValueError(f"split must be one of {SPLITS}, got {split!r}")
        if all(s is None for s in self.split):
            raise ValueError(f"interactions '{self.path}': the file has no 'split' array")
        return [d for d, s in zip(self, self.split) if s == split]

    @property
    def train(self) -> list[Demonstration]:
        return self.subset("train")

    @property
    def test(self) -> list[Demonstration]:
        return self.subset("test")

    @property
    def tasks(self) -> tuple[str, ...]:
        """The distinct task names, in order of first appearance."""
        return tuple(dict.fromkeys(d.task for d in self if d.task is not None))


def column_selection(text: str, name: str = "columns"):
    """A command line's column selection: a name of :data:`COLUMNS` (kept as the name) or ``START:STOP``.

    ``START:STOP`` becomes the explicit indices ``START .. STOP - 1`` (a slice would clip silently;
    :func:`load_interactions` checks each against the file), e.g. ``0:3`` for a file whose
    ``human`` holds only a wrist. Raises ``ValueError`` naming the setting (``name``, e.g.
    ``--columns``) and the accepted forms.
    """
    text = str(text).strip()
    if text in COLUMNS:
        return text
    try:
        start, stop = (int(x) for x in text.split(":"))
    except ValueError:
        raise ValueError(f"{name} must be START:STOP (e.g. 6:9 or 0:3) or one of {sorted(COLUMNS)}, "
                         f"got {text!r}") from None
    if not 0 <= start < stop:
        raise ValueError(f"{name} {text}: need 0 <= START < STOP")
    return list(range(start, stop))


def _column_indices(columns, n_columns: int, where: str) -> np.ndarray:
    label = columns
    if isinstance(columns, str):
        if columns not in COLUMNS:
            raise ValueError(f"{where}: unknown column selection {columns!r}; named ones are {sorted(COLUMNS)}")
        if columns in ("hand", "wrist") and n_columns == 3:  # a file that holds a wrist only: that is the hand
            return np.arange(3)
        if n_columns == 3:  # the other body parts are not in a wrist-only file (shoulder's 0:3 would be the wrist)
            raise ValueError(f"{where}: the column selection {columns!r} picks none of the 3 human columns (a file "
                             f"of 3 columns holds a wrist: 'hand', or give the columns as START:STOP, e.g. 0:3)")
        columns = COLUMNS[columns]
    if isinstance(columns, slice):
        idx = np.arange(n_columns)[columns]
    else:
        try:
            idx = np.asarray(columns)
        except (TypeError, ValueError):
            raise ValueError(f"{where}: columns must be a slice, a name or a sequence of ints, "
                             f"got {columns!r}") from None
        if idx.ndim != 1 or idx.dtype.kind not in "iu":
            raise ValueError(f"{where}: columns must be a slice, a name or a sequence of ints, got {columns!r}")
        bad = idx[(idx < 0) | (idx >= n_columns)]
        if bad.size:
            raise ValueError(f"{where}: columns {bad.tolist()} out of range: human has {n_columns} columns")
    if idx.size == 0:
        raise ValueError(f"{where}: the column selection {label!r} picks none of the {n_columns} human columns"
                         f" (the named selections are those of the buetepage_hr layout, 9 columns: shoulder, elbow, "
                         f"hand; give the columns as START:STOP, e.g. 0:{n_columns} for all)")
    if len(set(idx.tolist())) != idx.size:
        raise ValueError(f"{where}: the column selection {columns!r} repeats a column")
    return idx


def _per_interaction(contents: dict, key: str, m: int, where: str, kind: str):
    if key not in contents:
        return None
    a = contents[key]
    if a.ndim != 1 or a.shape[0] != m:
        raise ValueError(f"{where}: '{key}' has shape {a.shape}, expected ({m},): one per interaction "
                         f"(offsets has {m + 1} entries)")
    if kind == "str" and a.dtype.kind != "U":
        raise ValueError(f"{where}: '{key}' has dtype {a.dtype}, expected strings")
    if kind == "int" and a.dtype.kind not in "iu":
        raise ValueError(f"{where}: '{key}' has dtype {a.dtype}, expected integers")
    return a


def _nan_rows(a: np.ndarray) -> np.ndarray:
    return np.flatnonzero(~np.isfinite(a).all(axis=1))


#: Default longest run of missing samples (NaN/inf: a tracker that lost the joint) that
#: :func:`load_interactions` fills, in seconds (the gating's ``DecisionRule.lost_timeout``).
MAX_GAP_S = 0.5


class GapWarning(UserWarning):
    """Missing samples (NaN/inf) of an interactions file were filled by linear interpolation."""


def _fill_gaps(a: np.ndarray, max_run: int) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """``a`` (T, D) with every lost (NaN/inf) entry filled, column by column: linearly between the valid entries
    around it, or by the nearest valid one at either end; the runs are of rows holding any lost entry.

    Returns the filled copy and the runs (start, stop) filled; raises ``ValueError`` (no message: the caller
    names the place) if a run is longer than ``max_run`` rows or a column has no valid entry."""
    bad = ~np.isfinite(a).all(axis=1)
    if not bad.any():
        return a, []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], bad.astype(np.int8), [0]])))
    runs = [(int(b), int(e)) for b, e in zip(edges[::2], edges[1::2])]
    for b, e in runs:
        if e - b > max_run:
            raise ValueError((b, e, False))
    out = np.array(a, dtype=float)
    for d in range(a.shape[1]):   # each column over its own lost entries: a row's valid readings stay
        lost = ~np.isfinite(out[:, d])
        if lost.any():
            if lost.all():
                raise ValueError((0, len(a), True))
            out[lost, d] = np.interp(np.flatnonzero(lost), np.flatnonzero(~lost), out[~lost, d])  # ends held
    return out, runs


def load_interactions(path, columns="hand", rate_hz: float = 100.0, *,
                      max_gap_s: float = MAX_GAP_S) -> Interactions:
    """Read the interactions of a file in the layout above, one :class:`Demonstration` each.

    Parameters
    ----------
    path : str or Path
        The ``.npz`` file (e.g. ``../shared/data/buetepage_hr.npz``); read in place.
    columns : slice, sequence of int, or str
        Which columns of ``human`` the demonstrations hold: the hand by default
        ("hand": ``slice(6, 9)``), ``slice(0, 9)`` for the whole arm; or a name from
        :data:`COLUMNS` ("hand", "arm", "elbow", "shoulder"). The names are those of the
        buetepage_hr layout; "hand" (or "wrist") of a file whose ``human`` has 3 columns is
        those 3 columns.
    rate_hz : float
        Sampling rate: ``t = arange(T_i) / rate_hz`` seconds for each interaction.
    max_gap_s : float
        Rows with NaN/inf in the selected human columns or the robot columns (a tracker
        that lost the joint) are filled by linear interpolation between the rows around
        each run (held at either end of an interaction) when the run lasts at most this
        long; a :class:`GapWarning` says how many. A longer run raises ``ValueError``
        naming it. 0: refuse any.

    Returns
    -------
    Interactions
        A ``list[Demonstration]`` in file order; demonstration ``i`` has ``t`` (T_i,),
        ``human`` (T_i, len(columns)), ``robot`` (T_i, R) or None, ``task`` from the file,
        and ``name`` ``"<file stem>:<i, 3 digits>[:<split>]"`` (e.g.
        ``"buetepage_hr:017:train"``). The list's ``split`` and ``active_end`` hold the
        per-interaction annotations; ``.train`` and ``.test`` the two splits.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        Naming the file and the problem: not an npz, pickled objects, a missing key,
        a non-numeric or non-2-D array, offsets that do not start at 0, end at N or
        increase, lengths that disagree, an interaction shorter than ``MIN_SAMPLES``,
        NaN/inf runs longer than ``max_gap_s`` (with the interaction and its rows), a bad split value or an
        ``active_end`` outside its interaction.
    """
    path = Path(path)
    where = f"interactions '{path}'"
    rate = float(rate_hz)
    if not np.isfinite(rate) or rate <= 0:
        raise ValueError(f"{where}: rate_hz must be positive, got {rate_hz!r}")
    gap = float(max_gap_s)
    if not np.isfinite(gap) or gap < 0:
        raise ValueError(f"{where}: max_gap_s must be >= 0, got {max_gap_s!r}")
    max_run = int(np.floor(gap * rate + 1e-9))
    if not path.is_file():
        raise FileNotFoundError(f"{where}: no such file")
    contents = _read_npz(path, where)
    missing = [k for k in ("human", "offsets") if k not in contents]
    if missing:
        raise ValueError(f"{where}: missing key(s) {missing}; the file has {sorted(contents)}")
    human = contents["human"]
    if human.dtype.kind not in "fiu" or human.ndim != 2:
        raise ValueError(f"{where}: 'human' must be a 2-D numeric array (N, D), got dtype {human.dtype} "
                         f"shape {human.shape}")
    n = human.shape[0]
    robot = contents.get("robot")
    if robot is not None:
        if robot.dtype.kind not in "fiu" or robot.ndim != 2:
            raise ValueError(f"{where}: 'robot' must be a 2-D numeric array (N, R), got dtype {robot.dtype} "
                             f"shape {robot.shape}")
        if robot.shape[0] != n:
            raise ValueError(f"{where}: 'robot' has {robot.shape[0]} rows but 'human' has {n}")
    offsets = contents["offsets"]
    if offsets.ndim != 1 or offsets.dtype.kind not in "iu" or offsets.shape[0] < 2:
        raise ValueError(f"{where}: 'offsets' must be a 1-D integer array of at least 2 entries, got dtype "
                         f"{offsets.dtype} shape {offsets.shape}")
    offsets = offsets.astype(np.int64)
    if offsets[0] != 0 or offsets[-1] != n:
        raise ValueError(f"{where}: 'offsets' must run from 0 to the {n} rows of 'human', "
                         f"got {int(offsets[0])} .. {int(offsets[-1])}")
    steps = np.diff(offsets)
    if (steps <= 0).any():
        i = int(np.flatnonzero(steps <= 0)[0])
        raise ValueError(f"{where}: 'offsets' is not increasing: offsets[{i}]={int(offsets[i])} then "
                         f"offsets[{i + 1}]={int(offsets[i + 1])}")
    m = offsets.shape[0] - 1
    short = np.flatnonzero(steps < MIN_SAMPLES)
    if short.size:
        i = int(short[0])
        raise ValueError(f"{where}: interaction {i} has {int(steps[i])} samples, need at least {MIN_SAMPLES}")
    task = _per_interaction(contents, "task", m, where, "str")
    split = _per_interaction(contents, "split", m, where, "str")
    active_end = _per_interaction(contents, "active_end", m, where, "int")
    if split is not None:
        bad = sorted(set(split.tolist()) - set(SPLITS))
        if bad:
            raise ValueError(f"{where}: 'split' holds {bad}; values must be {SPLITS}")
    if active_end is not None:
        out = np.flatnonzero((active_end < 1) | (active_end > steps))
        if out.size:
            i = int(out[0])
            raise ValueError(f"{where}: active_end[{i}] = {int(active_end[i])} is outside interaction {i} "
                             f"({int(steps[i])} samples)")
    idx = _column_indices(columns, human.shape[1], where)
    parts = {"human": human[:, idx], "robot": robot}
    filled: dict[str, list] = {"human": [], "robot": []}
    for key, a in parts.items():
        if a is None or not _nan_rows(a.astype(float, copy=False)).size:
            continue
        pieces = []
        for i in range(m):
            lo, hi = int(offsets[i]), int(offsets[i + 1])
            try:
                piece, runs = _fill_gaps(a[lo:hi].astype(float), max_run)
            except ValueError as e:
                b, e_, everywhere = e.args[0]
                if everywhere:
                    raise ValueError(f"{where}: '{key}' has NaN/inf in every row of interaction {i} "
                                     f"({e_} rows): nothing to fill from") from None
                raise ValueError(f"{where}: '{key}' has NaN/inf in interaction {i} at rows {b}..{e_ - 1} "
                                 f"({(e_ - b) / rate:.3g} s at {rate:g} Hz; at most max_gap_s = {gap:g} s is filled "
                                 f"by interpolation): fill or cut them, or allow a longer gap") from None
            pieces.append(piece)
            filled[key] += [(i, b, e_) for b, e_ in runs]
        parts[key] = np.concatenate(pieces)
    runs = filled["human"] + filled["robot"]
    if runs:
        longest = max(e - b for _, b, e in runs)
        where_filled = sorted({i for i, _, _ in runs})
        warnings.warn(f"{where}: filled {len(runs)} run(s) of NaN/inf samples by linear interpolation (longest "
                      f"{longest} row(s), {longest / rate:.3g} s) in interaction(s) {where_filled[:10]}"
                      f"{' ...' if len(where_filled) > 10 else ''}: human {len(filled['human'])}, robot "
                      f"{len(filled['robot'])}", GapWarning, stacklevel=2)
    human_sel, robot_all = parts["human"], parts["robot"]
    stem = path.stem
    demos = []
    for i in range(m):
        a, b = int(offsets[i]), int(offsets[i + 1])
        name = f"{stem}:{i:03d}" + (f":{split[i]}" if split is not None else "")
        demos.append(Demonstration(t=np.arange(b - a) / rate, human=human_sel[a:b],
                                   robot=None if robot_all is None else robot_all[a:b],
                                   task=None if task is None else str(task[i]), name=name))
    return Interactions(demos, path=path, split=[None] * m if split is None else [str(s) for s in split],
                        active_end=[None] * m if active_end is None else [int(e) for e in active_end],
                        columns=idx, rate_hz=rate)
