"""Save and load a SkillLibrary: one ``.npz`` file, no pickle.

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

FORMAT = "drake-skills library"
SCHEMA_VERSION = 2


def save_library(lib, path) -> Path:
    """Atomically write ``lib`` to ``path`` (``.npz`` is appended if missing)."""
    from drake_skills.library.incremental import SkillLibrary

    if not isinstance(lib, SkillLibrary):
        raise ValueError(f"save_library takes a SkillLibrary, got {type(lib).__name__}")
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    comps = lib._components
    meta = {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "config": lib.config.dict(),
        "dim_human": lib.dim_human_,
        "dim_robot": lib.dim_robot_,
        "next_id": lib._next_id,
        "n_seen": lib._n_seen,
        "components": [{"id": c.id, "age": c.age, "support": c.support, "duration": c.duration} for c in comps],
        "history": lib._history,
    }
    d = comps[0].mean.shape[0] if comps else 0
    means = np.stack([c.mean for c in comps]) if comps else np.zeros((0, d))
    covs = np.stack([c.cov for c in comps]) if comps else np.zeros((0, d, d))
    atomic_write(path, lambda f: np.savez(f, metadata=np.array(json.dumps(meta)), means=means, covs=covs),
                 fsync=True)
    return path


def load_library(path):
    """Read a library written by :func:`save_library`.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is truncated, not a drake-skills library, of a newer schema
        version, or inconsistent; the message names the file.
    """
    from drake_skills.library.incremental import LibraryConfig, SkillLibrary, _State

    path = Path(path)
    where = f"library file '{path}'"
    if not path.exists():
        raise FileNotFoundError(f"{where} does not exist")
    if not zipfile.is_zipfile(path):
        raise ValueError(f"{where} is truncated or not an .npz file")
    try:
        with np.load(path, allow_pickle=False) as z:
            names = set(z.files)
            missing = {"metadata", "means", "covs"} - names
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
        raise ValueError(f"{where} is not a drake-skills library (format tag {meta.get('format') if isinstance(meta, dict) else None!r})")
    version = meta.get("schema_version")
    if not isinstance(version, int):
        raise ValueError(f"{where}: schema_version missing or not an integer")
    if version > SCHEMA_VERSION:
        raise ValueError(f"{where} has schema version {version}, newer than this drake-skills "
                         f"supports ({SCHEMA_VERSION}): upgrade drake-skills")
    try:
        cfg_meta = dict(meta["config"])
        if version < 2:  # written before the arc length ignored noise below a tolerance
            cfg_meta.setdefault("resample_tolerance", 0.0)
        config = LibraryConfig.from_dict(cfg_meta)
        comps_meta = meta["components"]
        if not isinstance(comps_meta, list):
            raise TypeError(f"components must be a list, got {type(comps_meta).__name__}")
        dim_h, dim_r = meta["dim_human"], meta["dim_robot"]
        next_id, n_seen, history = int(meta["next_id"]), int(meta["n_seen"]), list(meta["history"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{where}: bad metadata ({type(exc).__name__}: {exc})") from None
    K = len(comps_meta)
    lib = SkillLibrary(config)
    if K == 0:
        lib.dim_human_, lib.dim_robot_ = dim_h, dim_r
        lib._next_id, lib._n_seen, lib._history = next_id, n_seen, history
        return lib
    if dim_h is None or dim_r is None:
        raise ValueError(f"{where}: components but no dimensions")
    h = int(dim_h) * config.n_basis_human
    d = h + int(dim_r) * config.n_basis_robot
    if means.shape != (K, d) or covs.shape != (K, d, d):
        raise ValueError(f"{where}: arrays have shapes {means.shape}, {covs.shape}; metadata says "
                         f"{K} components of dimension {d}")
    if not (np.isfinite(means).all() and np.isfinite(covs).all()):
        raise ValueError(f"{where}: means or covariances contain NaN or inf")
    states = []
    ids = set()
    for i, cm in enumerate(comps_meta):
        try:
            cid, age, support, duration = int(cm["id"]), int(cm["age"]), float(cm["support"]), float(cm["duration"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{where}: component {i} metadata is bad ({exc})") from None
        if cid in ids or cid >= next_id or cid < 0:
            raise ValueError(f"{where}: component id {cid} is duplicated or out of range")
        if not (support > 0 and age >= 0 and np.isfinite(duration)):
            raise ValueError(f"{where}: component {cid} has support {support}, age {age}, duration {duration}")
        ids.add(cid)
        S = covs[i]
        if not np.allclose(S, S.T, rtol=1e-9, atol=1e-12):
            raise ValueError(f"{where}: covariance of component {cid} is not symmetric")
        try:
            chol = lib._chol_gating(S, h)
            np.linalg.cholesky(S + 1e-12 * np.trace(S) / d * np.eye(d))
        except (ValueError, np.linalg.LinAlgError):
            raise ValueError(f"{where}: covariance of component {cid} is not positive definite") from None
        states.append(_State(cid, age, support, means[i].copy(), S.copy(), duration, chol))
    lib._components = states
    lib._history = history
    lib._next_id = next_id
    lib._n_seen = n_seen
    lib.dim_human_, lib.dim_robot_ = int(dim_h), int(dim_r)
    return lib
