"""Algorithm 1 on a shared, learned scale: one demonstration's weights in, the new library out.

:func:`fold_in` is the whole step of ``SkillLibrary.partial_fit``:

1. count the demonstration in the totals the prior scale comes from
   (:class:`~drake_skills.library.scale.SharedScale`);
2. novelty: the squared Mahalanobis distance of ``w_h`` to every component under the
   shared gating covariance ``Sigma`` (predictive ``Sigma (1 + 1/s_k)``), tested by the
   rule of :mod:`drake_skills.library.novelty`;
3. update: a new component (Eq. 9), or every component that explains the motion by its
   responsibility (Eqs. 5-8, exact running moments), and the nearer of its two
   sub-clusters;
4. merge (Eqs. 10-11): pairs involving a changed component whose two-sample distance
   ``|mu_i - mu_j|^2_Sigma / (1/s_i + 1/s_j)`` is below the merge threshold; a merged
   component keeps the two it came from as its sub-clusters;
5. split: a changed component whose two sub-clusters have grown apart beyond the split
   threshold becomes two again (so a merge made on an early, too-wide scale is undone
   once the scale has been learned);
6. delete outliers by age and support.

Every distance is computed on the whitened human means at once (one matrix product),
so a step costs O(K h) arithmetic plus the work on the few changed components.
Nothing here mutates its arguments; the library commits a :class:`Step` in one
assignment, so a failed step leaves it as it was.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from drake_skills.library.novelty import NoveltyRule
from drake_skills.promp.gaussian import logsumexp
from drake_skills.library.scale import Cluster, SharedScale, gating_covariance

_LOG_2PI = np.log(2.0 * np.pi)
#: Components whose responsibility reaches this are updated (and reported in ``Update.updated``).
UPDATED_RESPONSIBILITY = 1e-3


@dataclass(frozen=True, eq=False)
class ComponentModel:
    """One skill: the moments of its demonstrations and of its two sub-clusters.

    Attributes
    ----------
    id : int
        Stable identifier (ids are never reused).
    created : int
        Index of the demonstration that created it (its age is ``n_seen - created``).
    cluster : Cluster
        Moments of the stacked weights ``[w_h; w_r]`` of its demonstrations.
    subclusters : tuple of (Cluster, Cluster or None)
        A split of its demonstrations in two (the two components it was merged from,
        or its first demonstration and the ones nearer to the second); their union is
        ``cluster``.
    """

    id: int
    created: int
    cluster: Cluster
    subclusters: tuple

    @property
    def support(self) -> float:
        return self.cluster.support

    @property
    def mean(self) -> np.ndarray:
        return self.cluster.mean


@dataclass(frozen=True, eq=False)
class Components:
    """The components with their gating data stacked for vectorized scoring.

    Attributes
    ----------
    items : tuple of ComponentModel
    means_h : array, shape (K, h)
        Human (gating) means, row k for ``items[k]``.
    support : array, shape (K,)
    created : array, shape (K,)
    """

    items: tuple = ()
    means_h: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    support: np.ndarray = field(default_factory=lambda: np.zeros(0))
    created: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    #: (K, 2, h) human means of the two sub-clusters (the second 0 while it is empty)
    sub_means_h: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 0)))
    #: (K, 2) their supports (0 for an empty one)
    sub_support: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def path_lengths(self) -> np.ndarray:
        """(K,) mean path lengths of the components' demonstrations."""
        return np.array([c.cluster.path_length for c in self.items], float)

    @classmethod
    def of(cls, items: Sequence[ComponentModel], n_human: int) -> "Components":
        work = _Work(cls((), np.zeros((0, n_human)), np.zeros(0), np.zeros(0, dtype=np.int64),
                         np.zeros((0, 2, n_human)), np.zeros((0, 2))), n_human)
        for c in items:
            work.append(c)
        return work.freeze()

    def __len__(self) -> int:
        return len(self.items)

    @property
    def ids(self) -> tuple[int, ...]:
        return tuple(c.id for c in self.items)


class _Work:
    """A mutable working copy of the components during one step (private to :func:`fold_in`)."""

    def __init__(self, comps: Components, h: int):
        self.items = list(comps.items)
        self.means_h = comps.means_h.copy()
        self.support = comps.support.copy()
        self.created = comps.created.copy()
        self.sub_means_h = comps.sub_means_h.copy()
        self.sub_support = comps.sub_support.copy()
        self.h = h

    def _rows(self, c: ComponentModel):
        h = self.h
        a, b = c.subclusters
        sm = np.zeros((2, h))
        ss = np.zeros(2)
        sm[0], ss[0] = a.mean[:h], a.support
        if b is not None:
            sm[1], ss[1] = b.mean[:h], b.support
        return c.cluster.mean[:h], c.cluster.support, c.created, sm, ss

    def set(self, i: int, c: ComponentModel) -> None:
        self.items[i] = c
        self.means_h[i], self.support[i], self.created[i], self.sub_means_h[i], self.sub_support[i] = self._rows(c)

    def append(self, c: ComponentModel) -> None:
        m, s, cr, sm, ss = self._rows(c)
        self.items.append(c)
        self.means_h = np.vstack([self.means_h, m[None]])
        self.support = np.append(self.support, s)
        self.created = np.append(self.created, cr)
        self.sub_means_h = np.concatenate([self.sub_means_h, sm[None]])
        self.sub_support = np.vstack([self.sub_support, ss[None]])

    def remove(self, idx) -> None:
        idx = set(int(i) for i in np.atleast_1d(idx))
        keep = np.array([i not in idx for i in range(len(self.items))], bool)
        self.items = [c for c, k in zip(self.items, keep) if k]
        self.means_h, self.support, self.created = self.means_h[keep], self.support[keep], self.created[keep]
        self.sub_means_h, self.sub_support = self.sub_means_h[keep], self.sub_support[keep]

    def index(self, cid: int) -> int:
        for i, c in enumerate(self.items):
            if c.id == cid:
                return i
        raise KeyError(cid)

    def freeze(self) -> Components:
        return Components(tuple(self.items), self.means_h, self.support, self.created, self.sub_means_h,
                          self.sub_support)


@dataclass(frozen=True)
class Metric:
    """The gating metric: ``Sigma`` (h, h), its Cholesky factor and that factor's inverse, its log-determinant."""

    cov: np.ndarray
    inv_chol: np.ndarray
    logdet: float
    chol: np.ndarray

    @classmethod
    def of(cls, cov: np.ndarray) -> "Metric":
        L = np.linalg.cholesky(cov)
        return cls(cov, np.linalg.inv(L), float(2.0 * np.sum(np.log(np.diag(L)))), L)

    def whiten(self, x: np.ndarray) -> np.ndarray:
        """``L^{-1} x`` for rows of ``x`` (n, h) or one (h,)."""
        return x @ self.inv_chol.T


def gating_metric(scale: SharedScale, n_human: int, config) -> Metric:
    """The :class:`Metric` of the shared gating covariance of ``scale`` (see :mod:`~drake_skills.library.scale`)."""
    return Metric.of(gating_covariance(scale, n_human, prior_scale=config.prior_scale,
                                       prior_strength=config.prior_strength, shrinkage=config.shrinkage,
                                       prior_floor=config.prior_floor))


def gating_scores(w_h: np.ndarray, comps: Components, metric: Metric) -> tuple[np.ndarray, np.ndarray]:
    """``log p(w_h | k)`` and the squared Mahalanobis distance ``d^2_k``, shapes (K,).

    The predictive covariance of component k is ``Sigma (1 + 1/s_k)`` (the shared
    within-skill covariance plus the uncertainty of the component's mean).
    """
    h = w_h.shape[0]
    if not len(comps):
        return np.zeros(0), np.zeros(0)
    inflate = 1.0 + 1.0 / comps.support
    diff = metric.whiten(comps.means_h) - metric.whiten(w_h)
    d2 = np.einsum("ij,ij->i", diff, diff) / inflate
    logp = -0.5 * (h * _LOG_2PI + metric.logdet + h * np.log(inflate) + d2)
    return logp, d2


def responsibilities(log_likelihoods: np.ndarray, support: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """p(k | w_h) (Eq. 5) with priors ``alpha_k = s_k / sum_j s_j``; components outside ``mask`` get 0."""
    a = log_likelihoods + np.log(support / support.sum())
    if mask is not None:
        a = np.where(mask, a, -np.inf)
    if not np.isfinite(a).any():
        return np.zeros_like(a)
    return np.exp(a - logsumexp(a))


def two_sample_d2(whitened: np.ndarray, support: np.ndarray, i: int) -> np.ndarray:
    """``|mu_i - mu_j|^2_Sigma / (1/s_i + 1/s_j)`` for every j (inf for j = i), shape (K,)."""
    diff = whitened - whitened[i]
    d2 = np.einsum("ij,ij->i", diff, diff) / (1.0 / support + 1.0 / support[i])
    d2[i] = np.inf
    return d2


@dataclass(frozen=True, eq=False)
class Step:
    """What :func:`fold_in` did: the new components and scale, and what to report and record."""

    components: Components
    scale: SharedScale
    next_id: int
    #: Component that explained the demonstration best before the update (None if novel).
    recognized: int | None
    created: tuple[int, ...]
    updated: tuple[int, ...]
    merged: tuple[tuple[int, int], ...]
    #: (kept, new) id pairs: component ``kept`` split and its other half became ``new``.
    split: tuple[tuple[int, int], ...]
    deleted: tuple[int, ...]
    #: Component id -> responsibility, for every component before the update (empty if novel).
    responsibilities: dict
    #: Component id -> index (0 or 1) of the sub-cluster the demonstration joined.
    subcluster: dict
    history: tuple[dict, ...]


def _new_component(cid: int, created: int, w, duration: float, path_length: float) -> ComponentModel:
    cl = Cluster.of_sample(w, duration, path_length)
    return ComponentModel(cid, created, cl, (cl, None))


def fold_in(comps: Components, scale: SharedScale, w: np.ndarray, duration: float, path_length: float, *,
            n_human: int, config, rule: NoveltyRule, next_id: int, demo_index: int, fit_residual: float = 0.0) -> Step:
    """Algorithm 1 for one demonstration with stacked weights ``w`` (d,) = ``[w_h; w_r]``.

    Parameters
    ----------
    comps : Components
        Before the demonstration.
    scale : SharedScale
        Before the demonstration.
    w : array, shape (d,)
    duration : float
        Seconds.
    path_length : float
        Length of the normalized human path.
    n_human : int
        h, the number of leading human weights in ``w``.
    config : LibraryConfig
    rule : NoveltyRule
    next_id : int
        Id of a component created now.
    demo_index : int
        Index of the demonstration in the stream; ages are counted from it.
    fit_residual : float
        Mean squared residual of the demonstration's human path around its basis fit.
    """
    h = n_human
    work = _Work(comps, h)
    scale = scale.count(w, fit_residual)
    created, updated, merged, split, deleted = [], [], [], [], []
    history: list[dict] = []
    resp: dict = {}
    subs: dict = {}
    recognized = None
    changed: set[int] = set()

    # 1-2. novelty against the scale learned so far (totals including this demonstration)
    novel = True
    if len(work.items):
        metric = gating_metric(scale, h, config)
        logp, d2 = gating_scores(w[:h], comps, metric)
        fits = ~rule.novel(logp, d2, h)
        novel = not fits.any()
    # 3. update
    if novel:
        work.append(_new_component(next_id, demo_index, w, duration, path_length))
        created.append(next_id)
        changed.add(next_id)
        history.append({"event": "created", "id": next_id, "demo": demo_index})
        next_id += 1
    else:
        lam = responsibilities(logp, comps.support, fits)
        recognized = comps.items[int(np.argmax(lam))].id
        resp = {c.id: float(l) for c, l in zip(comps.items, lam)}
        zw = metric.whiten(w[:h])
        for i in np.flatnonzero(lam >= UPDATED_RESPONSIBILITY):
            c, l = comps.items[i], float(lam[i])
            cluster, g = c.cluster.add(w, l, duration, path_length)
            scale = scale.with_scatter(g, +1.0, l)
            a, b = c.subclusters
            if b is None:
                j, b = 1, Cluster.of_sample(w, duration, path_length, support=l)
            else:
                da = metric.whiten(a.mean[:h]) - zw
                db = metric.whiten(b.mean[:h]) - zw
                j = int(db @ db < da @ da)
                if j == 0:
                    a = a.add(w, l, duration, path_length)[0]
                else:
                    b = b.add(w, l, duration, path_length)[0]
            work.set(int(i), ComponentModel(c.id, c.created, cluster, (a, b)))
            updated.append(c.id)
            subs[c.id] = j
            changed.add(c.id)

    # 4. merge, starting from what changed (Eqs. 10-11)
    while len(work.items) > 1 and changed:
        metric = gating_metric(scale, h, config)
        Z = metric.whiten(work.means_h)
        best = None
        for cid in sorted(changed):
            i = work.index(cid)
            d2m = two_sample_d2(Z, work.support, i)
            if config.merge_min_age > 0:  # the paper's v_min^merge: the older of the two must be past it
                ages = (demo_index + 1) - np.minimum(work.created, work.created[i])
                d2m = np.where(ages > config.merge_min_age, d2m, np.inf)
            score = rule.merge_scores(d2m, np.maximum(work.support, work.support[i]),
                                      1.0 / work.support + 1.0 / work.support[i], metric.logdet, h)
            j = int(np.argmin(score))
            if score[j] < 1.0 and (best is None or score[j] < best[0]):
                best = (float(score[j]), i, j)
        if best is None:
            break
        _, i, j = best
        a, b = work.items[i], work.items[j]
        keep, gone = (a, b) if (a.support, -a.id) >= (b.support, -b.id) else (b, a)
        pooled, g = keep.cluster.pool(gone.cluster)
        scale = scale.with_scatter(g, +1.0, 1.0)
        new = ComponentModel(keep.id, min(keep.created, gone.created), pooled, (keep.cluster, gone.cluster))
        work.set(work.index(keep.id), new)
        work.remove(work.index(gone.id))
        merged.append((keep.id, gone.id))
        history.append({"event": "merged", "into": keep.id, "absorbed": gone.id, "demo": demo_index})
        changed = (changed - {gone.id}) | {keep.id}

    # 5. split a component whose halves have grown apart (all components: the scale may
    #    have shrunk under one that did not change)
    if len(work.items):
        metric = gating_metric(scale, h, config)
        sa, sb = work.sub_support[:, 0], work.sub_support[:, 1]
        both = sb > 0
        if both.any():
            dz = metric.whiten(work.sub_means_h[:, 0] - work.sub_means_h[:, 1])
            d2s = np.where(both, np.einsum("ij,ij->i", dz, dz) / (1.0 / sa + 1.0 / np.where(both, sb, 1.0)), 0.0)
            for i in np.flatnonzero(rule.splits(d2s, h) & both):
                c = work.items[int(i)]
                a, b = c.subclusters
                g = np.sqrt(a.support * b.support / c.support) * (a.mean - b.mean)
                scale = scale.with_scatter(g, -1.0, -1.0)
                # the first sub-cluster keeps the id (after a merge: the kept component's own half)
                work.set(int(i), ComponentModel(c.id, c.created, a, (a, None)))
                work.append(ComponentModel(next_id, c.created, b, (b, None)))
                split.append((c.id, next_id))
                history.append({"event": "split", "id": c.id, "new": next_id, "demo": demo_index})
                next_id += 1

    # 6. delete outliers: past their deletion age with too little support
    K = len(work.items)
    n_seen = demo_index + 1
    min_age = config.delete_min_age * max(1.0, K / 5.0)
    ages = n_seen - work.created
    gone_idx = np.flatnonzero((ages > min_age) & (work.support <= config.delete_min_support))
    for i in gone_idx:
        c = work.items[int(i)]
        scale = scale.with_scatter(c.cluster.factor, -1.0, -(c.support - 1.0))
        deleted.append(c.id)
        history.append({"event": "deleted", "id": c.id, "demo": demo_index, "age": int(ages[i]),
                        "support": round(float(c.support), 6)})
    if len(gone_idx):
        work.remove(gone_idx)
    return Step(work.freeze(), scale, next_id, recognized, tuple(created), tuple(updated), tuple(merged),
                tuple(split), tuple(deleted), resp, subs, tuple(history))
