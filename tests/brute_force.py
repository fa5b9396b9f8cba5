"""The brute-force reference: Algorithm 1 and recognition as written before they were made flat in K (issue 19).

A plain copy of the straightforward code (a list of components, every distance and
every prefix statistic computed component by component) that the optimized library
must agree with: same components, same updates, same answers. Used by
``test_scale.py``; importable as ``brute_force`` (tests/ is on the path).
"""
from __future__ import annotations

import numpy as np
from scipy.special import logsumexp

from drake_skills.library import recognition
from drake_skills.library import scale as scale_module
from drake_skills.library.algorithm import ComponentModel
from drake_skills.library.novelty import chi2_ppf
from drake_skills.library.scale import Cluster, SharedScale, gating_covariance, observation_noise
from drake_skills.promp.basis import ridge_weights
from drake_skills.promp.gaussian import inverse_lower
from drake_skills.promp.interaction import prefix_statistics

_LOG_2PI = np.log(2.0 * np.pi)
#: The phases prefix recognition tries (1/20 ... 1) and its band around the path-length guess.
PHASE_GRID = tuple(np.round(np.arange(1, 21) / 20.0, 6))
PHASE_BAND = 1.5


def unshrink(cfg, h):
    """``S^-1 = I + beta (Phi^T Phi)^-1`` per dimension (h, h): ridge weights to least-squares weights.

    Written from the identity ``(G + beta I)^-1 G`` inverted in closed form, not as the
    library computes it (a pseudo-inverse of the solved product).
    """
    Phi = cfg.basis_human.phi_uniform(cfg.n_samples)
    G = Phi.T @ Phi
    N = G.shape[0]
    return np.kron(np.eye(h // N), np.eye(N) + cfg.ridge * np.linalg.inv(G))


def _metric(scale, h, cfg):
    cov = gating_covariance(scale, h, prior_scale=cfg.prior_scale, prior_strength=cfg.prior_strength,
                            shrinkage=cfg.shrinkage, prior_floor=cfg.prior_floor)
    L = np.linalg.cholesky(cov)
    Linv = inverse_lower(L)   # the library's routine (exact comparisons need its rounding), checked against numpy's
    assert np.allclose(Linv, np.linalg.inv(L), rtol=1e-10, atol=1e-12 * np.abs(Linv).max())
    return cov, Linv, float(2.0 * np.sum(np.log(np.diag(L))))


def _scores(w_h, means, support, metric):
    cov, Linv, logdet = metric
    h = w_h.shape[0]
    inflate = 1.0 + 1.0 / support
    diff = means @ Linv.T - w_h @ Linv.T
    d2 = np.einsum("ij,ij->i", diff, diff) / inflate
    return -0.5 * (h * _LOG_2PI + logdet + h * np.log(inflate) + d2), d2


def _resp(logp, support, mask=None):
    a = logp + np.log(support / support.sum())
    if mask is not None:
        a = np.where(mask, a, -np.inf)
    if not np.isfinite(a).any():
        return np.zeros_like(a)
    return np.exp(a - logsumexp(a))


def _band(share: float) -> list:
    """The phases searched for a path-length share: within PHASE_BAND of it on the grid, and the nearest."""
    grid = np.array(PHASE_GRID)
    g = min(max(share, grid[0]), 1.0)
    band = [f for f in grid if g / PHASE_BAND - 1e-12 <= f <= min(g * PHASE_BAND, 1.0) + 1e-12]
    nearest = float(grid[np.abs(grid - g).argmin()])
    return band if nearest in band else sorted(band + [nearest])


class Reference:
    """The library's state as a list of :class:`ComponentModel`, updated by the original loop."""

    def __init__(self, config, rule, n_human):
        self.cfg, self.rule, self.h = config, rule, n_human
        self.items: list[ComponentModel] = []
        self.scale: SharedScale | None = None
        self.next_id = 0
        self.n_seen = 0

    # arrays of the current items
    def _means(self, items=None):
        items = self.items if items is None else items
        return np.array([c.mean[:self.h] for c in items]).reshape(len(items), self.h)

    def _support(self, items=None):
        return np.array([c.support for c in (self.items if items is None else items)])

    def _name(self, cluster):
        """The task a cluster was taught as: the name of most weight, None without names or if mixed."""
        t = dict(cluster.tasks)
        total = sum(t.values())
        if not total > 0:
            return None
        top = max(sorted(t), key=lambda k: t[k])
        return top if (total - t[top]) / total < self.cfg.mixed_task_share else None

    def partial_fit(self, w, duration, path_length, fit_residual, task=None) -> dict:
        cfg, rule, h = self.cfg, self.rule, self.h
        n = self.n_seen
        scale = (self.scale if self.scale is not None else SharedScale.empty(w.shape[0])).count(w, fit_residual)
        items = list(self.items)
        next_id = self.next_id
        out = dict(recognized=None, created=[], updated=[], merged=[], split=[], deleted=[], responsibilities={},
                   subcluster={})
        novel = True
        if items:
            metric = _metric(scale, h, cfg)
            logp, d2 = _scores(w[:h], self._means(items), self._support(items), metric)
            fits = ~rule.novel(logp, d2, h)
            for k, c in enumerate(items):  # seen once, on a scale more prior than data: only within its quantile
                if c.support < 1.5 and cfg.novelty_test == "chi2" and cfg.single_demo_quantile < 1 \
                        and scale.dof < cfg.prior_strength and d2[k] > chi2_ppf(cfg.single_demo_quantile, h):
                    fits[k] = False
                if task is not None and cfg.keep_tasks_apart and self._name(c.cluster) not in (None, task):
                    fits[k] = False  # taught as another task
            novel = not fits.any()
        if novel:
            cl = Cluster.of_sample(w, duration, path_length, task=task)
            items.append(ComponentModel(next_id, n, cl, (cl, None)))
            out["created"].append(next_id)
            next_id += 1
        else:
            support = self._support(items)
            lam = _resp(logp, support, fits)
            out["recognized"] = items[int(np.argmax(lam))].id
            out["responsibilities"] = {c.id: float(v) for c, v in zip(items, lam)}
            Linv = metric[1]
            zw = w[:h] @ Linv.T
            old = list(items)
            for i in np.flatnonzero(lam >= 1e-3):
                c, v = old[i], float(lam[i])
                cluster, g = c.cluster.add(w, v, duration, path_length, task=task)
                scale = scale.with_scatter(g, +1.0, v)
                a, b = c.subclusters
                if b is None:
                    j, b = 1, Cluster.of_sample(w, duration, path_length, support=v, task=task)
                else:
                    da = a.mean[:h] @ Linv.T - zw
                    db = b.mean[:h] @ Linv.T - zw
                    j = int(db @ db < da @ da)
                    if j == 0:
                        a = a.add(w, v, duration, path_length, task=task)[0]
                    else:
                        b = b.add(w, v, duration, path_length, task=task)[0]
                items[i] = ComponentModel(c.id, c.created, cluster, (a, b))
                out["updated"].append(c.id)
                out["subcluster"][c.id] = j
        # merge: every pair, the closest first
        while len(items) > 1:
            metric = _metric(scale, h, cfg)
            Z = self._means(items) @ metric[1].T
            support = self._support(items)
            created = np.array([c.created for c in items])
            best = None
            for cid in sorted(c.id for c in items):
                i = [c.id for c in items].index(cid)
                diff = Z - Z[i]
                d2m = np.einsum("ij,ij->i", diff, diff) / (1.0 / support + 1.0 / support[i])
                d2m[i] = np.inf
                if cfg.merge_min_age > 0:
                    ages = (n + 1) - np.minimum(created, created[i])
                    d2m = np.where(ages > cfg.merge_min_age, d2m, np.inf)
                raw = d2m.copy()   # the single-demonstration limit holds on the distance itself
                names = [self._name(c.cluster) for c in items]
                for j in range(len(items)):  # the teacher's names: one task merges within a wider reach, two never
                    if names[i] is not None and names[j] == names[i]:
                        d2m[j] /= cfg.same_task_reach
                    elif cfg.keep_tasks_apart and None not in (names[i], names[j]):
                        d2m[j] = np.inf
                score = rule.merge_scores(d2m, np.maximum(support, support[i]), 1.0 / support + 1.0 / support[i],
                                          metric[2], h)
                if cfg.novelty_test == "chi2" and cfg.single_demo_quantile < 1 and scale.dof < cfg.prior_strength:
                    for j in range(len(items)):  # a pair with a component seen once: only within its quantile
                        if min(support[i], support[j]) < 1.5 and raw[j] > chi2_ppf(cfg.single_demo_quantile, h):
                            score[j] = np.inf
                        if cfg.keep_single_demos_apart and max(support[i], support[j]) < 1.5:  # two seen once
                            score[j] = np.inf
                ids = [c.id for c in items]
                for j in np.flatnonzero(score < 0.0):  # every pair below the threshold; of equal scores the lowest ids
                    key = (float(score[j]), min(ids[i], ids[j]), max(ids[i], ids[j]))
                    if best is None or key < best[0]:
                        best = (key, i, int(j))
            if best is None:
                break
            _, i, j = best
            a, b = items[i], items[j]
            keep, gone = (a, b) if (a.support, -a.id) >= (b.support, -b.id) else (b, a)
            pooled, g = keep.cluster.pool(gone.cluster)
            scale = scale.with_scatter(g, +1.0, 1.0)
            new = ComponentModel(keep.id, min(keep.created, gone.created), pooled, (keep.cluster, gone.cluster))
            items = [new if c.id == keep.id else c for c in items if c.id != gone.id]
            out["merged"].append((keep.id, gone.id))
        # split
        if items:
            metric = _metric(scale, h, cfg)
            K = len(items)
            sm, ss = np.zeros((K, 2, h)), np.zeros((K, 2))
            for k, c in enumerate(items):
                a, b = c.subclusters
                sm[k, 0], ss[k, 0] = a.mean[:h], a.support
                if b is not None:
                    sm[k, 1], ss[k, 1] = b.mean[:h], b.support
            sa, sb = ss[:, 0], ss[:, 1]
            both = sb > 0
            if both.any():
                dz = (sm[:, 0] - sm[:, 1]) @ metric[1].T
                d2s = np.where(both, np.einsum("ij,ij->i", dz, dz) / (1.0 / sa + 1.0 / np.where(both, sb, 1.0)), 0.0)
                for k, c in enumerate(items):  # halves taught as one task: split only beyond the same reach
                    a, b = c.subclusters
                    if b is not None and self._name(a) is not None and self._name(a) == self._name(b):
                        d2s[k] /= cfg.same_task_reach
                for i in np.flatnonzero(rule.splits(d2s, h) & both):
                    c = items[int(i)]
                    a, b = c.subclusters
                    # apart as two skills, not as two halves of one: the spread along the line through
                    # the means, within the halves against in all (scatter matrices in whitened units)
                    Linv = metric[1]
                    u = Linv @ (a.mean[:h] - b.mean[:h])
                    u = u / np.linalg.norm(u)
                    within = sum(u @ Linv @ cl.scatter[:h, :h] @ Linv.T @ u for cl in (a, b))
                    total = within + a.support * b.support / c.support * float(dz[i] @ dz[i])
                    if within / total > cfg.split_within_share and min(a.support, b.support) >= 5.0:
                        continue
                    g = np.sqrt(a.support * b.support / c.support) * (a.mean - b.mean)
                    scale = scale.with_scatter(g, -1.0, -1.0)
                    items[int(i)] = ComponentModel(c.id, c.created, a, (a, None))
                    items.append(ComponentModel(next_id, c.created, b, (b, None)))
                    out["split"].append((c.id, next_id))
                    next_id += 1
        # delete
        K = len(items)
        min_age = cfg.delete_min_age * max(1.0, K / 5.0)
        kept = []
        for c in items:
            if (n + 1) - c.created > min_age and c.support <= cfg.delete_min_support:
                scale = scale.with_scatter(c.cluster.factor, -1.0, -(c.support - 1.0))
                out["deleted"].append(c.id)
            else:
                kept.append(c)
        self.items, self.scale, self.next_id, self.n_seen = kept, scale, next_id, n + 1
        return {k: tuple(v) if isinstance(v, list) else v for k, v in out.items()}

    # ------------------------------------------------------------- recognition
    def _decide(self, logp, d2, dof, phases, has_robot, shared_cov, shares=None, records=None, new_ll=None):
        """``records``: the library's records of beginnings by component id, ``{id: (tested, missed)}`` (the
        reference learns from weights alone, so it cannot keep them); with ``shares`` (K,), a beginning."""
        cfg = self.cfg
        support = self._support()
        fits = ~self.rule.novel(logp, d2, dof)
        answers = fits.copy()
        dofs = np.broadcast_to(dof, fits.shape)
        for k in range(len(fits)):  # a component seen once explains a motion only within its quantile (a
            # whole motion while the scale is more prior than data, a beginning always)
            if support[k] < 1.5 and cfg.novelty_test == "chi2" and cfg.single_demo_quantile < 1 \
                    and (self.scale.dof < cfg.prior_strength or shares is not None) \
                    and d2[k] > chi2_ppf(cfg.single_demo_quantile, dofs[k]):
                answers[k] = False
        resp = _resp(logp, support)
        post = _resp(logp, support, fits if answers.any() else answers)  # beyond its quantile: still a rival
        ids = tuple(c.id for c in self.items)
        best = int(np.argmax(post))
        if not answers.any():
            status, comp = "unknown", None
        elif not answers[best]:
            status, comp = "undecided", None
        elif post[best] >= 1.0 - cfg.decision_risk or \
                post[self._same(best, post > 0, has_robot, shared_cov)].sum() >= 1.0 - cfg.decision_risk:
            status, comp = "skill", ids[best]
        else:
            status, comp = "undecided", None
        blind = []
        if status == "skill" and shares is not None and records:
            F = [0.1, 0.2]
            for j, c in enumerate(self.items):
                tested, missed = records[c.id]
                rate = [m / t if t > 0 else 0.0 for t, m in zip(tested, missed)]
                if j == best or shares[j] > 0.25 or np.interp(shares[j], F, rate) <= scale_module.BLIND_RATE:
                    continue
                dof_j = float(np.broadcast_to(dof, (len(self.items),))[j])
                if d2[j] <= recognition.BLIND_REACH * chi2_ppf(cfg.novelty_quantile, dof_j) and \
                        not self._same(best, np.eye(len(self.items), dtype=bool)[j], has_robot, shared_cov)[j]:
                    blind.append(c.id)
            if blind:
                status, comp = "undecided", None
        new_skill = 0.0
        if status == "skill" and new_ll is not None and phases[best] < recognition.NEW_SKILL_PHASE:
            # a skill never taught, weighed against the components kept (LibraryConfig.new_skill_weight)
            kept = np.flatnonzero(post > 0)
            terms = [np.log(support[k]) + logp[k] for k in kept] + [np.log(cfg.new_skill_weight) + new_ll]
            new_skill = float(np.exp(terms[-1] - logsumexp(terms)))
            if new_skill >= cfg.decision_risk:
                status, comp = "undecided", None
        return dict(component=comp, ids=ids, responsibilities=resp, log_likelihoods=logp, mahalanobis_sq=d2,
                    dof=dof, status=status, phases=phases, posterior=post, blind=tuple(blind), new_skill=new_skill)

    def _same(self, best, candidates, has_robot, shared_cov):
        h = self.h
        support = self._support()
        idx = np.flatnonzero(candidates)
        out = np.zeros(len(self.items), bool)
        out[best] = True
        others = idx[idx != best]
        if not others.size:
            return out
        block = slice(h, None) if has_robot else slice(0, h)
        S = shared_cov[block, block] * (1.0 + 1.0 / support[best])
        Linv = inverse_lower(np.linalg.cholesky(S))
        mb = self.items[best].mean[block]
        diff = np.stack([self.items[j].mean[block] - mb for j in others]) @ Linv.T
        d2 = np.einsum("ij,ij->i", diff, diff)
        out[others] = d2 <= chi2_ppf(self.cfg.novelty_quantile, S.shape[0])
        return out

    def _noise(self):
        return observation_noise(self.scale, self.cfg.observation_noise)

    def recognize_fixed(self, y, observed_fraction, has_robot, shared_cov) -> dict:
        """A beginning of a known fraction (or a whole motion): the record of beginnings plays no part."""
        cfg, h = self.cfg, self.h
        metric = _metric(self.scale, h, cfg)
        K = len(self.items)
        if observed_fraction == 1:
            w_h = ridge_weights(y, cfg.basis_human, cfg.ridge)
            logp, d2 = _scores(w_h, self._means(), self._support(), metric)
            return self._decide(logp, d2, h, np.ones(K), has_robot, shared_cov)
        Phi_o = cfg.basis_human.phi(np.linspace(0.0, observed_fraction, y.shape[0]))
        U = unshrink(cfg, h)
        logp, d2, dof = np.empty(K), np.empty(K), np.empty(K)
        for i, c in enumerate(self.items):
            logp[i], d2[i], dof[i] = prefix_statistics(U @ c.mean[:h], U @ metric[0] @ U.T * (1.0 + 1.0 / c.support),
                                                       Phi_o, y, self._noise())
        return self._decide(logp, d2, dof, np.full(K, observed_fraction), has_robot, shared_cov)

    def recognize_prefix(self, ys, length, has_robot, shared_cov, records=None) -> dict:
        """``ys``: the observed path resampled as the library resamples it; ``length``: its path length."""
        cfg, h = self.cfg, self.h
        metric = _metric(self.scale, h, cfg)
        K = len(self.items)
        logp, d2, dof, phases, shares = np.empty(K), np.empty(K), np.empty(K), np.empty(K), np.empty(K)
        m = ys.shape[0]
        U = unshrink(cfg, h)
        for i, c in enumerate(self.items):
            shares[i] = length / max(c.cluster.path_length, 1e-12)
            band = _band(shares[i])
            stats = [prefix_statistics(U @ c.mean[:h], U @ metric[0] @ U.T * (1.0 + 1.0 / c.support),
                                       cfg.basis_human.phi(np.linspace(0.0, f, m)), ys, self._noise()) for f in band]
            lps = np.array([st[0] for st in stats])
            j = int(np.argmax(lps))
            logp[i] = logsumexp(lps) - np.log(len(band))  # the phase marginalized over the band
            d2[i], dof[i], phases[i] = stats[j][1], stats[j][2], band[j]
        new_ll = None
        if cfg.new_skill_weight > 0:
            # a skill never taught: the population of every demonstration (mean; spread per weight plus the
            # shared within-skill covariance), its path the support-weighted mean of the components', the phase
            # marginalized over its band as a component's
            sc = self.scale
            cov0 = metric[0] + np.diag(sc.total_m2[:h] / max(sc.n - 1, 1))
            support = self._support()
            length0 = float(np.sum(support * [c.cluster.path_length for c in self.items]) / support.sum())
            band = _band(length / max(length0, 1e-12))
            lps = [prefix_statistics(U @ sc.total_mean[:h], U @ cov0 @ U.T, cfg.basis_human.phi(np.linspace(0.0, f, m)),
                                     ys, self._noise())[0] for f in band]
            new_ll = logsumexp(lps) - np.log(len(band))
        return self._decide(logp, d2, dof, phases, has_robot, shared_cov, shares, records, new_ll)
