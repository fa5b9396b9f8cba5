"""Algorithm 1 as pure functions: one demonstration's weights in, the new components out.

:func:`fold_in` is the whole step of ``SkillLibrary.partial_fit``; it calls, in order,

1. novelty: :func:`gating_scores` and the rule of :mod:`drake_skills.library.novelty`;
2. update: :func:`new_component` (Eq. 9) or :func:`update_components` (Eqs. 5-8,
   each with :func:`incremental_update`);
3. merge: :func:`merge_pass` (Eqs. 10-11);
4. delete: :func:`prune`.

Nothing here mutates its arguments: components are immutable
:class:`ComponentModel` objects, replaced when they change, so a failed step leaves
the library as it was and the library commits a :class:`Step` in one assignment.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np
from scipy.special import logsumexp

from drake_skills.library.config import LibraryConfig
from drake_skills.library.novelty import NoveltyRule, novelty_rule
from drake_skills.library.state import ComponentState
from drake_skills.promp.gaussian import cholesky, log_density_from_mahalanobis, mahalanobis_sq, merge_moments, \
    symmetrize

#: Components whose responsibility reaches this count as updated (``Update.updated``) and are checked for merges.
UPDATED_RESPONSIBILITY = 1e-3


@dataclass(frozen=True, eq=False)
class ComponentModel(ComponentState):
    """A component as the algorithm uses it: its state and the factor of its gating covariance.

    Attributes
    ----------
    chol_gating : array, shape (h, h)
        Lower Cholesky factor of the floored gating covariance
        ``cov[:h, :h] + gating_floor I`` (h = number of human weights).
    """

    chol_gating: np.ndarray

    @classmethod
    def of(cls, state: ComponentState, n_human: int, gating_floor: float) -> "ComponentModel":
        """The model of a component state (its gating factor computed)."""
        return cls(state.id, state.age, state.support, state.mean, state.cov, state.duration,
                   gating_cholesky(state.cov, n_human, gating_floor))

    def state(self) -> ComponentState:
        """The plain state (without the factor)."""
        return ComponentState(self.id, self.age, self.support, self.mean, self.cov, self.duration)


@dataclass(frozen=True, eq=False)
class Step:
    """What :func:`fold_in` did: the new components and what to report and record."""

    components: tuple[ComponentModel, ...]
    next_id: int
    #: Component that explained the demonstration best before the update (None if novel).
    recognized: int | None
    created: tuple[int, ...]
    updated: tuple[int, ...]
    merged: tuple[tuple[int, int], ...]
    deleted: tuple[int, ...]
    #: Component id -> responsibility, for every component before the update (empty if novel).
    responsibilities: dict
    #: Events for the library's history, in order.
    history: tuple[dict, ...]


def incremental_update(mean, cov, support: float, w, lam: float, fast_forgetting: bool = True):
    """One responsibility-weighted update of a component (Eqs. 6-8).

    Parameters
    ----------
    mean : array, shape (d,)
    cov : array, shape (d, d)
    support : float
        s_k before the update.
    w : array, shape (d,)
        The new weight vector.
    lam : float
        Its responsibility lambda_kn in (0, 1].
    fast_forgetting : bool
        Use gamma~ = gamma + exp(-s) lambda (Eq. 6) for the covariance.

    Returns
    -------
    mean, cov, support, gamma

    Notes
    -----
    With ``e = w - mu_old``, ``gamma = lam / s`` and ``s = s_old + lam``::

        mu  = mu_old + gamma e                                     # Eq. (7)
        C   = (1 - gamma~) C_old + gamma~ (1 - gamma) e e^T          # Eqs. (7)-(8), corrected

    With ``gamma~ = gamma`` this is exactly the running weighted (biased)
    covariance, the initial component counting as one pseudo-sample with
    covariance Sigma_init.  (Eqs. 7-8 as printed, ``gamma (w - mu)(w - mu)^T``
    with the *new* mean, drop a factor ``(1 - gamma)`` of the scatter.)
    """
    s = support + lam
    gamma = lam / s
    gamma_t = min(gamma + np.exp(-s) * lam, 1.0) if fast_forgetting else gamma
    e = w - mean
    mean = mean + gamma * e
    cov = symmetrize((1.0 - gamma_t) * cov + (gamma_t * (1.0 - gamma)) * np.outer(e, e))
    return mean, cov, s, gamma


def gating_cholesky(cov, n_human: int, gating_floor: float) -> np.ndarray:
    """Cholesky factor (h, h) of the gating covariance ``cov[:h, :h]`` plus the floor (h = ``n_human``)."""
    h = n_human
    return cholesky(cov[:h, :h] + gating_floor * np.eye(h))


def gating_scores(w_h, components: Sequence[ComponentModel]) -> tuple[np.ndarray, np.ndarray]:
    """``log p(w_h | k)`` and the squared Mahalanobis distance, shapes (K,), under the floored gating."""
    K = len(components)
    logp, d2 = np.empty(K), np.empty(K)
    h = w_h.shape[0]
    for i, c in enumerate(components):
        d2[i] = mahalanobis_sq(w_h, c.mean[:h], c.chol_gating)
        logp[i] = log_density_from_mahalanobis(d2[i], c.chol_gating)
    return logp, d2


def responsibilities(log_likelihoods, components: Sequence[ComponentModel]) -> np.ndarray:
    """p(k | w_h) (Eq. 5), shape (K,), with priors alpha_k = s_k / sum_j s_j."""
    total = sum(c.support for c in components)
    log_alpha = np.log([c.support / total for c in components])
    a = log_likelihoods + log_alpha
    return np.exp(a - logsumexp(a))


def new_component(component_id: int, w, duration: float, n_human: int, config: LibraryConfig) -> ComponentModel:
    """Eq. (9): a component at the weights ``w`` (d,) with Sigma_init, support 1 and age 1."""
    init = np.full(w.shape[0], config.sigma_init_human ** 2)
    init[n_human:] = config.sigma_init_robot ** 2
    cov = np.diag(init)
    return ComponentModel(component_id, 1, 1.0, w.copy(), cov, duration,
                          gating_cholesky(cov, n_human, config.gating_floor))


def update_components(components: Sequence[ComponentModel], w, lam: np.ndarray, duration: float, n_human: int,
                      config: LibraryConfig) -> tuple[list[ComponentModel], list[int]]:
    """Eqs. (6)-(8) for every component with a positive responsibility; all age by one.

    Returns the new components and the ids whose responsibility reached
    :data:`UPDATED_RESPONSIBILITY`.
    """
    out, updated = [], []
    for c, l in zip(components, lam):
        if l <= 0.0:
            out.append(replace(c, age=c.age + 1))
            continue
        mean, cov, s, gamma = incremental_update(c.mean, c.cov, c.support, w, float(l), config.fast_forgetting)
        dur = c.duration + gamma * (duration - c.duration)
        out.append(ComponentModel(c.id, c.age + 1, s, mean, cov, dur,
                                  gating_cholesky(cov, n_human, config.gating_floor)))
        if l >= UPDATED_RESPONSIBILITY:
            updated.append(c.id)
    return out, updated


def merge_pass(components: Sequence[ComponentModel], changed: set[int], n_human: int, rule: NoveltyRule,
               config: LibraryConfig) -> tuple[list[ComponentModel], list[tuple[int, int]]]:
    """Eqs. (10)-(11): merge while some pair qualifies, best pair first.

    A component older than ``merge_min_age`` is checked against the changed
    components (all others if it changed itself); the pair with the lowest
    ``rule.merge_scores`` below 1 is merged into the one with more support
    (moment matching, :func:`~drake_skills.promp.gaussian.merge_moments`), and the
    pass repeats with the merged component as changed.

    Returns the components and the ``(kept, absorbed)`` id pairs, in order.
    """
    comps, changed, merged = list(components), set(changed), []
    h = n_human
    while len(comps) > 1 and changed:
        best = None  # (score, i, j): merge j into i
        means = np.stack([c.mean[:h] for c in comps])
        for i, ci in enumerate(comps):
            if ci.age <= config.merge_min_age:
                continue
            if ci.id in changed:
                js = [j for j in range(len(comps)) if j != i]
            else:
                js = [j for j, cj in enumerate(comps) if cj.id in changed and j != i]
            if not js:
                continue
            score = rule.merge_scores(mahalanobis_sq(means[js], ci.mean[:h], ci.chol_gating), ci.support,
                                      ci.chol_gating)
            k = int(np.argmin(score))
            if score[k] < 1 and (best is None or score[k] < best[0]):
                best = (float(score[k]), i, js[k])
        if best is None:
            break
        _, i, j = best
        a, b = comps[i], comps[j]
        keep, gone = (a, b) if a.support >= b.support else (b, a)
        mean, cov = merge_moments(keep.support, keep.mean, keep.cov, gone.support, gone.mean, gone.cov)
        s = keep.support + gone.support
        dur = (keep.support * keep.duration + gone.support * gone.duration) / s
        new = ComponentModel(keep.id, max(keep.age, gone.age), s, mean, cov, dur,
                             gating_cholesky(cov, h, config.gating_floor))
        comps = [new if c.id == keep.id else c for c in comps if c.id != gone.id]
        merged.append((keep.id, gone.id))
        changed = (changed - {gone.id}) | {keep.id}
    return comps, merged


def prune(components: Sequence[ComponentModel], config: LibraryConfig
          ) -> tuple[list[ComponentModel], list[ComponentModel]]:
    """Deletion of outliers: components past ``delete_min_age`` with support <= ``delete_min_support`` go.

    Returns the kept and the deleted components.
    """
    keep, gone = [], []
    for c in components:
        (gone if c.age > config.delete_min_age and c.support <= config.delete_min_support else keep).append(c)
    return keep, gone


def fold_in(components: Sequence[ComponentModel], w, duration: float, *, n_human: int, config: LibraryConfig,
            next_id: int, demo_index: int, rule: NoveltyRule | None = None) -> Step:
    """Algorithm 1 for one demonstration with stacked weights ``w`` (d,) = ``[w_h; w_r]``.

    Parameters
    ----------
    components : sequence of ComponentModel
        The library's components before the demonstration.
    w : array, shape (d,)
    duration : float
        The demonstration's duration (s).
    n_human : int
        h, the number of leading human weights in ``w``.
    config : LibraryConfig
    next_id : int
        Id of a component created now.
    demo_index : int
        Index of the demonstration in the stream (for the history).
    rule : NoveltyRule, optional
        The novelty and merge tests; default :func:`~drake_skills.library.novelty.novelty_rule` of ``config``.
    """
    rule = rule if rule is not None else novelty_rule(config)
    comps = list(components)
    created, updated, resp = [], [], {}
    recognized = None
    history: list[dict] = []
    # 1. novelty (Eq. 9, Algorithm 1): is the demonstration novel for every component?
    novel = True
    if comps:
        logp, d2 = gating_scores(w[:n_human], comps)
        novel = bool(rule.novel(logp, d2, n_human).all())
    # 2. update: a new component, or every component by its responsibility
    if novel:
        # existing components age too: v counts demonstrations seen since creation
        comps = [replace(c, age=c.age + 1) for c in comps]
        comps.append(new_component(next_id, w, duration, n_human, config))
        created.append(next_id)
        history.append({"event": "created", "id": next_id, "demo": demo_index})
        next_id += 1
    else:
        lam = responsibilities(logp, comps)
        recognized = comps[int(np.argmax(lam))].id
        resp = {c.id: float(l) for c, l in zip(comps, lam)}
        comps, updated = update_components(comps, w, lam, duration, n_human, config)
    # 3. merge (Eqs. 10-11), starting from what changed
    comps, merged = merge_pass(comps, set(created) | set(updated), n_human, rule, config)
    history += [{"event": "merged", "into": kept, "absorbed": gone, "demo": demo_index} for kept, gone in merged]
    # 4. delete outliers
    comps, gone = prune(comps, config)
    history += [{"event": "deleted", "id": c.id, "demo": demo_index, "age": c.age, "support": round(c.support, 6)}
                for c in gone]
    return Step(tuple(comps), next_id, recognized, tuple(created), tuple(updated), tuple(merged),
                tuple(c.id for c in gone), resp, tuple(history))
