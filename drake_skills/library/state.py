"""The state of a :class:`~drake_skills.library.incremental.SkillLibrary` as plain, immutable data.

:meth:`SkillLibrary.state` returns a :class:`LibraryState` and
:meth:`SkillLibrary.from_state` builds a library from one; storage writes and reads
nothing else (it never touches the library's private fields), and a state is what an
experiment keeps when it needs a library as it was.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drake_skills.library.config import LibraryConfig
from drake_skills.library.gain import ConditioningGain
from drake_skills.library.scale import BEGINNING_FRACTIONS, Cluster, SharedScale


@dataclass(frozen=True, eq=False)
class ComponentState:
    """One component: the moments of its demonstrations, its age and its two sub-clusters.

    Attributes
    ----------
    id : int
        Stable identifier (ids are never reused).
    age : int
        v_k, demonstrations processed since the component was created (>= 1).
    cluster : Cluster
        Support s_k, mean and scatter of the stacked weights ``[w_h; w_r]``, mean
        duration and path length of its demonstrations.
    subclusters : tuple (Cluster, Cluster or None)
        Its demonstrations split in two; their union is ``cluster`` (the split test
        of :mod:`drake_skills.library.novelty` looks at how far apart they are).
    """

    id: int
    age: int
    cluster: Cluster
    subclusters: tuple

    @property
    def support(self) -> float:
        return self.cluster.support

    @property
    def mean(self) -> np.ndarray:
        return self.cluster.mean

    @property
    def duration(self) -> float:
        return self.cluster.duration

    @property
    def path_length(self) -> float:
        return self.cluster.path_length


def _check_cluster(cl, d: int, what: str, *, arrays: bool = True) -> None:
    """Raise ValueError naming ``what`` if ``cl`` is not a valid cluster of ``d`` weights.

    ``arrays=False`` skips the NaN/inf test of the mean and the scatter factor (the
    caller tests all clusters' arrays at once).
    """
    if not isinstance(cl, Cluster):
        raise ValueError(f"{what} is not a Cluster")
    if not (math.isfinite(cl.support) and cl.support > 0):
        raise ValueError(f"{what} has support {cl.support}")
    ms = cl.mean.shape if isinstance(cl.mean, np.ndarray) else np.shape(cl.mean)
    fs = cl.factor.shape if isinstance(cl.factor, np.ndarray) else np.shape(cl.factor)
    if ms != (d,) or len(fs) != 2 or fs[0] != d or fs[1] > d:
        raise ValueError(f"{what} has mean and scatter shapes {ms}, {fs}; the dimensions say {d} weights")
    if arrays and not (np.isfinite(cl.mean).all() and np.isfinite(cl.factor).all()):
        raise ValueError(f"{what} has NaN or inf in its mean or scatter")
    if not (math.isfinite(cl.duration) and cl.duration >= 0 and math.isfinite(cl.path_length)
            and cl.path_length >= 0):
        raise ValueError(f"{what} has duration {cl.duration} and path length {cl.path_length}")
    t, m = np.asarray(cl.tested), np.asarray(cl.missed)
    B = len(BEGINNING_FRACTIONS)
    if t.shape != (B,) or m.shape != (B,) or not (np.isfinite(t).all() and np.isfinite(m).all()) \
            or (t < 0).any() or (m < 0).any() or (m > t * (1 + 1e-9) + 1e-9).any():
        raise ValueError(f"{what} has a bad record of beginnings (tested {t.tolist()}, missed {m.tolist()}): "
                         f"{B} shares, 0 <= missed <= tested")
    pend = np.asarray(cl.pending, float)
    if pend.shape != (B,) or ((pend < 0) | (pend > 1)).any():
        raise ValueError(f"{what} has a bad pending test of beginnings ({pend.tolist()}): {B} outcomes in [0, 1] "
                         "or NaN")
    if not isinstance(cl.tasks, tuple) or not all(
            isinstance(t, tuple) and len(t) == 2 and isinstance(t[0], str) and isinstance(t[1], float)
            and math.isfinite(t[1]) and t[1] >= 0 for t in cl.tasks) \
            or sum(w for _, w in cl.tasks) > cl.support * (1 + 1e-9) + 1e-9:
        raise ValueError(f"{what} has bad task weights ({cl.tasks!r:.80}): (name, weight >= 0) pairs summing to at "
                         "most its support")


@dataclass(frozen=True, eq=False)
class LibraryState:
    """Everything a library has learned, enough to rebuild it exactly.

    Attributes
    ----------
    config : LibraryConfig
    dim_human, dim_robot : int or None
        D_h and D_r (0 for human-only data); None before the first demonstration.
    next_id : int
        The id the next created component gets.
    n_seen : int
        Demonstrations folded in so far.
    components : tuple of ComponentState
        In the library's order (the order of responsibilities and recognitions).
    history : tuple of dict
        Creations, merges, splits and deletions, in order (JSON-ready dicts).
    scale : SharedScale or None
        The totals and the pooled within-skill scatter (None before the first demonstration).
    trained_with_workspace : bool or None
        Whether any demonstration was folded in with a workspace (Eq. 14 from raw
        units), so that a query without one is probably a mistake; None when not known
        (files written before the library kept it).
    gain : ConditioningGain or None
        The fit of Eq. (13)'s gains (:mod:`~drake_skills.library.gain`); None: none yet
        (files written before the library kept it), the paper's Eq. (13).
    """

    config: LibraryConfig
    dim_human: int | None
    dim_robot: int | None
    next_id: int
    n_seen: int
    components: tuple[ComponentState, ...] = ()
    history: tuple[dict, ...] = ()
    scale: SharedScale | None = None
    trained_with_workspace: bool | None = None
    gain: ConditioningGain | None = None

    def __post_init__(self):
        if not isinstance(self.config, LibraryConfig):
            raise ValueError(f"config must be a LibraryConfig, got {type(self.config).__name__}")
        if self.gain is not None:
            if not isinstance(self.gain, ConditioningGain):
                raise ValueError(f"gain must be a ConditioningGain or None, got {type(self.gain).__name__}")
            if self.gain.n_basis != self.config.n_basis_robot:
                raise ValueError(f"the conditioning gain has {self.gain.n_basis} basis functions, the config "
                                 f"{self.config.n_basis_robot} robot basis functions")
            if self.gain.count > self.n_seen:
                raise ValueError(f"the conditioning gain counts {self.gain.count} demonstrations; the library has "
                                 f"seen {self.n_seen}")
        if self.trained_with_workspace is not None and not isinstance(self.trained_with_workspace, bool):
            raise ValueError(f"trained_with_workspace must be True, False or None, got {self.trained_with_workspace!r}")
        if (self.dim_human is None) != (self.dim_robot is None):
            raise ValueError(f"dim_human and dim_robot are both None or both set, got "
                             f"{self.dim_human!r} and {self.dim_robot!r}")
        if self.components and self.dim_human is None:
            raise ValueError("components but no dimensions")
        if self.dim_human is not None and (self.dim_human < 1 or self.dim_robot < 0):
            raise ValueError(f"dimensions must be dim_human >= 1 and dim_robot >= 0, got "
                             f"{self.dim_human}, {self.dim_robot}")
        if self.n_seen < 0 or self.next_id < 0:
            raise ValueError(f"n_seen and next_id must be >= 0, got {self.n_seen}, {self.next_id}")
        d = self.n_weights
        if self.dim_human is not None:
            sc = self.scale
            if not isinstance(sc, SharedScale):
                raise ValueError("a fitted library needs its shared scale")
            if np.shape(sc.total_mean) != (d,) or np.shape(sc.total_m2) != (d,) or np.shape(sc.pooled) != (d, d):
                raise ValueError(f"shared scale has shapes {np.shape(sc.total_mean)}, {np.shape(sc.pooled)}; "
                                 f"the dimensions say {d} weights")
            if not all(np.isfinite(a).all() for a in (sc.total_mean, sc.total_m2, sc.pooled)) \
                    or not np.isfinite(sc.dof) or sc.n < 0 or not (np.isfinite(sc.fit_m2) and sc.fit_m2 >= 0):
                raise ValueError("shared scale has NaN or inf entries or a negative count")
            if (sc.total_m2 < -1e-9 * (1 + np.abs(sc.total_m2).max())).any() or sc.dof < -1e-9:
                raise ValueError("shared scale has negative variances or degrees of freedom")
        ids = set()
        clusters = []
        for c in self.components:
            if c.id in ids or not 0 <= c.id < self.next_id:
                raise ValueError(f"component id {c.id} is duplicated or out of range (next id {self.next_id})")
            ids.add(c.id)
            if not 1 <= c.age <= max(self.n_seen, 1):
                raise ValueError(f"component {c.id} has age {c.age}; the library has seen {self.n_seen} "
                                 f"demonstrations")
            _check_cluster(c.cluster, d, f"component {c.id}", arrays=False)
            clusters.append((c.cluster, f"component {c.id}"))
            if len(c.subclusters) != 2 or c.subclusters[0] is None:
                raise ValueError(f"component {c.id} needs two sub-clusters (the second may be None)")
            for j, sub in enumerate(c.subclusters):
                if sub is not None:
                    _check_cluster(sub, d, f"sub-cluster {j} of component {c.id}", arrays=False)
                    clusters.append((sub, f"sub-cluster {j} of component {c.id}"))
            total = sum(s.support for s in c.subclusters if s is not None)
            if abs(total - c.support) > 1e-6 * max(1.0, c.support):
                raise ValueError(f"component {c.id} has support {c.support} but its sub-clusters {total}")
        # NaN or inf anywhere: one test of all the arrays, then the first bad cluster by name
        if clusters and not (np.isfinite(np.stack([cl.mean for cl, _ in clusters])).all()
                             and np.isfinite(np.concatenate([cl.factor for cl, _ in clusters], axis=1)).all()):
            for cl, what in clusters:
                _check_cluster(cl, d, what)

    @property
    def n_human(self) -> int:
        """Number of human (gating) weights, D_h N_h (0 before the first demonstration)."""
        return 0 if self.dim_human is None else int(self.dim_human) * self.config.n_basis_human

    @property
    def n_weights(self) -> int:
        """Number of stacked weights d = D_h N_h + D_r N_r."""
        return 0 if self.dim_human is None else self.n_human + int(self.dim_robot) * self.config.n_basis_robot
