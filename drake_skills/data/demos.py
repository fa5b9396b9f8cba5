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
    scenario); :func:`load_dir` skips it. A ``workspace.json`` (``{"lower": [...],
    "upper": [...], "scale": 10}``, :meth:`Workspace.save <drake_skills.data.workspace.Workspace.save>`)
    gives the bounds directly; :func:`load_workspace` reads either.

A folder of demonstrations (:func:`scan_dir`) holds each demonstration once: an npz and
a CSV of the same name are one demonstration if they hold the same data, or an error.
Files of the folder that are not demonstrations (calibration files, a library or
predictions saved there, a CSV table) are skipped with a note; one that looks like a
demonstration but is malformed is an error. Every malformed file raises ``ValueError``
naming the file and the problem.
"""
from __future__ import annotations

import csv
import io
import logging
import re
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drake_skills._checks import as_finite_array
from drake_skills._io import atomic_write
from drake_skills.data.demonstration import Demonstration, human_columns as _human_columns, save_csv, save_npz
from drake_skills.data.workspace import Workspace

log = logging.getLogger(__name__)

#: Suffixes of demonstration files.
DEMO_SUFFIXES = (".npz", ".csv")
_HUMAN_XYZ = ("hx", "hy", "hz")
__all__ = ["DEMO_SUFFIXES", "DirScan", "check_layout", "columns_of", "is_calibration_file", "load_calibration",
           "load_csv", "load_demo", "load_dir", "load_npz", "load_workspace", "save_calibration", "save_csv",
           "save_npz", "scan_dir"]


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
        vals = {row[i].strip() for row in rows[1:]}  # spaces around a label are not part of it
        if len(vals) > 1:
            raise ValueError(f"{where}: column '{c}' must hold one value, has {sorted(vals)[:3]}")
        if vals and (v := vals.pop()):  # an empty label is no label
            kw[c] = v
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


@dataclass
class DirScan:
    """What :func:`scan_dir` found in a folder of demonstrations.

    Attributes
    ----------
    demos : list of Demonstration
        One per demonstration, sorted by path.
    skipped : list of (Path, str)
        Files that are not demonstrations, with the reason.
    duplicates : list of (Path, Path)
        (kept, same): a CSV read once because the npz of the same name holds the same data.
    failed : list of (Path, str)
        Demonstration files that could not be read, with the error (only with
        ``scan_dir(..., keep_going=True)``; otherwise the first one raises).
    """

    demos: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    duplicates: list = field(default_factory=list)
    failed: list = field(default_factory=list)

    def notes(self) -> list[str]:
        """One line per skipped file and per demonstration found twice."""
        out = [f"skipped '{p}': {why}" for p, why in self.skipped]
        out += [f"read '{a}' once: '{b.name}' holds the same demonstration" for a, b in self.duplicates]
        return out


def _not_a_demo(path: Path) -> str | None:
    """Why ``path`` (a .npz or .csv) is not a demonstration file, or None if it should be read as one."""
    if is_calibration_file(path):
        return "a calibration file (it gives the subject's workspace)"
    if path.suffix.lower() == ".npz":
        if not zipfile.is_zipfile(path):
            return None  # load_npz says what is wrong with it
        try:
            with zipfile.ZipFile(path) as z:
                names = {n[:-4] if n.endswith(".npy") else n for n in z.namelist()}
        except (zipfile.BadZipFile, OSError):
            return None
        if "metadata" in names:
            return "a drake-skills library file"
        if "format" in names:
            return "a drake-skills output file (not a demonstration)"
        if not names & {"t", "human"}:
            return f"an npz without the arrays of a demonstration (t, human): has {sorted(names)[:6]}"
        return None
    try:
        with open(path, newline="") as f:
            first = f.readline()
    except (OSError, UnicodeDecodeError):
        return None
    header = [c.strip() for c in next(csv.reader([first]), [])]
    if header and header[0] != "t" and not any(c in _HUMAN_XYZ or re.fullmatch(r"h\d+", c) for c in header):
        return f"a CSV without the columns of a demonstration (t, hx, ...): header {','.join(header[:6])!r}"
    return None


def _same_demo(a: Demonstration, b: Demonstration) -> str | None:
    """What differs between two demonstrations (None if they are the same, to CSV precision)."""
    for name in ("t", "human", "robot"):
        x, y = getattr(a, name), getattr(b, name)
        if (x is None) != (y is None):
            return "only one has a robot trajectory"
        if x is not None and (x.shape != y.shape or not np.allclose(x, y, rtol=1e-9, atol=1e-12)):
            return f"'{name}' differs (shapes {x.shape} and {y.shape})"
    for label in ("task", "subject"):
        if getattr(a, label) != getattr(b, label):
            return f"{label} {getattr(a, label)!r} vs {getattr(b, label)!r}"
    return None


def scan_dir(directory: str | Path, *, keep_going: bool = False) -> DirScan:
    """The demonstrations under ``directory`` (recursively), each once, and the files skipped.

    ``.npz`` and ``.csv`` files are read; hidden files are ignored. An npz and a CSV
    of the same name in the same folder are one demonstration (the npz is kept) when
    they hold the same data (within 1e-9 relative, the CSV's precision), else an
    error. Calibration files, library files, drake-skills output files and CSV
    tables are skipped (:attr:`DirScan.skipped`).

    Raises
    ------
    FileNotFoundError
        If ``directory`` does not exist.
    ValueError
        Naming the file, on the first malformed demonstration (with ``keep_going``:
        recorded in :attr:`DirScan.failed` instead), or naming both files of a name that
        holds two different demonstrations.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise FileNotFoundError(f"demonstration directory '{directory}' does not exist")
    files = sorted(p for p in directory.rglob("*")
                   if p.is_file() and p.suffix.lower() in DEMO_SUFFIXES and not p.name.startswith("."))
    scan = DirScan()
    by_name: dict[tuple[Path, str], Path] = {}
    for p in files:
        why = _not_a_demo(p)
        if why is not None:
            scan.skipped.append((p, why))
            continue
        try:
            demo = load_demo(p)
        except ValueError as exc:
            if not keep_going:
                raise
            scan.failed.append((p, str(exc)))
            continue
        key = (p.parent, p.stem.lower())
        if key in by_name:
            first = by_name[key]
            kept = next(d for d in scan.demos if d.name == str(first))
            diff = _same_demo(kept, demo)
            if diff is not None:
                raise ValueError(f"demo '{first}' and '{p.name}' have the same name but hold different "
                                 f"demonstrations ({diff}): keep one of them")
            npz_first = first.suffix.lower() == ".npz"
            if not npz_first:  # keep the npz (exact binary) in the list
                scan.demos[scan.demos.index(kept)] = demo
                by_name[key] = p
            scan.duplicates.append((p, first) if not npz_first else (first, p))
            continue
        by_name[key] = p
        scan.demos.append(demo)
    return scan


def load_dir(directory: str | Path) -> list[Demonstration]:
    """All demonstrations under ``directory``, each once, sorted by path (see :func:`scan_dir`).

    What was skipped or read once is logged (INFO). Raises ``FileNotFoundError`` if the
    directory does not exist and ``ValueError`` (naming the file) on the first
    malformed file.
    """
    scan = scan_dir(directory)
    for note in scan.notes():
        log.info("%s", note)
    return scan.demos


# --------------------------------------------------------------------------- layout
def columns_of(dim_human: int, dim_robot: int) -> list[str]:
    """The CSV columns of a demonstration with these dimensions (without the labels)."""
    return ["t"] + _human_columns(dim_human) + [f"q{i + 1}" for i in range(dim_robot)]


def _span(cols: list[str]) -> str:
    return ", ".join(cols) if len(cols) <= 3 else f"{cols[0]}..{cols[-1]}"


def check_layout(demo: Demonstration, dim_human: int, dim_robot: int, declared_by: str) -> None:
    """Raise unless ``demo`` has ``dim_human`` human and ``dim_robot`` robot columns.

    The error names the file and the missing (or extra) columns, e.g. ``demo 'a.csv':
    missing column 'hz' (...)``; ``declared_by`` says where the dimensions come from
    (the library's first demonstration, or an existing library).
    """
    if (demo.dim_human, demo.dim_robot) == (dim_human, dim_robot):
        return
    where = f"demo '{demo.name}'" if demo.name else "demonstration"
    want, have = columns_of(dim_human, dim_robot), columns_of(demo.dim_human, demo.dim_robot)
    problems = []
    missing = [c for c in want if c not in have]
    extra = [c for c in have if c not in want]
    if missing:
        problems.append(f"missing column{'s' if len(missing) > 1 else ''} {', '.join(repr(c) for c in missing)}")
    if extra:
        problems.append(f"extra column{'s' if len(extra) > 1 else ''} {', '.join(repr(c) for c in extra)}")
    h_want, r_want = _human_columns(dim_human), [f"q{i + 1}" for i in range(dim_robot)]
    layout = f"t, {_span(h_want)}" + (f", {_span(r_want)}" if r_want else " (no robot)")
    raise ValueError(f"{where}: {'; '.join(problems)}: the library's dimensions are declared by {declared_by}, "
                     f"which has {layout}")


def load_workspace(path: str | Path, *, z_factor: float = 0.9) -> Workspace:
    """The workspace of a ``workspace.json`` (its bounds) or a ``calibration*.npz`` (Sec. 4.2.2).

    A calibration file gives the per-axis range of its motions, the third axis
    shrunk to ``z_factor`` about its centre (the paper's 0.9: people stretch out more
    when calibrating than when working).
    """
    path = Path(path)
    if path.suffix.lower() == ".json":
        return Workspace.load(path)
    if path.suffix.lower() == ".npz":
        motions = list(load_calibration(path).values())
        try:
            return Workspace.from_calibration(motions, z_factor=z_factor if motions[0].shape[1] > 2 else None)
        except ValueError as exc:
            raise ValueError(f"calibration '{path}': {exc}") from None
    raise ValueError(f"workspace '{path}': expected a workspace .json or a calibration .npz")


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
