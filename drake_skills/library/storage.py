"""Save and load a library's :class:`~drake_skills.library.state.LibraryState`: one ``.npz`` file, no pickle.

``SkillLibrary.save`` writes ``lib.state()`` with :func:`save_state`;
``SkillLibrary.load`` is ``SkillLibrary.from_state(load_state(path))``. This module
knows the state type and the file format only, never the library class.

Layout (schema version 2; version 1 lacked ``config.resample_tolerance``,
which reads as 0, the arc length of version 1):

* ``metadata``: a 0-d unicode array holding JSON: ``{"format": "drake-skills
  library", "schema_version": 2, "config": {...}, "dim_human": ...,
  "dim_robot": ..., "next_id": ..., "n_seen": ..., "components": [{"id", "age",
  "support", "duration"}, ...], "history": [...]}``;
* ``means``: (K, d) and ``covs``: (K, d, d), in the order of ``components``.

Writes go to a temporary file in the same directory, then ``os.replace``, so a
crash never leaves a half-written library.  Loading uses
``allow_pickle=False`` and checks the format tag, the schema version, shapes,
finiteness and symmetry/positive definiteness, and names the file in every
error.
"""
from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np

from drake_skills._io import atomic_write
from drake_skills.library.config import LibraryConfig
from drake_skills.library.state import ComponentState, LibraryState

FORMAT = "drake-skills library"
SCHEMA_VERSION = 2


def save_state(state: LibraryState, path) -> Path:
    """Atomically write ``state`` to ``path`` (``.npz`` is appended if missing); returns the path written."""
    if not isinstance(state, LibraryState):
        raise ValueError(f"save_state takes a LibraryState, got {type(state).__name__}")
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    comps = state.components
    meta = {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "config": state.config.dict(),
        "dim_human": state.dim_human,
        "dim_robot": state.dim_robot,
        "next_id": state.next_id,
        "n_seen": state.n_seen,
        "components": [{"id": c.id, "age": c.age, "support": c.support, "duration": c.duration} for c in comps],
        "history": list(state.history),
    }
    d = state.n_weights
    means = np.stack([c.mean for c in comps]) if comps else np.zeros((0, d))
    covs = np.stack([c.cov for c in comps]) if comps else np.zeros((0, d, d))
    atomic_write(path, lambda f: np.savez(f, metadata=np.array(json.dumps(meta)), means=means, covs=covs),
                 fsync=True)
    return path


def _read(path: Path, where: str):
    """The JSON metadata and the two arrays of a library file."""
    if not path.exists():
        raise FileNotFoundError(f"{where} does not exist")
    if not zipfile.is_zipfile(path):
        raise ValueError(f"{where} is truncated or not an .npz file")
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = {"metadata", "means", "covs"} - set(z.files)
            if missing:
                raise ValueError(f"{where} is not a drake-skills library (missing {sorted(missing)})")
            meta_raw = z["metadata"]
            means = np.array(z["means"], dtype=float)
            covs = np.array(z["covs"], dtype=float)
    except ValueError as exc:
        if str(exc).startswith(where):
            raise
        raise ValueError(f"{where} cannot be read as .npz without pickle ({exc})") from None
    except (zipfile.BadZipFile, OSError, EOFError, KeyError) as exc:
        raise ValueError(f"{where} is truncated or not an .npz file ({type(exc).__name__}: {exc})") from None
    if meta_raw.dtype.kind != "U" or meta_raw.shape != ():
        raise ValueError(f"{where}: metadata entry is not a JSON string")
    try:
        meta = json.loads(str(meta_raw))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{where}: metadata is not valid JSON ({exc})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise ValueError(f"{where} is not a drake-skills library (format tag "
                         f"{meta.get('format') if isinstance(meta, dict) else None!r})")
    version = meta.get("schema_version")
    if not isinstance(version, int):
        raise ValueError(f"{where}: schema_version missing or not an integer")
    if version > SCHEMA_VERSION:
        raise ValueError(f"{where} has schema version {version}, newer than this drake-skills "
                         f"supports ({SCHEMA_VERSION}): upgrade drake-skills")
    return meta, version, means, covs


def load_state(path) -> LibraryState:
    """Read the state written by :func:`save_state`.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is truncated, not a drake-skills library, of a newer schema
        version, or inconsistent; the message names the file.
    """
    path = Path(path)
    where = f"library file '{path}'"
    meta, version, means, covs = _read(path, where)
    try:
        cfg_meta = dict(meta["config"])
        if version < 2:  # written before the arc length ignored noise below a tolerance
            cfg_meta.setdefault("resample_tolerance", 0.0)
        config = LibraryConfig.from_dict(cfg_meta)
        comps_meta = list(meta["components"])
        dim_h, dim_r = meta["dim_human"], meta["dim_robot"]
        dims = (None, None) if dim_h is None and dim_r is None else (int(dim_h), int(dim_r))
        next_id, n_seen, history = int(meta["next_id"]), int(meta["n_seen"]), tuple(meta["history"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{where}: bad metadata ({type(exc).__name__}: {exc})") from None
    K = len(comps_meta)
    if K and dims[0] is None:
        raise ValueError(f"{where}: components but no dimensions")
    d = 0 if dims[0] is None else dims[0] * config.n_basis_human + dims[1] * config.n_basis_robot
    if K and (means.shape != (K, d) or covs.shape != (K, d, d)):
        raise ValueError(f"{where}: arrays have shapes {means.shape}, {covs.shape}; metadata says "
                         f"{K} components of dimension {d}")
    if not (np.isfinite(means).all() and np.isfinite(covs).all()):
        raise ValueError(f"{where}: means or covariances contain NaN or inf")
    comps = []
    for i, cm in enumerate(comps_meta):
        try:
            comps.append(ComponentState(int(cm["id"]), int(cm["age"]), float(cm["support"]), means[i].copy(),
                                        covs[i].copy(), float(cm["duration"])))
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{where}: component {i} metadata is bad ({exc})") from None
    try:
        return LibraryState(config, dims[0], dims[1], next_id, n_seen, tuple(comps), history)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
