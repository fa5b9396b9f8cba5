"""Demonstration files: one ``.npz`` or ``.csv`` per demonstration, and calibration files.

npz
    Arrays ``t`` (T,), ``human`` (T, D_h), optional ``robot`` (T, D_r), optional 0-d
    string arrays ``task`` and ``subject``. Loaded with ``allow_pickle=False``.
csv
    Header ``t,hx,hy,hz,q1,...,q7[,task,subject]``: time, then the human columns
    (``hx, hy, hz`` for D_h <= 3, else ``h1 .. hD``), then the robot columns
    ``q1 .. qD`` (none for human-only data), then optional label columns.
Calibration
    ``calibration.npz`` with one (T_i, D) array per motion (``xy``, ``zy`` for the salad
    scenario); :func:`load_dir` skips it.

Every malformed file raises ``ValueError`` naming the file and the problem.
"""
from __future__ import annotations

import csv
import io
import re
import zipfile
from pathlib import Path

import numpy as np

from drake_skills._checks import as_finite_array
from drake_skills._io import atomic_write
from drake_skills.data.demonstration import Demonstration

#: Suffixes of demonstration files.
DEMO_SUFFIXES = (".npz", ".csv")
_HUMAN_XYZ = ("hx", "hy", "hz")


def _read_npz(path: Path, where: str) -> dict[str, np.ndarray]:
    """The arrays of an npz archive, never unpickling anything.

    A file that is not a zip archive is rejected before numpy sees it: numpy
    would try to read it as a pickle and suggest ``allow_pickle=True``.
    """
    if not zipfile.is_zipfile(path):
        raise ValueError(f"{where}: not an npz file (not a zip archive; truncated or another format?)")
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except ValueError as exc:
        if "pickle" in str(exc):
            raise ValueError(f"{where}: holds Python objects (pickled data), which are never loaded") from None
        raise ValueError(f"{where}: cannot read npz ({exc})") from None
    except (OSError, zipfile.BadZipFile, EOFError) as exc:
        raise ValueError(f"{where}: not an npz file ({exc})") from None


# --------------------------------------------------------------------------- npz
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


def _numeric(a: np.ndarray, key: str, where: str) -> np.ndarray:
    if a.dtype.kind not in "fiu":
        raise ValueError(f"{where}: '{key}' has dtype {a.dtype}, expected numbers")
    return a


def _label(a: np.ndarray, key: str, where: str) -> str:
    if a.dtype.kind != "U" or a.ndim != 0:
        raise ValueError(f"{where}: '{key}' must be a single string, got dtype {a.dtype} shape {a.shape}")
    return str(a)


def load_npz(path: str | Path) -> Demonstration:
    """Read a demonstration written by :func:`save_npz`.

    Raises
    ------
    ValueError
        Naming the file and the problem: not an npz, pickled objects, missing or
        non-numeric arrays, NaN/inf, mismatched lengths, non-monotonic or too short time.
    """
    path = Path(path)
    where = f"demo '{path}'"
    if not path.is_file():
        raise FileNotFoundError(f"{where}: no such file")
    contents = _read_npz(path, where)
    missing = [k for k in ("t", "human") if k not in contents]
    if missing:
        raise ValueError(f"{where}: missing array(s) {missing}; has {sorted(contents)}")
    t = _numeric(contents["t"], "t", where)
    human = _numeric(contents["human"], "human", where)
    robot = _numeric(contents["robot"], "robot", where) if "robot" in contents else None
    labels = {k: _label(contents[k], k, where) for k in ("task", "subject") if k in contents}
    return Demonstration(t=t, human=human, robot=robot, name=str(path), **labels)


# --------------------------------------------------------------------------- csv
def _human_columns(d: int) -> list[str]:
    return list(_HUMAN_XYZ[:d]) if d <= 3 else [f"h{i + 1}" for i in range(d)]


def save_csv(demo: Demonstration, path: str | Path) -> Path:
    """Write ``demo`` as CSV with header ``t,hx,hy,hz,q1,...,q7[,task,subject]``.

    Numbers are written with 17 significant digits (exact float64 round trip).
    """
    path = Path(path)
    header = ["t"] + _human_columns(demo.dim_human) + [f"q{i + 1}" for i in range(demo.dim_robot)]
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


def load_csv(path: str | Path) -> Demonstration:
    """Read a demonstration written by :func:`save_csv` (or by hand, same header).

    Raises
    ------
    ValueError
        Naming the file and the problem: empty file, missing ``t`` or human columns,
        unknown columns, rows of the wrong length, non-numbers, NaN, non-monotonic time.
    """
    path = Path(path)
    where = f"demo '{path}'"
    if not path.is_file():
        raise FileNotFoundError(f"{where}: no such file")
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        raise ValueError(f"{where}: not a text (CSV) file") from None
    rows = list(csv.reader(io.StringIO(text)))
    rows = [r for r in rows if r and any(c.strip() for c in r)]
    if not rows:
        raise ValueError(f"{where}: empty file, expected a header t,hx,hy,hz,q1,...")
    header = [c.strip() for c in rows[0]]
    if not header or header[0] != "t":
        raise ValueError(f"{where}: first column must be 't', header is {','.join(header)!r}")
    if len(set(header)) != len(header):
        raise ValueError(f"{where}: duplicate column names in header {','.join(header)!r}")
    human = [i for i, c in enumerate(header) if c in _HUMAN_XYZ or re.fullmatch(r"h\d+", c)]
    robot = [i for i, c in enumerate(header) if re.fullmatch(r"q\d+", c)]
    labels = {c: i for i, c in enumerate(header) if c in ("task", "subject")}
    unknown = [c for i, c in enumerate(header)
               if i and i not in human and i not in robot and c not in labels]
    if unknown:
        raise ValueError(f"{where}: unknown column(s) {unknown}; expected t, hx.. (or h1..), q1.., task, subject")
    if not human:
        raise ValueError(f"{where}: no human columns (hx, hy, hz or h1, h2, ...) in header {','.join(header)!r}")
    names = [header[i] for i in human]
    if names != _human_columns(len(human)):
        raise ValueError(f"{where}: human columns must be {_human_columns(len(human))}, got {names}")
    if [header[i] for i in robot] != [f"q{k + 1}" for k in range(len(robot))]:
        raise ValueError(f"{where}: robot columns must be q1..q{len(robot)} in order, got {[header[i] for i in robot]}")
    numeric = [0] + human + robot
    values = np.empty((len(rows) - 1, len(numeric)))
    for r, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise ValueError(f"{where}: line {r} has {len(row)} fields, header has {len(header)}")
        try:
            values[r - 2] = [float(row[i]) for i in numeric]
        except ValueError:
            bad = next(header[i] for i in numeric if not _is_float(row[i]))
            raise ValueError(f"{where}: line {r}, column '{bad}' is not a number") from None
    kw = {}
    for c, i in labels.items():
        vals = {row[i] for row in rows[1:]}
        if len(vals) > 1:
            raise ValueError(f"{where}: column '{c}' must hold one value, has {sorted(vals)[:3]}")
        if vals:
            kw[c] = vals.pop()
    n_h = len(human)
    return Demonstration(t=values[:, 0], human=values[:, 1:1 + n_h],
                         robot=values[:, 1 + n_h:] if robot else None, name=str(path), **kw)


def _is_float(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


# --------------------------------------------------------------------------- any format
def load_demo(path: str | Path) -> Demonstration:
    """Load a ``.npz`` or ``.csv`` demonstration (by suffix)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        return load_npz(path)
    if suffix == ".csv":
        return load_csv(path)
    raise ValueError(f"demo '{path}': unknown file type {path.suffix!r}, expected .npz or .csv")


def is_calibration_file(path: str | Path) -> bool:
    """True for calibration files (name starting with ``calibration``)."""
    return Path(path).name.lower().startswith("calibration")


def load_dir(directory: str | Path) -> list[Demonstration]:
    """All demonstrations (.npz, .csv) under ``directory``, recursively, sorted by path.

    Calibration files are skipped. Raises ``FileNotFoundError`` if the directory does
    not exist and ``ValueError`` (naming the file) on the first malformed file.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise FileNotFoundError(f"demonstration directory '{directory}' does not exist")
    files = sorted(p for p in directory.rglob("*")
                   if p.is_file() and p.suffix.lower() in DEMO_SUFFIXES and not is_calibration_file(p)
                   and not p.name.startswith("."))
    return [load_demo(p) for p in files]


# --------------------------------------------------------------------------- calibration
def save_calibration(path: str | Path, motions) -> Path:
    """Write calibration motions.

    Parameters
    ----------
    path : str or Path
    motions : dict of str to array, shape (T_i, D), or a sequence of arrays
        A sequence of two is stored as ``xy``, ``zy``; otherwise ``motion0``, ``motion1``, ...
    """
    path = Path(path)
    if not isinstance(motions, dict):
        motions = list(motions)
        keys = ["xy", "zy"] if len(motions) == 2 else [f"motion{i}" for i in range(len(motions))]
        motions = dict(zip(keys, motions))
    if not motions:
        raise ValueError(f"calibration '{path}': no motions to save")
    arrays = {k: as_finite_array(v, f"calibration motion '{k}'", ndim=2, min_rows=2, where=f"calibration '{path}'")
              for k, v in motions.items()}
    atomic_write(path, lambda f: np.savez(f, **arrays))
    return path


def load_calibration(path: str | Path) -> dict[str, np.ndarray]:
    """Read calibration motions: a dict of name to array, shape (T_i, D), in file order.

    Raises
    ------
    ValueError
        Naming the file: not an npz, no motions, non-numeric, NaN, wrong shape, or
        motions of different dimensions.
    """
    path = Path(path)
    where = f"calibration '{path}'"
    if not path.is_file():
        raise FileNotFoundError(f"{where}: no such file")
    contents = _read_npz(path, where)
    if not contents:
        raise ValueError(f"{where}: holds no calibration motions")
    out = {k: as_finite_array(_numeric(v, k, where), f"motion '{k}'", ndim=2, min_rows=2, where=where)
           for k, v in contents.items()}
    dims = {a.shape[1] for a in out.values()}
    if len(dims) != 1:
        raise ValueError(f"{where}: motions have different dimensions {sorted(dims)}")
    return out
