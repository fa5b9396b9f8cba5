"""Library files written by hand, in the documented format of ``drake_skills/library/storage.py``.

Tests use them to set up a library in an exact state (chosen means, covariances,
supports and ages) through the public ``SkillLibrary.load``, and to write files
that are wrong in one way each. Importable as ``library_files``.
"""
import json

import numpy as np

FORMAT = "drake-skills library"
SCHEMA_VERSION = 2


def component(cid, mean, cov, *, support=1.0, age=1, duration=1.0):
    """One component as the file stores it: metadata entry plus its arrays."""
    return {"id": cid, "age": age, "support": support, "duration": duration,
            "mean": np.asarray(mean, float), "cov": np.asarray(cov, float)}


def metadata(config, components, *, dim_human, dim_robot, next_id=None, n_seen=None, history=None):
    """The JSON metadata of a library with these components (``config`` a LibraryConfig)."""
    ids = [c["id"] for c in components]
    return {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "config": config.dict(),
        "dim_human": dim_human,
        "dim_robot": dim_robot,
        "next_id": (max(ids) + 1 if ids else 0) if next_id is None else next_id,
        "n_seen": sum(c["age"] for c in components) if n_seen is None else n_seen,
        "components": [{k: c[k] for k in ("id", "age", "support", "duration")} for c in components],
        "history": [{"event": "created", "id": i, "demo": 0} for i in ids] if history is None else history,
    }


def write(path, meta, means, covs, **extra_arrays):
    """Write ``meta`` (a dict, or a ready-made metadata array) with ``means`` and ``covs``."""
    md = meta if isinstance(meta, np.ndarray) else np.array(json.dumps(meta))
    np.savez(path, metadata=md, means=means, covs=covs, **extra_arrays)
    return path


def write_library(path, config, components, *, dim_human, dim_robot, **meta_kw):
    """A complete, valid library file; returns ``path``."""
    meta = metadata(config, components, dim_human=dim_human, dim_robot=dim_robot, **meta_kw)
    d = components[0]["mean"].shape[0] if components else 0
    means = np.stack([c["mean"] for c in components]) if components else np.zeros((0, d))
    covs = np.stack([c["cov"] for c in components]) if components else np.zeros((0, d, d))
    return write(path, meta, means, covs)


def encode(config, demo):
    """The stacked weights the library computes for ``demo``: the mean of the component it creates."""
    from drake_skills import SkillLibrary

    lib = SkillLibrary(config)
    lib.partial_fit(demo)
    return np.array(lib.components[0].mean)
