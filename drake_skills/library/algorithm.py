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
4. merge (Eqs. 10-11): every pair whose two-sample distance
   ``|mu_i - mu_j|^2_Sigma / (1/s_i + 1/s_j)`` is below the merge threshold, the
   closest first (a component that did not change can come within it as the scale
   moves); a merged component keeps the two it came from as its sub-clusters; two components
   taught as the same task (``Cluster.tasks``) merge within ``same_task_reach`` times the
   threshold, and two taught as different tasks never merge (``keep_tasks_apart``; a demonstration
   named as another task than a component's does not join it either, step 3: deviations from
   the paper, which learns without names);
5. split: a component whose two sub-clusters have grown apart beyond the split
   threshold (``same_task_reach`` times it for halves taught as one task), and lie apart as
   two skills do rather than as two halves of one
   (:func:`within_share`, ``LibraryConfig.split_within_share``), becomes two again (so a
   merge made on an early, too-wide scale is undone once the scale has been learned);
6. delete outliers by age and support.

Every distance is computed on the whitened human means at once (one matrix product),
so a step costs O(K h) arithmetic plus the work on the few changed components: a bound
per component, carried from step to step (:func:`distance_shrink`), with every pair's
distance at least the smaller of its two components' bounds, rules out the pairs that
cannot merge.
Nothing here mutates its arguments; the library commits a :class:`Step` in one
assignment, so a failed step leaves it as it was.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Mapping, Sequence

import numpy as np

from drake_skills.library.novelty import NoveltyRule, chi2_ppf
from drake_skills.promp.gaussian import inverse_lower, logsumexp
from drake_skills.library.scale import (BEGINNING_FRACTIONS, RECORD_TESTS, Cluster, SharedScale, gating_covariance,
                                        task_of)
from drake_skills.library.views import Responsibilities

_LOG_2PI = np.log(2.0 * np.pi)
#: Components whose responsibility reaches this are updated (and reported in ``Update.updated``).
UPDATED_RESPONSIBILITY = 1e-3
#: A component below this support has been learned from a single demonstration ("young"). While the
#: shared scale is more prior than data, a demonstration joins it, another component merges with it
#: and, at run time, it explains a motion only within ``LibraryConfig.single_demo_quantile``; two such
#: components do not merge at all then (``LibraryConfig.keep_single_demos_apart``).
YOUNG_SUPPORT = 1.5
#: The split's within-share test (``LibraryConfig.split_within_share``) holds once both sub-clusters have
#: this support: a half of one demonstration has no spread, one of a few says little of it (and the halves'
#: selection after the fact moves their distance little). The splits of LASA-30 (halves of 1-4) and of
#: the synthetic 1000 skills (1-2) are not touched; those of a skill shown 50-100 times are (halves of 10-100).
SPLIT_SHARE_SUPPORT = 5.0


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

    def task_name(self, mixed_task_share: float) -> str | None:
        """The task it was taught as (its main task name; None without names or when the other names hold
        ``mixed_task_share`` or more of it), kept with it once computed (components are immutable)."""
        cached = self.__dict__.get("_task_name")
        if cached is None or cached[0] != mixed_task_share:
            cached = (mixed_task_share, task_of(self.cluster.tasks, mixed_task_share))
            object.__setattr__(self, "_task_name", cached)   # a cache of derived data; the dataclass stays frozen
        return cached[1]

    def sub_within(self, h: int) -> np.ndarray:
        """(h, h): the human block of its two sub-clusters' scatters, summed (0 without a second one); what
        :func:`within_share` reads. Computed once per component (components are immutable) and kept with it,
        so a split check costs no copy of K such matrices."""
        cached = self.__dict__.get("_sub_within")
        if cached is None or cached.shape[0] != h:
            cached = _summed_scatter(*self.subclusters, h)
            cached.setflags(write=False)
            object.__setattr__(self, "_sub_within", cached)   # a cache of derived data; the dataclass stays frozen
        return cached


@dataclass(frozen=True, eq=False)
class Components:
    """The components with their gating data stacked for vectorized scoring.

    Immutable: a step of :func:`fold_in` builds a new one (its arrays are read-only).

    Attributes
    ----------
    items : tuple of ComponentModel
    means_h : array, shape (K, h)
        Human (gating) means, row k for ``items[k]``.
    support : array, shape (K,)
    created : array, shape (K,)
    sub_means_h : array, shape (K, 2, h)
        Human means of the two sub-clusters (the second 0 while it is empty).
    sub_support : array, shape (K, 2)
        Their supports (0 for an empty one).
    id_array : array of int, shape (K,)
        ``items[k].id``.
    path_length : array, shape (K,)
        Mean normalized path length of each component's demonstrations.
    tested, missed : arrays, shape (K, B)
        The components' records of beginnings (``Cluster.tested``, ``Cluster.missed``).
    merge_bound : array, shape (K,)
        Bounds of the two-sample distances under the metric of ``bound_ref``: every pair's
        distance is at least the smaller of its two components' bounds (0: unknown; not each
        component's distance to its nearest other: after a split, a half may lie nearer to a
        component than that component's bound, but the half's own bound is 0). Derived data
        that only lets :func:`fold_in` skip merge checks that cannot succeed; never stored.
    bound_ref : array, shape (h, h), or None
        Inverse Cholesky factor of the gating covariance ``merge_bound`` holds under (None: no bound).
    """

    items: tuple = ()
    means_h: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    support: np.ndarray = field(default_factory=lambda: np.zeros(0))
    created: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    sub_means_h: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 0)))
    sub_support: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    id_array: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    path_length: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tested: np.ndarray = field(default_factory=lambda: np.zeros((0, len(BEGINNING_FRACTIONS))))
    missed: np.ndarray = field(default_factory=lambda: np.zeros((0, len(BEGINNING_FRACTIONS))))
    merge_bound: np.ndarray = field(default_factory=lambda: np.zeros(0))
    bound_ref: np.ndarray | None = None

    @property
    def path_lengths(self) -> np.ndarray:
        """(K,) mean path lengths of the components' demonstrations."""
        return self.path_length

    @property
    def beginnings(self) -> tuple[np.ndarray, np.ndarray]:
        """The components' records of beginnings (``Cluster.tested``, ``Cluster.missed``), two arrays (K, B)."""
        return self.tested, self.missed

    @classmethod
    def of(cls, items: Sequence[ComponentModel], n_human: int) -> "Components":
        items = tuple(items)
        rows = [_rows(c, n_human) for c in items]
        K = len(items)
        B = len(BEGINNING_FRACTIONS)
        if K:
            means, support, created, sub_means, sub_support, ids, paths, tested, missed = (np.array(x) for x in
                                                                                          zip(*rows))
        else:
            means, support, created = np.zeros((0, n_human)), np.zeros(0), np.zeros(0, dtype=np.int64)
            sub_means, sub_support, ids, paths = np.zeros((0, 2, n_human)), np.zeros((0, 2)), np.zeros(0), np.zeros(0)
            tested, missed = np.zeros((0, B)), np.zeros((0, B))
        return cls._frozen(items, means.reshape(K, n_human), support.astype(float), created.astype(np.int64),
                           sub_means.reshape(K, 2, n_human), sub_support.reshape(K, 2), ids.astype(np.int64),
                           paths.astype(float), tested.reshape(K, B).astype(float), missed.reshape(K, B).astype(float),
                           np.zeros(K))

    @classmethod
    def _frozen(cls, items, *arrays, bound_ref: np.ndarray | None = None) -> "Components":
        for a in arrays:
            a.setflags(write=False)
        if bound_ref is not None:
            bound_ref.setflags(write=False)
        return cls(items, *arrays, bound_ref=bound_ref)

    def __len__(self) -> int:
        return len(self.items)

    @cached_property
    def ids(self) -> tuple[int, ...]:
        return tuple(self.id_array.tolist())          # Python ints, in one C loop (1000 of them: 10 us)

    def index(self, component_id: int) -> int:
        """Row of the component with this id (KeyError if there is none)."""
        hit = np.flatnonzero(self.id_array == component_id)
        if not hit.size:
            raise KeyError(component_id)
        return int(hit[0])


def _rows(c: ComponentModel, h: int):
    """The stacked data of one component: mean, support, created, sub-cluster means and supports, id, path length,
    record of beginnings."""
    a, b = c.subclusters
    sm = np.zeros((2, h))
    ss = np.zeros(2)
    sm[0], ss[0] = a.mean[:h], a.support
    if b is not None:
        sm[1], ss[1] = b.mean[:h], b.support
    return (c.cluster.mean[:h], c.cluster.support, c.created, sm, ss, c.id, c.cluster.path_length, c.cluster.tested,
            c.cluster.missed)


class _Work:
    """A mutable working copy of the components during one step (private to :func:`fold_in`).

    The arrays are copied once into buffers with spare rows, so that appending a
    component (creation, split) writes one row instead of copying all K; removing
    (merge, deletion) compacts them. :meth:`freeze` hands the buffers to a new
    :class:`Components` (this object is not used after that).
    """

    def __init__(self, comps: Components, h: int):
        K = len(comps.items)
        self.items = list(comps.items)
        self.h = h
        cap = K + 4
        self._means = _grown(comps.means_h, cap)
        self._support = _grown(comps.support, cap)
        self._created = _grown(comps.created, cap)
        self._sub_means = _grown(comps.sub_means_h, cap)
        self._sub_support = _grown(comps.sub_support, cap)
        self._ids = _grown(comps.id_array, cap)
        self._paths = _grown(comps.path_length, cap)
        self._tested = _grown(comps.tested, cap)
        self._missed = _grown(comps.missed, cap)
        self._bound = _grown(comps.merge_bound, cap)
        self.bound_ref = comps.bound_ref
        self.n = K

    # views of the current rows
    @property
    def means_h(self) -> np.ndarray:
        return self._means[:self.n]

    @property
    def support(self) -> np.ndarray:
        return self._support[:self.n]

    @property
    def created(self) -> np.ndarray:
        return self._created[:self.n]

    @property
    def sub_means_h(self) -> np.ndarray:
        return self._sub_means[:self.n]

    @property
    def sub_support(self) -> np.ndarray:
        return self._sub_support[:self.n]

    @property
    def ids(self) -> np.ndarray:
        return self._ids[:self.n]

    @property
    def merge_bound(self) -> np.ndarray:
        """Writable: the rows' merge bounds (see :class:`Components`; 0 once the row changed)."""
        return self._bound[:self.n]

    def _buffers(self) -> tuple:
        return (self._means, self._support, self._created, self._sub_means, self._sub_support, self._ids,
                self._paths, self._tested, self._missed, self._bound)

    def set(self, i: int, c: ComponentModel) -> None:
        self.items[i] = c
        for buf, row in zip(self._buffers(), _rows(c, self.h)):
            buf[i] = row
        self._bound[i] = 0.0  # a changed component's distances are unknown

    def append(self, c: ComponentModel) -> None:
        if self.n == self._means.shape[0]:
            cap = 2 * self.n + 4
            (self._means, self._support, self._created, self._sub_means, self._sub_support, self._ids,
             self._paths, self._tested, self._missed, self._bound) = (_grown(a[:self.n], cap) for a in self._buffers())
        self.items.append(None)
        self.n += 1
        self.set(self.n - 1, c)

    def remove(self, idx) -> None:
        keep = np.ones(self.n, bool)
        keep[np.atleast_1d(np.asarray(idx, dtype=int))] = False
        self.items = [c for c, k in zip(self.items, keep) if k]
        n = int(keep.sum())
        for a in self._buffers():
            a[:n] = a[:self.n][keep]
        self.n = n

    def index(self, cid: int) -> int:
        hit = np.flatnonzero(self.ids == cid)
        if not hit.size:
            raise KeyError(cid)
        return int(hit[0])

    def freeze(self) -> Components:
        return Components._frozen(tuple(self.items), *(a[:self.n] for a in self._buffers()), bound_ref=self.bound_ref)


def single_demo_rule(config, scale: SharedScale, *, beginning: bool = False) -> float | None:
    """The chi-square quantile a young component (:data:`YOUNG_SUPPORT`) is held to now, or None.

    None (no limit beyond the novelty and merge tests) with the rule off (``single_demo_quantile``
    1) or with the log-likelihood test; for a whole motion (learning, merging, recognition) also
    once the shared scale is more data than prior (pooled degrees of freedom ``nu >=
    prior_strength``). A *beginning* (``beginning=True``: recognition from a prefix, its phase
    estimated) is held to it at every ``nu``: the phase is searched for the best fit, and a
    component seen once has no spread of its own to say where along it a beginning may lie (on
    the buetepage test split the first 20 % of a hand wave was taken, at phase 0.85, for the
    whole of a one-demonstration rocket fragment, at d^2 30-38 of 15 dof, in 14 of 180 answers;
    RESULTS.md, "A skill seen once"). Learning, recognition and ``drake-skills recognize`` ask
    this one function.
    """
    q = config.single_demo_quantile
    if q >= 1 or config.novelty_test != "chi2" or (scale.dof >= config.prior_strength and not beginning):
        return None
    return q


def _any_named(items) -> bool:
    return any(c.cluster.tasks for c in items)


def _young_limit(config, h: int, scale: SharedScale) -> float | None:
    """The whole-motion distance within which a young component takes a demonstration or merges (None: no limit)."""
    q = single_demo_rule(config, scale)
    return None if q is None else chi2_ppf(q, h)


def _grown(a: np.ndarray, rows: int) -> np.ndarray:
    """A writable copy of ``a`` with ``rows`` rows (the first ``len(a)`` are ``a``)."""
    out = np.empty((rows,) + a.shape[1:], dtype=a.dtype)
    out[:a.shape[0]] = a
    return out


@dataclass(frozen=True)
class Metric:
    """The gating metric: ``Sigma`` (h, h), the inverse of its Cholesky factor, its log-determinant, the factor."""

    cov: np.ndarray
    inv_chol: np.ndarray
    logdet: float
    chol: np.ndarray | None = None

    @classmethod
    def of(cls, cov: np.ndarray) -> "Metric":
        L = np.linalg.cholesky(cov)
        return cls(cov, inverse_lower(L), float(2.0 * np.sum(np.log(np.diag(L)))), L)

    def whiten(self, x: np.ndarray) -> np.ndarray:
        """``L^{-1} x`` for rows of ``x`` (n, h) or one (h,)."""
        return x @ self.inv_chol.T


def gating_metric(scale: SharedScale, n_human: int, config) -> Metric:
    """The :class:`Metric` of the shared gating covariance of ``scale`` (see :mod:`~drake_skills.library.scale`)."""
    return Metric.of(gating_covariance(scale, n_human, prior_scale=config.prior_scale,
                                       prior_strength=config.prior_strength, shrinkage=config.shrinkage,
                                       prior_floor=config.prior_floor))


def gating_scores(w_h: np.ndarray, comps: Components, metric: Metric,
                  whitened: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``log p(w_h | k)`` and the squared Mahalanobis distance ``d^2_k``, shapes (K,).

    The predictive covariance of component k is ``Sigma (1 + 1/s_k)`` (the shared
    within-skill covariance plus the uncertainty of the component's mean).
    ``whitened``: ``metric.whiten(comps.means_h)`` if already known (K, h).
    """
    h = w_h.shape[0]
    if not len(comps):
        return np.zeros(0), np.zeros(0)
    inflate = 1.0 + 1.0 / comps.support
    Z = metric.whiten(comps.means_h) if whitened is None else whitened
    diff = Z - metric.whiten(w_h)
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


def within_share(a: Cluster, b: Cluster, metric: Metric, h: int) -> float:
    """The share of a component's spread along the line through its sub-clusters' means that lies within them.

    With the whitened difference ``dz`` of the two human means, ``u = dz / |dz|``, the
    sub-clusters' scatters ``S_a``, ``S_b`` (whitened) and supports ``s_a``, ``s_b``::

        W = u' (S_a + S_b) u,    B = s_a s_b / (s_a + s_b) |dz|^2,    share = W / (W + B)

    (1 - share is the part of the spread along ``u`` that lies between the two means). A Gaussian
    cut at its mean leaves 1 - 2/pi = 0.36 within the halves, two equal Gaussians D standard
    deviations apart ``1 / (1 + D^2 / 4)``. Sub-clusters of one demonstration each have no scatter:
    0. Identical means: 1.
    """
    dz = metric.whiten(a.mean[:h] - b.mean[:h])
    if not float(dz @ dz) > 0.0:
        return 1.0
    return float(_shares(dz[None], _summed_scatter(a, b, h)[None], np.array([a.support]), np.array([b.support]),
                         np.array([a.support + b.support]), metric)[0])


def _summed_scatter(a: Cluster, b: Cluster | None, h: int) -> np.ndarray:
    """(h, h): the human block of the scatters of ``a`` and ``b``, summed; 0 without ``b`` (nothing to split)."""
    F = np.column_stack([a.factor[:h], b.factor[:h]]) if b is not None else np.zeros((h, 0))
    return F @ F.T


def _shares(dz: np.ndarray, within_scatter: np.ndarray, sa: np.ndarray, sb: np.ndarray, s: np.ndarray,
            metric: Metric) -> np.ndarray:
    """:func:`within_share` of n components at once: their halves' whitened mean differences ``dz`` (n, h,
    nonzero), summed human scatters (n, h, h), the halves' supports and the components'."""
    between = np.einsum("ij,ij->i", dz, dz)
    v = (dz / np.sqrt(between)[:, None]) @ metric.inv_chol  # u' L^-1: the whitened direction in raw human weights
    within = np.einsum("ri,rij,rj->r", v, within_scatter, v)
    return within / (within + between * sa * sb / s)


def _within_shares(work: "_Work", rows: np.ndarray, dz: np.ndarray, metric: Metric) -> list[float]:
    """:func:`within_share` of the components in ``rows`` at once; ``dz`` (len(rows), h): their halves' whitened
    mean differences (nonzero: the rows passed the split quantile)."""
    if not rows.size:
        return []
    h = dz.shape[1]
    scatter = np.stack([work.items[int(i)].sub_within(h) for i in rows])
    return _shares(dz, scatter, work.sub_support[rows, 0], work.sub_support[rows, 1], work.support[rows],
                   metric).tolist()


def distance_shrink(inv_chol_old: np.ndarray | None, metric: Metric) -> float:
    """A factor ``f`` with ``|x|^2_new >= f |x|^2_old`` for every ``x``: how far any squared distance can shrink.

    ``|x|^2_old = |L_old^{-1} x|^2`` and ``|x|^2_new = |L_new^{-1} x|^2``; with ``y = L_old^{-1} x``
    and ``A = L_old^{-1} L_new``, ``|y| = |A L_new^{-1} x| <= |A|_2 |x|_new``, so
    ``f = 1 / |A|_2^2``, and ``|A|_2^2 <= |A|_1 |A|_inf`` (a bound without a decomposition: a few
    microseconds, and tight when the metric changed little). Taken a hair low (1e-9), so that
    rounding never makes a bound exceed the distance it bounds. 0 without an old metric.
    """
    if inv_chol_old is None:
        return 0.0
    A = np.abs(inv_chol_old @ metric.chol)
    return (1.0 - 1e-9) / float(A.sum(axis=0).max() * A.sum(axis=1).max())


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
    responsibilities: Mapping
    #: Component id -> index (0 or 1) of the sub-cluster the demonstration joined.
    subcluster: dict
    history: tuple[dict, ...]
    #: The gating metric of ``scale`` when the step computed it (None otherwise): the library's
    #: next queries and update start from it instead of factoring the same covariance again.
    metric: Metric | None = None


def _new_component(cid: int, created: int, w, duration: float, path_length: float,
                   pending: np.ndarray | None = None, task: str | None = None) -> ComponentModel:
    cl = Cluster.of_sample(w, duration, path_length, pending=pending, task=task)
    return ComponentModel(cid, created, cl, (cl, None))


def fold_in(comps: Components, scale: SharedScale, w: np.ndarray, duration: float, path_length: float, *,
            n_human: int, config, rule: NoveltyRule, next_id: int, demo_index: int, fit_residual: float = 0.0,
            beginnings=None, task: str | None = None) -> Step:
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
    beginnings : callable, optional
        ``beginnings(k)`` -> (B,) or None: whether component row ``k`` of ``comps`` rejects the
        demonstration's beginnings at :data:`~drake_skills.library.scale.BEGINNING_FRACTIONS`
        of its path (1, 0, or NaN: not tested; None: nothing tested, e.g. a full record), asked
        before the update of the component that takes at least half of the demonstration (unless
        its record holds ``RECORD_TESTS`` at every share), and
        added to its record of beginnings (``Cluster.tested``, ``Cluster.missed``; its
        sub-cluster's too); for a novel demonstration, of the nearest component, kept as the new
        component's pending test (``Cluster.pending``, counted if it merges). None: no record.
    task : str, optional
        The demonstration's task name, counted in the clusters it joins at their responsibility
        (``Cluster.tasks``); with ``keep_tasks_apart`` it joins no component taught as another task
        (``ComponentModel.task_name``), and merges follow the names (``same_task_reach``, ``keep_tasks_apart``).
    """
    h = n_human
    work = _Work(comps, h)
    scale = scale.count(w, fit_residual)
    created, updated, merged, split, deleted = [], [], [], [], []
    history: list[dict] = []
    resp: Mapping = {}
    subs: dict = {}
    recognized = None

    last: list = [None, None]  # (scale, its metric): the merge loop and the split step often see one scale

    def metric_of(s: SharedScale) -> Metric:
        if last[0] is not s:
            last[:] = [s, gating_metric(s, h, config)]
        return last[1]

    # 1-2. novelty against the scale learned so far (totals including this demonstration)
    novel = True
    if len(work.items):
        metric = metric_of(scale)
        logp, d2 = gating_scores(w[:h], comps, metric)
        fits = ~rule.novel(logp, d2, h)
        young_limit = _young_limit(config, h, scale)
        if young_limit is not None:
            fits &= ~((comps.support < YOUNG_SUPPORT) & (d2 > young_limit))
        if task is not None and config.keep_tasks_apart:  # the teacher said it is another task: not one of these
            for i in np.flatnonzero(fits):
                name = comps.items[i].task_name(config.mixed_task_share)
                fits[i] = name is None or name == task
        novel = not fits.any()
    # 3. update
    if novel:
        # its beginnings against the nearest component: they join its record if it merges (Cluster.pending)
        # (the nearest it may join: a component taught as another task is none of its concern, keep_tasks_apart)
        pending = None
        if beginnings is not None and len(comps.items):
            apart = task is not None and config.keep_tasks_apart
            for k in (np.argsort(d2, kind="stable") if apart else (int(np.argmin(d2)),)):
                if not apart or comps.items[k].task_name(config.mixed_task_share) in (None, task):
                    pending = beginnings(int(k))
                    break
        work.append(_new_component(next_id, demo_index, w, duration, path_length, pending, task))
        created.append(next_id)
        history.append({"event": "created", "id": next_id, "demo": demo_index})
        next_id += 1
    else:
        lam = responsibilities(logp, comps.support, fits)
        recognized = comps.items[int(np.argmax(lam))].id
        resp = Responsibilities(comps.id_array, lam)
        zw = metric.whiten(w[:h])
        for i in np.flatnonzero(lam >= UPDATED_RESPONSIBILITY):
            c, l = comps.items[i], float(lam[i])
            # the record of beginnings: only the component the demonstration mostly joins
            full = c.cluster.tested.min() >= RECORD_TESTS   # a full record is not tested again
            missed = beginnings(int(i)) if beginnings is not None and l >= 0.5 and not full else None
            cluster, g = c.cluster.add(w, l, duration, path_length, missed, task)
            scale = scale.with_scatter(g, +1.0, l)
            a, b = c.subclusters
            if b is None:
                j, b = 1, Cluster.of_sample(w, duration, path_length, support=l, missed=missed, task=task)
            else:
                da = metric.whiten(a.mean[:h]) - zw
                db = metric.whiten(b.mean[:h]) - zw
                j = int(db @ db < da @ da)
                if j == 0:
                    a = a.add(w, l, duration, path_length, missed, task)[0]
                else:
                    b = b.add(w, l, duration, path_length, missed, task)[0]
            work.set(int(i), ComponentModel(c.id, c.created, cluster, (a, b)))
            updated.append(c.id)
            subs[c.id] = j

    # 4. merge (Eqs. 10-11): every pair within the merge threshold, the closest first. Algorithm 1
    #    checks every component (past its merge age), not only those the update changed: the learned
    #    scale moves under all of them and can bring two that did not change within the threshold (a
    #    skill shown several times in a row fragments while the scale is still its prior, and its
    #    fragments never change again). work.merge_bound, carried from step to step and shrunk by as
    #    much as the metric can have shrunk any distance since, keeps every pair's distance at least
    #    the smaller of its two components' bounds, so the rows of the components whose bound is within
    #    the merge limit find every pair that can merge; the result is that of scoring every pair.
    while len(work.items) > 1:
        metric = metric_of(scale)
        young_limit = _young_limit(config, h, scale)
        bound = work.merge_bound
        if work.bound_ref is not metric.inv_chol:
            bound *= distance_shrink(work.bound_ref, metric)
            work.bound_ref = metric.inv_chol
        # components taught as one task merge within same_task_reach merge limits (a library without names: 1)
        # and components taught as different tasks never merge (keep_tasks_apart); a library without names: as before
        named = (config.same_task_reach != 1.0 or config.keep_tasks_apart) and _any_named(work.items)
        reach = config.same_task_reach if named else 1.0
        limit = rule.merge_limit(work.support, metric.logdet, h)
        rows = np.flatnonzero(~(bound >= reach * limit))  # NaN: scored
        if not rows.size:
            break
        share = config.mixed_task_share
        Z = metric.whiten(work.means_h)
        ids = work.ids
        best = None
        for i in rows:
            d2m = two_sample_d2(Z, work.support, i)
            np.minimum(bound, d2m, out=bound)  # exact distances tighten the partners' bounds too
            bound[i] = d2m.min()
            if config.merge_min_age > 0:  # the paper's v_min^merge: the older of the two must be past it
                ages = (demo_index + 1) - np.minimum(work.created, work.created[i])
                d2m = np.where(ages > config.merge_min_age, d2m, np.inf)
            raw = d2m   # the single-demonstration limit below holds on the distance itself, names or not
            name = work.items[i].task_name(share) if named else None
            if name is not None:  # only pairs within reach x the largest limit can merge: their names are read
                d2m = d2m.copy()
                for k in np.flatnonzero(d2m < reach * limit):
                    other = work.items[k].task_name(share)
                    if other == name:
                        d2m[k] /= reach
                    elif other is not None and config.keep_tasks_apart:
                        d2m[k] = np.inf
            score = rule.merge_scores(d2m, np.maximum(work.support, work.support[i]),
                                      1.0 / work.support + 1.0 / work.support[i], metric.logdet, h)
            if young_limit is not None:  # a pair with a component seen once merges only within its limit
                young = (work.support < YOUNG_SUPPORT) | (work.support[i] < YOUNG_SUPPORT)
                score = np.where(young & (raw > young_limit), np.inf, score)
                if config.keep_single_demos_apart and work.support[i] < YOUNG_SUPPORT:  # two seen once: never
                    score = np.where(work.support < YOUNG_SUPPORT, np.inf, score)
            j = int(np.argmin(score))
            tied = np.flatnonzero(score == score[j])
            if tied.size > 1:
                j = int(tied[np.argmin(ids[tied])])
            # the same key whichever of the two rows finds the pair: of equal scores the pair of lowest ids merges
            key = (float(score[j]), min(int(ids[i]), int(ids[j])), max(int(ids[i]), int(ids[j])))
            if key[0] < 0.0 and (best is None or key < best[0]):
                best = (key, int(i), j)
        if best is None:
            break
        _, i, j = best
        a, b = work.items[i], work.items[j]
        keep, gone = (a, b) if (a.support, -a.id) >= (b.support, -b.id) else (b, a)
        pooled, g = keep.cluster.pool(gone.cluster)
        scale = scale.with_scatter(g, +1.0, 1.0)
        halves = tuple(replace(c.cluster, pending=np.full_like(c.cluster.pending, np.nan)) for c in (keep, gone))
        new = ComponentModel(keep.id, min(keep.created, gone.created), pooled, halves)  # pending tests counted once
        work.set(work.index(keep.id), new)
        work.remove(work.index(gone.id))
        merged.append((keep.id, gone.id))
        history.append({"event": "merged", "into": keep.id, "absorbed": gone.id, "demo": demo_index})

    # 5. split a component whose halves have grown apart (all components: the scale may
    #    have shrunk under one that did not change)
    if len(work.items):
        metric = metric_of(scale)
        sa, sb = work.sub_support[:, 0], work.sub_support[:, 1]
        both = sb > 0
        if both.any():
            dz = metric.whiten(work.sub_means_h[:, 0] - work.sub_means_h[:, 1])
            d2s = np.where(both, np.einsum("ij,ij->i", dz, dz) / (1.0 / sa + 1.0 / np.where(both, sb, 1.0)), 0.0)
            rows = np.flatnonzero(rule.splits(d2s, h) & both)
            if config.same_task_reach != 1.0 and rows.size:  # halves taught as one task: only beyond the same reach
                for i in rows:  # (the reach only shrinks d2s: the candidates are among these rows)
                    a, b = work.items[int(i)].subclusters
                    name = task_of(a.tasks, config.mixed_task_share)
                    if name is not None and name == task_of(b.tasks, config.mixed_task_share):
                        d2s[i] /= config.same_task_reach
                rows = rows[rule.splits(d2s[rows], h)]
            shares = _within_shares(work, rows, dz[rows], metric)
            for i, share in zip(rows, shares):
                c = work.items[int(i)]
                a, b = c.subclusters
                if share > config.split_within_share and min(a.support, b.support) >= SPLIT_SHARE_SUPPORT:
                    continue  # one skill cut in two after the fact, not two skills
                g = np.sqrt(a.support * b.support / c.support) * (a.mean - b.mean)
                scale = scale.with_scatter(g, -1.0, -1.0)
                # the first sub-cluster keeps the id (after a merge: the kept component's own half)
                work.set(int(i), ComponentModel(c.id, c.created, a, (a, None)))
                work.append(ComponentModel(next_id, c.created, b, (b, None)))
                split.append((c.id, next_id))
                history.append({"event": "split", "id": c.id, "new": next_id, "demo": demo_index,
                                "within": round(share, 6)})
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
                tuple(split), tuple(deleted), resp, subs, tuple(history), last[1] if last[0] is scale else None)
