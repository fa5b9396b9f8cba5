"""Save and load a library's :class:`~drake_skills.library.state.LibraryState`: one ``.npz`` file, no pickle.

``SkillLibrary.save`` writes ``lib.state()`` with :func:`save_state`;
``SkillLibrary.load`` is ``SkillLibrary.from_state(load_state(path))``. This module
knows the state type and the file format only, never the library class.

Layout (schema version 3):

* ``metadata``: a 0-d unicode array holding JSON: ``{"format": "drake-skills
  library", "schema_version": 3, "generation", "config": {...}, "dim_human", "dim_robot",
  "next_id", "n_seen", "history": [...], "trained_with_workspace": true, false or
  null (optional: files written before it are read as null, unknown), "gain": null or
  {"count", "normal", "target"} (the fit of Eq. (13)'s gains, ``library.gain``; optional: files
  written before it read as null), "scale": {"n", "dof"}, "components":
  [{"id", "age", "support", "duration", "path_length", "rank", "beginnings", "subclusters":
  [{"support", "duration", "path_length", "rank", "beginnings"}, null or {...}]}, ...]}``
  ("beginnings": ``{"tested": [B], "missed": [B], "pending": [B]}``, the record of
  beginnings of ``Cluster`` and its pending test, null where none; optional: files
  written before it read as no record);
* ``means`` (K, d); ``factors`` (d, R): the components' scatter factors side by side
  (``rank`` columns each, in order); ``sub_means`` (K, 2, d) and ``sub_factors`` (d,
  R') the same for the sub-clusters (zeros for an empty one);
* ``total_mean`` (d,), ``total_m2`` (d,), ``pooled`` (d, d): the shared scale.

The scatter is stored as factors (a few columns per demonstration), so a library of
1000 components of 3 demonstrations each and 150 weights takes ~7 MB, where dense
covariances would take 180 MB.

``generation`` counts the saves of the file (1 for the first, +1 for each save over
it; files written before it existed count as 0): ``SkillLibrary.save`` refuses to
overwrite a file whose generation changed since the library was loaded from it, so a
second writer's work is never silently replaced (:func:`file_generation` reads it
without reading the arrays).

Files of schema 1 and 2 (dense covariances, the fixed ``Sigma_init`` scale) still
load: their settings of the retired fixed scale are dropped, each component's
covariance becomes its scatter (``s_k C_k``), and the shared scale is estimated from
the stored components (a warning says so).

Writes go to a temporary file in the same directory, then ``os.replace``, so a crash
never leaves a half-written library. Loading uses ``allow_pickle=False``, reads every
array's header first and checks that the file holds the bytes it declares and that its
shape is the one the metadata says, before reading any array (a crafted file cannot
make it allocate more than its own size, and the metadata is bounded), checks
finiteness and the consistency of the dimensions (every array against ``dim_human``,
``dim_robot`` and the basis sizes; the workspace against ``dim_human``; the shared
scale's count, degrees of freedom and pooled scatter against the components; each
component's sub-clusters against it), refuses before reading any array a file whose
metadata declares more than :data:`MAX_ARRAY_BYTES` of arrays, and names the file and
the reason in every error.
"""
from __future__ import annotations

import json
import logging
import math
import os
import zipfile
from pathlib import Path

import numpy as np

from drake_skills._io import atomic_write
from drake_skills._lock import FileLock
from drake_skills.library.config import RETIRED_FIELDS, LibraryConfig
from drake_skills.library.gain import ConditioningGain
from drake_skills.library.invariants import invariant_violations
from drake_skills.library.scale import BEGINNING_FRACTIONS, Cluster, SharedScale
from drake_skills.library.state import ComponentState, LibraryState

log = logging.getLogger(__name__)

FORMAT = "drake-skills library"
SCHEMA_VERSION = 3
#: Largest metadata entry read (characters): ~ 10^5 components' bookkeeping.
MAX_METADATA_CHARS = 64 * 2 ** 20
#: Largest number of weights per demonstration a file may declare.
MAX_WEIGHTS = 10_000
#: Largest total size of the arrays a file may declare (bytes): ~ 100x the largest library we know of.
MAX_ARRAY_BYTES = 2 ** 30
#: Relative tolerance of the consistency checks between the shared scale and the components.
CONSISTENCY_RTOL = 1e-6

#: Largest ratio of an array's bytes to its compressed bytes accepted from a compressed
#: entry (``save`` stores arrays uncompressed; numbers rarely compress beyond a few times).
MAX_EXPANSION = 64


class LibraryChangedError(ValueError):
    """The library file was saved by someone else since this library was loaded from it."""


def library_path(path) -> Path:
    """``path`` as :func:`save_state` writes it (``.npz`` appended if missing)."""
    path = Path(path)
    return path if path.suffix == ".npz" else path.with_name(path.name + ".npz")


def _cluster_meta(cl: Cluster) -> dict:
    return {"support": cl.support, "duration": cl.duration, "path_length": cl.path_length,
            "rank": int(cl.factor.shape[1]), "beginnings": {"tested": [float(x) for x in cl.tested],
                                                           "missed": [float(x) for x in cl.missed],
                                                           "pending": [None if not math.isfinite(x) else float(x)
                                                                       for x in cl.pending]},
            "tasks": {name: float(weight) for name, weight in cl.tasks}}


def _tasks(meta: dict) -> tuple:
    """A cluster's task names and weights from its metadata (optional key: files written before it have none)."""
    t = meta.get("tasks", {})
    if not isinstance(t, dict) or not all(isinstance(k, str) and type(v) in (int, float) and math.isfinite(v)
                                          and v >= 0 for k, v in t.items()):
        raise ValueError(f"tasks must map task names to weights >= 0, got {t!r:.80}")
    return tuple(sorted((k, float(v)) for k, v in t.items()))


def _beginnings(meta: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A cluster's record of beginnings and its pending test from its metadata (optional keys: files written
    before them read as no record and nothing pending; null in "pending" is nothing pending at that share)."""
    B = len(BEGINNING_FRACTIONS)
    b = meta.get("beginnings")
    if b is None:
        return np.zeros(B), np.zeros(B), np.full(B, np.nan)
    if not isinstance(b, dict) or not all(isinstance(b.get(k, []), list) for k in ("tested", "missed", "pending")) \
            or not all(x is None or type(x) in (int, float) for k in ("tested", "missed", "pending")
                       for x in (b.get(k) or [])):
        raise ValueError(f"beginnings must be an object of lists of numbers (tested, missed, pending), got {b!r:.80}")
    pending = b.get("pending")
    pending = np.full(B, np.nan) if pending is None else \
        np.array([np.nan if x is None else float(x) for x in pending], dtype=float)
    return np.array(b["tested"], dtype=float), np.array(b["missed"], dtype=float), pending


def save_state(state: LibraryState, path, *, generation: int = 1) -> Path:
    """Atomically write ``state`` to ``path`` (``.npz`` is appended if missing); returns the path written.

    ``generation`` is recorded in the metadata (see the module docstring); this
    function neither locks nor checks it (``SkillLibrary.save`` does both).
    """
    if not isinstance(state, LibraryState):
        raise ValueError(f"save_state takes a LibraryState, got {type(state).__name__}")
    _int(generation, "generation")
    path = library_path(path)
    comps = state.components
    d = state.n_weights
    sc = state.scale if state.scale is not None else SharedScale.empty(d)
    meta = {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "generation": int(generation),
        "config": state.config.dict(),
        "dim_human": state.dim_human,
        "dim_robot": state.dim_robot,
        "next_id": state.next_id,
        "n_seen": state.n_seen,
        "history": list(state.history),
        "trained_with_workspace": state.trained_with_workspace,
        "gain": None if state.gain is None else {"count": state.gain.count, "normal": state.gain.normal.tolist(),
                                                 "target": state.gain.target.tolist()},
        "scale": {"n": int(sc.n), "dof": float(sc.dof), "fit_m2": float(sc.fit_m2)},
        "components": [dict(id=c.id, age=c.age, **_cluster_meta(c.cluster),
                            subclusters=[None if s is None else _cluster_meta(s) for s in c.subclusters])
                       for c in comps],
    }
    sub_means = np.zeros((len(comps), 2, d))
    sub_factors = []
    for k, c in enumerate(comps):
        for j, s in enumerate(c.subclusters):
            if s is not None:
                sub_means[k, j] = s.mean
                sub_factors.append(s.factor)
    arrays = {
        "metadata": np.array(json.dumps(meta)),
        "means": np.stack([c.mean for c in comps]) if comps else np.zeros((0, d)),
        "factors": np.concatenate([c.cluster.factor for c in comps], axis=1) if comps else np.zeros((d, 0)),
        "sub_means": sub_means,
        "sub_factors": np.concatenate(sub_factors, axis=1) if sub_factors else np.zeros((d, 0)),
        "total_mean": np.asarray(sc.total_mean, float),
        "total_m2": np.asarray(sc.total_m2, float),
        "pooled": np.asarray(sc.pooled, float),
    }
    atomic_write(path, lambda f: np.savez(f, **arrays), fsync=True)
    return path


def save_checked(state: LibraryState, path, expected_generation: int | None, *,
                 timeout: float | None = None) -> tuple[Path, int]:
    """Save ``state`` under the file's lock if its generation is still ``expected_generation``.

    Parameters
    ----------
    state : LibraryState
    path : path-like
        ``.npz`` is appended if missing.
    expected_generation : int or None
        The generation the caller last saw in the file; None saves whatever the
        file holds now (an unreadable file is then replaced too).
    timeout : float, optional
        Seconds to wait for the lock (None: as long as it takes).

    Returns
    -------
    path : Path
        The file written.
    generation : int
        Its new generation (the file's previous generation + 1).

    Raises
    ------
    LibraryChangedError
        If the file's generation is not ``expected_generation`` (another process
        saved it, or it was removed); nothing is written.
    """
    path = library_path(path)
    with FileLock(path, timeout=timeout):
        try:
            current = file_generation(path)
        except ValueError as exc:
            if expected_generation is not None:
                raise LibraryChangedError(f"library file '{path}' changed since it was loaded and cannot be read "
                                          f"now ({exc}); nothing was saved") from None
            current = None
        if expected_generation is not None and current != expected_generation:
            now = "was removed" if current is None else f"is at generation {current}"
            raise LibraryChangedError(
                f"library file '{path}' changed since this library was loaded from it (loaded at generation "
                f"{expected_generation}, the file {now}): another process saved it, and saving now would "
                f"silently drop its demonstrations. Nothing was saved: load the file again and fold your "
                f"demonstrations in (SkillLibrary.update_file does this under the file's lock), or pass "
                f"expected_generation=None to overwrite it")
        generation = (current or 0) + 1
        save_state(state, path, generation=generation)
        _remove_stale_temporaries(path)
    return path, generation


def _remove_stale_temporaries(path: Path) -> None:
    """Temporary files of :func:`atomic_write` left by a writer killed mid-save (we hold the lock: none is live)."""
    for tmp in path.parent.glob(f".{path.name}.*.tmp"):
        try:
            tmp.unlink()
            log.info("removed %s, left by a save that was interrupted", tmp)
        except OSError:  # pragma: no cover - removed meanwhile, or not ours to remove
            pass


def _headers(z: zipfile.ZipFile, where: str, file_bytes: int) -> dict:
    """Shape and dtype of every array of an .npz, read from the headers only.

    Also checks that every entry holds the bytes its header declares, and that those
    bytes are in the file (stored) or at most :data:`MAX_EXPANSION` times the
    compressed bytes that are: a crafted header cannot make loading allocate memory
    the file does not back.
    """
    out = {}
    for info in z.infolist():
        name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
        with z.open(info) as f:
            try:
                version = np.lib.format.read_magic(f)
                read = np.lib.format.read_array_header_1_0 if version == (1, 0) else \
                    np.lib.format.read_array_header_2_0
                shape, fortran, dtype = read(f)
            except ValueError as exc:
                raise ValueError(f"{where}: entry {name!r} is not a numpy array ({exc})") from None
            header_bytes = f.tell()
        if dtype.hasobject:
            raise ValueError(f"{where}: entry {name!r} holds Python objects; library files hold only numbers "
                             f"and text (refusing to unpickle)")
        need = int(np.prod(shape, dtype=object)) * dtype.itemsize
        backed = info.compress_size * (1 if info.compress_type == zipfile.ZIP_STORED else MAX_EXPANSION)
        if info.file_size < header_bytes + need or need > backed or \
                info.header_offset + info.compress_size > file_bytes:
            raise ValueError(f"{where}: entry {name!r} declares {tuple(shape)} {dtype} ({need} bytes) but the file "
                             f"holds {info.compress_size} bytes for it (truncated or crafted)")
        out[name] = (tuple(shape), dtype)
    return out


def _read(f, where: str):
    """The JSON metadata, the schema version and an accessor for the arrays of a library file open as ``f``.

    Everything is read through ``f`` (the accessor too: call it before ``f`` is closed),
    so a save that replaces the file meanwhile (a new inode) cannot mix two versions.
    """
    if not zipfile.is_zipfile(f):
        raise ValueError(f"{where} is truncated or not an .npz file")
    try:
        f.seek(0)
        with zipfile.ZipFile(f) as z:
            headers = _headers(z, where, os.fstat(f.fileno()).st_size)
        if "metadata" not in headers:
            raise ValueError(f"{where} is not a drake-skills library (missing ['metadata'])")
        shape, dtype = headers["metadata"]
        if dtype.kind != "U" or shape != ():
            raise ValueError(f"{where}: metadata entry is not a JSON string")
        if dtype.itemsize // 4 > MAX_METADATA_CHARS:
            raise ValueError(f"{where}: metadata entry of {dtype.itemsize // 4} characters is larger than "
                             f"{MAX_METADATA_CHARS}")
        f.seek(0)
        with np.load(f, allow_pickle=False) as z:
            meta_raw = z["metadata"]
    except ValueError as exc:
        if str(exc).startswith(where):
            raise
        raise ValueError(f"{where} cannot be read as .npz without pickle ({exc})") from None
    except (zipfile.BadZipFile, OSError, EOFError, KeyError) as exc:
        raise ValueError(f"{where} is truncated or not an .npz file ({type(exc).__name__}: {exc})") from None
    try:
        meta = json.loads(str(meta_raw))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{where}: metadata is not valid JSON ({exc})") from None
    except RecursionError:
        raise ValueError(f"{where}: metadata is nested too deeply to be a drake-skills library") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise ValueError(f"{where} is not a drake-skills library (format tag "
                         f"{meta.get('format') if isinstance(meta, dict) else None!r})")
    version = meta.get("schema_version")
    if not isinstance(version, int) or isinstance(version, bool):
        raise ValueError(f"{where}: schema_version missing or not an integer")
    if version > SCHEMA_VERSION:
        raise ValueError(f"{where} has schema version {version}, newer than this drake-skills "
                         f"supports ({SCHEMA_VERSION}): upgrade drake-skills")
    if version < 1:
        raise ValueError(f"{where}: schema_version {version} is not a version of this format")

    def arrays(expected: dict) -> dict:
        """Read the arrays named in ``expected`` (name -> shape), each checked before it is read."""
        missing = sorted(set(expected) - set(headers))
        if missing:
            raise ValueError(f"{where} is not a drake-skills library (missing {missing})")
        total = 8 * sum(math.prod(want) for want in expected.values())
        if total > MAX_ARRAY_BYTES:
            raise ValueError(f"{where}: the metadata declares {total / 2 ** 20:.0f} MiB of arrays, more than "
                             f"the {MAX_ARRAY_BYTES / 2 ** 20:.0f} MiB a library file may hold "
                             f"(storage.MAX_ARRAY_BYTES); refusing to read it")
        for name, want in expected.items():
            shape, dtype = headers[name]
            if shape != tuple(want):
                raise ValueError(f"{where}: array {name!r} has shape {shape}, the metadata says {tuple(want)}")
            if dtype.kind not in "fiu":
                raise ValueError(f"{where}: array {name!r} is not numeric ({dtype})")
        try:
            f.seek(0)
            with np.load(f, allow_pickle=False) as z:
                out = {name: np.array(z[name], dtype=float) for name in expected}
        except (zipfile.BadZipFile, OSError, EOFError, KeyError, ValueError) as exc:
            raise ValueError(f"{where} is truncated or damaged ({type(exc).__name__}: {exc})") from None
        for name, a in out.items():
            if not np.isfinite(a).all():
                raise ValueError(f"{where}: array {name!r} contains NaN or inf")
        return out

    return meta, version, arrays


#: Largest integer a library file may hold (ids, counts, ages): exact in a float, far beyond any library.
MAX_FILE_INT = 2 ** 53


def _int(x, what: str, lo: int = 0) -> int:
    if isinstance(x, bool) or not isinstance(x, int) or x < lo:
        raise ValueError(f"{what} must be an integer >= {lo}, got {x!r:.40}")
    if x > MAX_FILE_INT:
        raise ValueError(f"{what} must be at most 2**53, got {x}")
    return x


def load_state(path) -> LibraryState:
    """Read the state written by :func:`save_state` (or by a version that wrote schema 1 or 2).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is truncated, not a drake-skills library, of a newer schema
        version, or inconsistent; the message names the file and the reason.
    """
    return load_versioned(path)[0]


def _generation(meta: dict, where: str) -> int:
    try:
        return _int(meta.get("generation", 0), "generation")
    except ValueError as exc:
        raise ValueError(f"{where}: bad metadata ({exc})") from None


def file_generation(path) -> int | None:
    """The generation of the library file at ``path`` (None if there is no file), from its metadata alone.

    Raises
    ------
    ValueError
        If the file exists but is not a readable drake-skills library.
    """
    path = Path(path)
    if not path.exists():
        return None
    where = f"library file '{path}'"
    _not_a_directory(path, where)
    with open(path, "rb") as f:
        return _generation(_read(f, where)[0], where)


def _not_a_directory(path: Path, where: str) -> None:
    if path.is_dir():
        raise ValueError(f"{where} is a directory; give the library's .npz file")


def load_versioned(path) -> tuple[LibraryState, int]:
    """:func:`load_state` and the file's generation (0 for a file written before generations)."""
    path = Path(path)
    where = f"library file '{path}'"
    if not path.exists():
        raise FileNotFoundError(f"{where} does not exist")
    _not_a_directory(path, where)
    with open(path, "rb") as f:  # one handle for the whole load
        meta, version, arrays = _read(f, where)
        generation = _generation(meta, where)
        return _state_of(meta, version, arrays, where), generation


def _state_of(meta: dict, version: int, arrays, where: str) -> LibraryState:
    try:
        cfg_meta = dict(meta["config"])
        if version < 2:  # written before the arc length ignored noise below a tolerance
            cfg_meta.setdefault("resample_tolerance", 0.0)
        if version < 3:  # the fixed Sigma_init scale; the file's representation settings stay
            for name in RETIRED_FIELDS:
                cfg_meta.pop(name, None)
            cfg_meta.setdefault("ridge", 1e-6)
            cfg_meta.setdefault("n_basis_human", 10)
        cfg_meta.setdefault("adapt_to_noise", False)  # optional key: a file written before it walked plainly
        cfg_meta.setdefault("average_holds", False)  # optional key: a file written before it walked holds plainly
        cfg_meta.setdefault("single_demo_quantile", 1.0)  # optional key: a file written before the rule had none
        cfg_meta.setdefault("split_within_share", 1.0)  # optional key: a file written before it split on distance alone
        cfg_meta.setdefault("keep_single_demos_apart", False)  # optional key: a file written before it merged them
        cfg_meta.setdefault("skip_false_starts", False)  # optional key: a file written before it read motions whole
        cfg_meta.setdefault("mixed_task_share", 1.0)  # optional key: a file written before it kept no task names
        cfg_meta.setdefault("other_task_reach", 0.0)  # optional key: likewise
        cfg_meta.setdefault("same_task_reach", 1.0)  # optional key: a file written before it merged without names
        cfg_meta.setdefault("keep_tasks_apart", False)  # optional key: likewise
        cfg_meta.setdefault("new_skill_weight", 0.0)  # optional key: a file written before it answered beginnings so
        config = LibraryConfig.from_dict(cfg_meta)
        comps_meta = list(meta["components"])
        dim_h, dim_r = meta["dim_human"], meta["dim_robot"]
        dims = (None, None) if dim_h is None and dim_r is None else (_int(dim_h, "dim_human", 1),
                                                                      _int(dim_r, "dim_robot", 0))
        next_id, n_seen = _int(meta["next_id"], "next_id"), _int(meta["n_seen"], "n_seen")
        history = tuple(meta["history"])
        if not all(isinstance(e, dict) for e in history):
            raise ValueError("history entries must be objects")
        with_ws = meta.get("trained_with_workspace")  # optional key: schema 3 without it reads as unknown
        if with_ws is not None and not isinstance(with_ws, bool):
            raise ValueError(f"trained_with_workspace must be true, false or null, got {with_ws!r}")
        gain = _gain_of(meta.get("gain"), config.n_basis_robot)  # optional: older files read as None (Eq. 13)
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{where}: bad metadata ({type(exc).__name__}: {exc})") from None
    K = len(comps_meta)
    if dims[0] is None:
        if K:
            raise ValueError(f"{where}: components but no dimensions")
        try:
            return LibraryState(config, None, None, next_id, n_seen, (), history, None, with_ws, gain)
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
    ws = config.workspace
    if ws is not None and ws.dim != dims[0]:
        raise ValueError(f"{where} is inconsistent: its workspace is {ws.dim}-D but dim_human is {dims[0]}")
    d = dims[0] * config.n_basis_human + dims[1] * config.n_basis_robot
    if d > MAX_WEIGHTS:
        raise ValueError(f"{where}: metadata declares {d} weights per demonstration (more than {MAX_WEIGHTS})")
    if version < 3:
        return _load_dense(where, config, dims, next_id, n_seen, history, comps_meta, arrays, d)
    try:
        ranks = [_int(c["rank"], f"component {i} rank") for i, c in enumerate(comps_meta)]
        sub_ranks = [_int(s["rank"], f"component {i} sub-cluster rank")
                     for i, c in enumerate(comps_meta) for s in c["subclusters"] if s is not None]
        scale_meta = meta["scale"]
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{where}: bad component metadata ({type(exc).__name__}: {exc})") from None
    if any(r > d for r in ranks + sub_ranks):
        raise ValueError(f"{where}: a scatter factor of rank above {d} (the number of weights)")
    a = arrays({"means": (K, d), "factors": (d, sum(ranks)), "sub_means": (K, 2, d),
                "sub_factors": (d, sum(sub_ranks)), "total_mean": (d,), "total_m2": (d,), "pooled": (d, d)})
    comps = []
    col = sub_col = 0
    try:
        for i, cm in enumerate(comps_meta):
            f = a["factors"][:, col:col + ranks[i]]
            col += ranks[i]
            cluster = Cluster(float(cm["support"]), a["means"][i], f, float(cm["duration"]), float(cm["path_length"]),
                              *_beginnings(cm), _tasks(cm))
            subs = []
            if not isinstance(cm["subclusters"], list) or len(cm["subclusters"]) != 2:
                raise ValueError(f"component {i} needs two sub-cluster entries")
            for j, sm in enumerate(cm["subclusters"]):
                if sm is None:
                    subs.append(None)
                    continue
                r = int(sm["rank"])
                sf = a["sub_factors"][:, sub_col:sub_col + r]
                sub_col += r
                subs.append(Cluster(float(sm["support"]), a["sub_means"][i, j], sf, float(sm["duration"]),
                                    float(sm["path_length"]), *_beginnings(sm), _tasks(sm)))
            comps.append(ComponentState(_int(cm["id"], f"component {i} id"), _int(cm["age"], f"component {i} age"),
                                        cluster, tuple(subs)))
        scale = SharedScale(_int(scale_meta["n"], "scale n"), a["total_mean"], a["total_m2"], a["pooled"],
                            float(scale_meta["dof"]), float(scale_meta.get("fit_m2", 0.0)))
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{where}: component metadata is bad ({type(exc).__name__}: {exc})") from None
    if not np.allclose(scale.pooled, scale.pooled.T, rtol=1e-9, atol=1e-12):
        raise ValueError(f"{where}: the pooled scatter is not symmetric")
    return _consistent(where, config, dims[0], dims[1], next_id, n_seen, tuple(comps), history, scale, with_ws,
                       gain)


def _gain_of(g, n_basis: int) -> ConditioningGain | None:
    """The ``gain`` entry of the metadata: null, or ``{"count", "normal", "target"}`` of numbers (checked by the class)."""
    if g is None:
        return None
    if not isinstance(g, dict) or set(g) != {"count", "normal", "target"}:
        raise ValueError("gain must be null or an object with count, normal and target")
    for name, shape in (("normal", (n_basis, n_basis)), ("target", (n_basis,))):
        rows = g[name] if name == "normal" else [g[name]]
        if not isinstance(rows, list) or len(rows) != (n_basis if name == "normal" else 1) or not all(
                isinstance(row, list) and len(row) == n_basis for row in rows):
            raise ValueError(f"gain {name} must be {' x '.join(map(str, shape))} numbers for the config's "
                             f"{n_basis} robot basis functions")
        if not all(type(v) in (int, float) for row in rows for v in row):
            raise ValueError(f"gain {name} holds something other than numbers")
    gain = ConditioningGain(np.array(g["normal"], dtype=float), np.array(g["target"], dtype=float), g["count"])
    with np.errstate(over="ignore", invalid="ignore"):
        gain.gains()   # the fit every prediction asks for: a record that overflows it is refused here
    return gain


def _consistent(where: str, *args) -> LibraryState:
    """``LibraryState(*args)``, checked against :func:`~drake_skills.library.invariants.invariant_violations`."""
    try:
        state = LibraryState(*args)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    problems = invariant_violations(state, rtol=CONSISTENCY_RTOL)
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise ValueError(f"{where} is inconsistent: {problems[0]}{more}")
    return state


def _load_dense(where, config, dims, next_id, n_seen, history, comps_meta, arrays, d) -> LibraryState:
    """A schema 1-2 file: dense covariances of the fixed-scale library."""
    K = len(comps_meta)
    a = arrays({"means": (K, d), "covs": (K, d, d)})
    comps, supports = [], []
    try:
        for i, cm in enumerate(comps_meta):
            s, cov = float(cm["support"]), a["covs"][i]
            if not np.allclose(cov, cov.T, rtol=1e-9, atol=1e-12):
                raise ValueError(f"covariance of component {cm.get('id', i)} is not symmetric")
            w, V = np.linalg.eigh(0.5 * (cov + cov.T))
            if w.min() < -1e-9 * max(1.0, abs(w).max()):
                raise ValueError(f"covariance of component {cm.get('id', i)} is not positive definite")
            factor = V * np.sqrt(np.clip(w, 0.0, None) * s)
            cl = Cluster(s, a["means"][i], factor, float(cm["duration"]), 0.0)
            comps.append(ComponentState(_int(cm["id"], f"component {i} id"), max(1, _int(cm["age"], "age")),
                                        cl, (cl, None)))
            supports.append(s)
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{where}: {exc}") from None
    if comps:
        s = np.array(supports)
        means = a["means"]
        mean = s @ means / s.sum()
        var = s @ (np.stack([np.diag(c) for c in a["covs"]]) + (means - mean) ** 2)
        pooled = sum(c.cluster.scatter for c in comps)
        scale = SharedScale(max(n_seen, 1), mean, var, 0.5 * (pooled + pooled.T), float(np.sum(s - 1.0)))
    else:
        scale = SharedScale.empty(d)
    log.warning("%s has schema version < 3 (fixed Sigma_init scale): its shared scale is estimated from the "
                "stored components, and phase estimates need new demonstrations (no path lengths stored)", where)
    return _consistent(where, config, dims[0], dims[1], next_id, n_seen, tuple(comps), history, scale)
