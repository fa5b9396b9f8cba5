"""Libraries in an exact state, built by hand through ``SkillLibrary.from_state``; importable as ``library_states``.

Tests choose the components' means, scatters, supports, ages, durations and path
lengths and the shared scale, so that a decision (novelty, merge, deletion) and its
result can be checked against numbers computed in the test, independently of the
library's code. :func:`iso_scale` gives a shared scale whose gating covariance is
``var I`` up to the prior's weight ``2 / (dof + 2)`` (tests read the exact one
with ``lib.shared_covariance()``).
"""
import numpy as np

from drake_skills import SkillLibrary
from drake_skills.library.scale import Cluster, SharedScale
from drake_skills.library.state import ComponentState, LibraryState


def component(cid, mean, *, factor=None, support=1.0, age=1, duration=1.0, path_length=5.0):
    """One component with scatter ``factor factor^T`` (none by default) and no second sub-cluster."""
    mean = np.asarray(mean, float)
    f = np.zeros((mean.shape[0], 0)) if factor is None else np.asarray(factor, float)
    cl = Cluster(float(support), mean, f, float(duration), float(path_length))
    return ComponentState(cid, age, cl, (cl, None))


def iso_scale(d, var=1.0, dof=1e6):
    """A shared scale with pooled scatter ``var dof I`` over ``dof`` degrees of freedom and no totals."""
    return SharedScale(0, np.zeros(d), np.zeros(d), var * dof * np.eye(d), float(dof), 0.0)


def library(config, comps, *, dim_human, dim_robot, scale=None, n_seen=None, next_id=None, history=None,
            var=1.0):
    """A SkillLibrary holding ``comps`` (ComponentState) on ``scale`` (default :func:`iso_scale` of ``var``)."""
    d = dim_human * config.n_basis_human + dim_robot * config.n_basis_robot
    ids = [c.id for c in comps]
    state = LibraryState(
        config, dim_human, dim_robot,
        (max(ids) + 1 if ids else 0) if next_id is None else next_id,
        max([c.age for c in comps] + [1]) if n_seen is None else n_seen,
        tuple(comps),
        tuple({"event": "created", "id": i, "demo": 0} for i in ids) if history is None else tuple(history),
        iso_scale(d, var) if scale is None else scale)
    return SkillLibrary.from_state(state)


def encode(config, demo):
    """The stacked weights the library computes for ``demo``."""
    return SkillLibrary(config).encode(demo)


def unit(rng, n):
    u = rng.standard_normal(n)
    return u / np.linalg.norm(u)
