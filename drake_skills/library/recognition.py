"""Run-time queries of the skill library: recognition (Eq. 12), the robot's answer (Eq. 13), the phase.

:class:`RecognitionMixin` is the query half of
:class:`~drake_skills.library.incremental.SkillLibrary` (the learning half and the
state live there). It reads the library's state through the attributes and methods
``SkillLibrary`` defines: ``config``, ``_components``, ``_rule``, ``_scale``, ``_gain``,
``n_human``, ``has_robot``, ``dim_robot_``, ``_metric()``, ``_whitened_means()``,
``_shared_cov()``, ``_expert_cov()``, ``_cached()``, ``_model()``,
``_check_fitted()``, ``human_samples()``, ``_normalized()`` and ``_guard()``; it keeps
two caches of its own keyed on the current scale (the response whitener and the
eigendecompositions of prefix scoring), so a library that learns never answers from
a stale one.

Whole motions are tested on their weights against each component (as learning
does); a beginning is scored for all (component, phase) pairs at once
(:mod:`drake_skills.library.prefix`) and, above :data:`PRUNE_MIN_COMPONENTS`, only for
the components a cheap lower bound (:mod:`drake_skills.library.prefix_bound`) does not
rule out. The answers are those of scoring every component one by one
(``tests/library/test_scale.py`` checks them against that reference).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from drake_skills._checks import check_fraction, check_integer
from drake_skills.data.workspace import Workspace
from drake_skills.library.algorithm import (YOUNG_SUPPORT, ComponentModel, gating_scores, responsibilities,
                                           single_demo_rule, two_sample_d2)
from drake_skills.library.gain import scale_correction
from drake_skills.library.novelty import Chi2Rule, chi2_ppf
from drake_skills.library.prefix import (PHASE_GRID, _basis_at, band_of, loglik_one, phase_band, prefix_loglik,
                                         score_at_phase, score_component, score_prefix)
from drake_skills.library.prefix_bound import prefix_candidates
from drake_skills.library.scale import (BEGINNING_FRACTIONS, beginning_blind, cross_covariance, main_task,
                                        mixed_share, observation_noise)
from drake_skills.library.views import Recognition, StillMotionError, UnknownSkillError
from drake_skills.promp.basis import GaussianBasis, ridge_weights, trajectory_covariance, trajectory_variance
from drake_skills.promp.interaction import condition_blocks, conditioned_mean_shift
from drake_skills.promp.gaussian import inverse_lower, logsumexp
from drake_skills.promp.preprocessing import restart_vertex

__all__ = ["PRUNE_MIN_COMPONENTS", "RecognitionMixin"]

#: Above this many components, prefix recognition scores only the components a cheap
#: bound does not rule out (:func:`~drake_skills.library.prefix_bound.prefix_candidates`).
PRUNE_MIN_COMPONENTS = 16
#: A component that misses its own beginnings (``scale.beginning_blind``) is not ruled out by a
#: beginning whose prefix statistic is within this many of its thresholds (``d^2 / chi2_ppf``).
#: Chosen on development data: the beginnings the blind hand-wave components of the buetepage
#: training split had to block gave 0.1-11.6; beginnings at 30-70 % of 30 synthetic skills
#: against blind *other* skills 5-450 (median 120), so 16 keeps every block of the first and
#: drops most of the second. It is not a separation of skills: nearer skills' beginnings fall
#: within it (a cold review found half of the 10-20 % beginnings of 40 synthetic skills within 16
#: of a blind other skill, which is then "undecided", never wrong).
BLIND_REACH = 16.0
#: A beginning whose best skill's estimated phase is at least this has covered (nearly) all of that skill's path:
#: it is judged as a whole motion is, by the novelty test, and the hypothesis of a skill never taught
#: (``LibraryConfig.new_skill_weight``) plays no part. Without this a library of one or two skills never answered a
#: whole motion read with its phase estimated: the population of so few skills is little wider than each of them.
NEW_SKILL_PHASE = 0.9


class RecognitionMixin:
    """Recognition, prediction and phase estimation for :class:`~drake_skills.library.incremental.SkillLibrary`."""
    def recognize(self, human, *, observed_fraction: float | None = None, workspace: Workspace | None = None,
                  normalized: bool = False) -> Recognition:
        """Which skill is this human motion (Eq. 12): "skill", "undecided" or "unknown".

        Parameters
        ----------
        human : array, shape (T, D_h)
            The observed human positions (raw units if a workspace applies; see
            :meth:`human_samples` for ``normalized``): a whole motion or its beginning.
        observed_fraction : float in (0, 1], optional
            The fraction of the whole motion's path ``human`` covers, if known: 1 tests
            the motion's weights against each component (as learning does), less
            compares the observed samples with each component's prefix of that length.
            If omitted, the fraction is estimated per component: its path length
            against the component's mean path length, refined over a grid of phases (:mod:`~drake_skills.library.prefix`)
            by the likelihood of the samples (``Recognition.phases``); and the answer is
            "undecided" while a skill that would answer differently misses more than
            ``scale.BLIND_RATE`` (30 %) of its own demonstrations' beginnings at the share
            of its path this one covers (its record of beginnings; ``Recognition.blind``,
            :meth:`_decide`). While the shared scale is more prior than data, a component
            learned from one demonstration explains a motion only within
            ``LibraryConfig.single_demo_quantile`` (0.9), not ``novelty_quantile``; between the
            two it cannot be the answer but still takes its share of the posterior (it is not
            ruled out), so a rival is answered only if it is ``1 - decision_risk`` probable
            against it too. A skill near one taught as another task is not acted on
            (``Recognition.contested``); with a fraction given, only while the motion lies within
            ``other_task_reach`` of that neighbour's novelty limit, without one (a beginning) always.
            So pass 1 for a motion you know is complete, as the Drake gating does at rest.
        workspace : Workspace, optional
        normalized : bool
            ``human`` is already in the library's normalized units (Eq. 14 applied).

        Returns
        -------
        Recognition
            ``.status``, ``.component`` (None unless "skill"), ``.phase`` and the
            per-component statistics.

        Raises
        ------
        ValueError
            For bad input (NaN, one sample, wrong columns) and for a beginning that does
            not move yet (path length 0: a wrist still at rest; a live caller waits for
            the first movement, as the Drake gating does), or before anything was learned.
        """
        self._check_fitted()
        if observed_fraction is not None:
            observed_fraction = check_fraction(observed_fraction)
            y = self.human_samples(human, workspace=workspace, observed_fraction=observed_fraction,
                                   normalized=normalized)
            self._guard(y, workspace, normalized, whole=float(observed_fraction) == 1, query=True, where=None)
            rec = self._recognize_fixed(y, float(observed_fraction))
            if observed_fraction != 1:  # the caller's fraction is of the motion as given
                return rec
            return self._read_again(rec, self._normalized(human, workspace, normalized), self._recognize_whole)[0]
        path = self._normalized(human, workspace, normalized)
        self._guard(path.y, workspace, normalized, whole=False, query=True, where=None)
        return self._read_again(self._recognize_prefix(path), path, self._recognize_prefix)[0]

    def _recognize_whole(self, path: "_Path") -> Recognition:
        return self._recognize_fixed(path.resample(self.config.n_samples), 1.0)

    def _read_again(self, rec: Recognition, path: "_Path", read, given: int | None = None
                    ) -> tuple[Recognition, "_Path"]:
        """``rec`` and the path it read, or, for an unknown motion that set off more than once, the reading from
        its last start when that names a skill or is undecided (``LibraryConfig.skip_false_starts``). ``given``:
        the caller chose where to read from (``restart``), so ``rec`` stands."""
        if rec.status != "unknown" or not self.config.skip_false_starts or given is not None:
            return rec, path
        if self._sets_off_twice().any():   # a skill of its own may begin so: its motions are no false starts
            return rec, path
        try:
            again = self._restarted(path)
        except StillMotionError:  # what follows the last start does not move (e.g. its noise is all there is)
            return rec, path
        if again is None:
            return rec, path
        rec2 = read(again)
        if rec2.status == "unknown":
            return rec, path
        return replace(rec2, restart=again.offset), again

    def _sets_off_twice(self) -> np.ndarray:
        """Which components' mean human paths set off from their start more than once (K,) (``restart_vertex``).

        A library that learned such a skill (a beckon: out and back, then a reach) does not read unknown
        motions from a restart: one of them may be that skill, shown larger or slower, and its tail another
        skill. Once per library version, and then only for the components the last update made (a component is
        immutable: its answer is kept with it, as ``ComponentModel.sub_within`` keeps its scatter), so that a
        library of a thousand components pays for one or two paths, not 1000 (70 ms).
        """
        def compute():
            cfg = self.config
            Phi = cfg.basis_human.phi_uniform(cfg.n_samples)
            D, h = self.dim_human_, self.n_human
            key = (cfg.basis_human, int(cfg.n_samples), float(cfg.resample_tolerance))
            flags = []
            for c in self._components.items:
                hit = c.__dict__.get("_sets_off_twice")
                if hit is None or hit[0] != key:
                    hit = (key, restart_vertex(Phi @ c.mean[:h].reshape(D, -1).T, cfg.resample_tolerance) > 0)
                    object.__setattr__(c, "_sets_off_twice", hit)   # derived data; the dataclass stays frozen
                flags.append(hit[1])
            return np.array(flags, dtype=bool)
        return self._cached("sets_off_twice", compute)

    def _empty_recognition(self, dof) -> Recognition:
        z = np.zeros(0)
        return Recognition(None, (), z, z, z, dof, "unknown", z, z)

    def _decide(self, logp, d2, dof, phases, scored: np.ndarray | None = None,
                shares: np.ndarray | None = None, new_ll=None) -> Recognition:
        """The answer from per-component statistics; ``scored``: the components scored (the others cannot fit).

        ``shares`` (K,): for a beginning, the share of each component's path it covers. A
        beginning that one skill explains is still "undecided" while a component that would
        answer differently misses too many of its own demonstrations' beginnings at its share
        (its record of beginnings; :func:`~drake_skills.library.scale.beginning_blind`) and
        the beginning lies within :data:`BLIND_REACH` of its thresholds: its test cannot rule
        it out (``Recognition.blind`` names it). ``new_ll``: for a beginning, a callable giving its
        log-likelihood as a skill never taught (:meth:`_new_skill_loglik`), asked only when the answer
        would be a skill and the best one's phase is below :data:`NEW_SKILL_PHASE`; with ``new_skill_weight``
        beside the supports of the components kept, at ``decision_risk`` of the posterior or more the answer is
        "undecided" (``Recognition.new_skill``).
        """
        comps = self._components
        if scored is None:
            fits = ~self._rule.novel(logp, d2, dof)
        else:
            fits = np.zeros(len(comps), bool)
            fits[scored] = ~self._rule.novel(logp[scored], d2[scored], dof[scored])
        # a component seen once, on a scale still more prior than data or (its phase searched) from a
        # beginning, is the answer only well inside (``answers``); beyond that but within the novelty
        # test it cannot be ruled out, so it still takes its share of the posterior (``fits``)
        answers = fits.copy()
        q1 = single_demo_rule(self.config, self._scale, beginning=shares is not None)
        if q1 is not None:
            young = fits & (comps.support < YOUNG_SUPPORT)
            if young.any():
                k = np.flatnonzero(young)
                answers[k] = d2[k] <= chi2_ppf(q1, np.broadcast_to(dof, fits.shape)[k])
        resp = responsibilities(logp, comps.support)
        keep = fits if answers.any() else answers
        post = resp.copy() if keep.all() else responsibilities(logp, comps.support, keep)   # (the same, all kept)
        ids = comps.ids
        best = int(np.argmax(post))
        if not answers.any():
            status, comp = "unknown", None
        elif not answers[best]:
            status, comp = "undecided", None
        elif post[best] >= 1.0 - self.config.decision_risk or \
                post[self._same_response(best, post > 0)].sum() >= 1.0 - self.config.decision_risk:
            status, comp = "skill", ids[best]
        else:
            status, comp = "undecided", None
        contested = ()
        if status == "skill":
            contested = self._contested(best)
            if contested and shares is None and contested != (ids[best],):
                contested = self._within_reach(contested, d2, dof)
            if contested:
                status, comp = "undecided", None   # the teacher named these differently: not acted on
        blind = ()
        if status == "skill" and shares is not None and isinstance(self._rule, Chi2Rule):
            mask = beginning_blind(*comps.beginnings, shares)
            mask[best] = False
            if mask.any():
                k = np.flatnonzero(mask)
                ratio = d2[k] / chi2_ppf(self.config.novelty_quantile, np.broadcast_to(dof, mask.shape)[k])
                mask[k] = ratio <= BLIND_REACH
            if mask.any():
                mask &= ~self._same_response(best, mask)
            if mask.any():
                status, comp, blind = "undecided", None, tuple(ids[i] for i in np.flatnonzero(mask))
        new_skill = 0.0
        if new_ll is not None and status == "skill" and phases[best] < NEW_SKILL_PHASE:
            # a skill never taught, with weight new_skill_weight beside the supports of the components kept
            a = np.log(comps.support[keep]) + logp[keep]
            b = np.log(self.config.new_skill_weight) + new_ll()
            new_skill = float(np.exp(b - logsumexp(np.append(a, b))))
            if new_skill >= self.config.decision_risk:
                status, comp = "undecided", None
        seen_once = tuple(ids[i] for i in np.flatnonzero(fits & ~answers)) if answers.any() else ()
        return Recognition(comp, ids, resp, logp, d2, dof, status, phases, post, blind, seen_once,
                           contested=contested, new_skill=new_skill)

    def _contested(self, best: int) -> tuple[int, ...]:
        """Ids of the components that make acting on component row ``best`` unsafe by their task names: ``best``
        itself when it was taught as several tasks (``mixed_task_share``), or the components taught as another
        task whose means lie within ``other_task_reach`` times the merge limit of its (two-sample distance under
        the shared metric: fragments of one motion lie so close), once the shared scale is more data than prior
        (pooled dof ``nu >= prior_strength``; a chi-square library only: the reach is in its merge limits).
        Empty without task names. Kept per library version and row (it depends on nothing else)."""
        memo = self._cached("contested", dict)
        hit = memo.get(best)
        if hit is None:
            hit = memo[best] = self._contested_now(best)
        return hit

    def _within_reach(self, contested: tuple[int, ...], d2: np.ndarray, dof) -> tuple[int, ...]:
        """Of the skills taught as other tasks near the best one (``contested``, ids), those a whole motion (or a
        given fraction) may still be: its distance to them at most ``other_task_reach`` times their novelty limit.

        The reach the components' means are judged on (merge limits apart), applied to the motion itself: beyond
        twice a skill's limit the motion is not that skill's, and the neighbour does not hold the answer. There
        every component is scored (``d2`` of all rows); a beginning, whose candidates may be pruned, keeps every
        contest (:meth:`_decide`). A deviation from the paper, as the reach is.
        """
        cfg = self.config
        rows = np.array([self._components.index(c) for c in contested], int)
        limit = cfg.other_task_reach * chi2_ppf(cfg.novelty_quantile, np.broadcast_to(dof, d2.shape)[rows])
        return tuple(c for c, near in zip(contested, d2[rows] <= limit) if near)

    def _contested_now(self, best: int) -> tuple[int, ...]:
        cfg = self.config
        comps = self._components
        tasks = comps.items[best].cluster.tasks
        if mixed_share(tasks) >= cfg.mixed_task_share:
            return (comps.ids[best],)
        task = main_task(tasks)
        if (task is None or not cfg.other_task_reach > 0 or len(comps) < 2 or not isinstance(self._rule, Chi2Rule)
                or self._scale.dof < cfg.prior_strength):
            return ()  # (while the scale is more prior than data every pair lies near: skills seen once, the rule
            #           of single_demo_quantile, keep a young library safe)
        d2 = two_sample_d2(self._whitened_means(), comps.support, best)
        near = np.flatnonzero(d2 <= cfg.other_task_reach * chi2_ppf(cfg.merge_quantile, self.n_human))
        return tuple(comps.ids[i] for i in near if main_task(comps.items[i].cluster.tasks) not in (None, task))

    def _same_response(self, best: int, candidates: np.ndarray) -> np.ndarray:
        """Which candidates answer like component ``best`` (a mask, ``best`` included).

        Executing ``best`` is only wrong if the motion belongs to a component that
        would answer differently: another component whose mean response (its robot
        weights; the human weights of a human-only library) lies within the best's
        predictive within-skill spread (the ``novelty_quantile`` of the distance under
        ``Sigma_rr (1 + 1/s_best)``) answers the same way, so its probability counts
        for ``best`` in the decision; unless its demonstrations were taught under another
        task name than ``best``'s (``Cluster.tasks``): the teacher said they differ.
        """
        comps = self._components
        h = self.n_human
        idx = np.flatnonzero(candidates)
        out = np.zeros(len(comps), bool)
        out[best] = True
        others = idx[idx != best]
        cfg = self.config
        task = main_task(comps.items[best].cluster.tasks)
        if task is not None and (cfg.mixed_task_share < 1 or cfg.other_task_reach > 0 or cfg.keep_tasks_apart
                                 or cfg.same_task_reach != 1):
            # a component taught as another task does not answer like it, whatever its response (the names in
            # use; a library with every task setting off, as a file written before task names loads, answers as
            # it did)
            others = np.array([j for j in others if main_task(comps.items[j].cluster.tasks) in (None, task)], int)
        if not others.size:
            return out
        block = slice(h, None) if self.has_robot else slice(0, h)
        Linv = self._response_whitener()
        mb = comps.items[best].mean[block]
        diff = np.stack([comps.items[j].mean[block] - mb for j in others]) @ Linv.T
        d2 = np.einsum("ij,ij->i", diff, diff) / (1.0 + 1.0 / comps.support[best])
        out[others] = d2 <= chi2_ppf(self.config.novelty_quantile, Linv.shape[0])
        return out

    def _response_whitener(self) -> np.ndarray:
        """Inverse Cholesky factor of the shared covariance of the responses (robot weights; human for letters)."""
        if getattr(self, "_response_cache", (None,))[0] is not self._scale:
            h = self.n_human
            block = slice(h, None) if self.has_robot else slice(0, h)
            L = np.linalg.cholesky(self._shared_cov()[block, block])
            self._response_cache = (self._scale, inverse_lower(L))
        return self._response_cache[1]

    def _recognize_fixed(self, y, observed_fraction: float) -> Recognition:
        """Eq. (12) on preprocessed human samples ``y`` evenly spaced in phase over ``[0, observed_fraction]``."""
        cfg = self.config
        comps = self._components
        h = self.n_human
        if not len(comps):
            return self._empty_recognition(h)
        if observed_fraction == 1:
            w_h = ridge_weights(y, cfg.basis_human, cfg.ridge)
            logp, d2 = gating_scores(w_h, comps, self._metric(), self._whitened_means())
            return self._decide(logp, d2, h, np.ones(len(comps)))
        pm = self._prefix_model()
        logp, d2, dof = score_at_phase(y, observed_fraction, pm.means_h, 1.0 + 1.0 / comps.support, pm.chol,
                                       cfg.basis_human, self._noise(), self._prefix_cache())
        return self._decide(logp, d2, dof, np.full(len(comps), observed_fraction))

    def _recognize_prefix(self, path: "_Path") -> Recognition:
        """Recognition with the phase estimated per component (see :meth:`recognize`)."""
        cfg = self.config
        comps = self._components
        h = self.n_human
        if not len(comps):
            return self._empty_recognition(h)
        pm = self._prefix_model()
        guess = path.length / np.maximum(comps.path_length, 1e-12)
        ys = path.resample(_prefix_samples(cfg.n_samples, _median(np.minimum(guess, 1.0))))
        inflate = 1.0 + 1.0 / comps.support
        noise = self._noise()
        idx = None
        band = phase_band(guess)
        if len(comps) > PRUNE_MIN_COMPONENTS and isinstance(self._rule, Chi2Rule):
            keep = prefix_candidates(ys, PHASE_GRID, band, pm.means_h, inflate, pm.chol, cfg.basis_human, noise,
                                     cfg.novelty_quantile, self._prefix_cache())
            keep |= beginning_blind(*comps.beginnings, guess)  # they may not be ruled out (see _decide)
            idx = np.flatnonzero(keep)
        if idx is None or idx.size == len(comps):
            sc = score_prefix(ys, guess, pm.means_h, inflate, pm.chol, cfg.basis_human, noise,
                              self._prefix_cache(), band)
            logp, d2, dof, phases, sub = sc.log_likelihoods, sc.mahalanobis_sq, sc.dof, sc.phases, None
        else:
            # the components ruled out cannot explain the samples: log-likelihood -inf, distance inf
            K = len(comps)
            logp, d2 = np.full(K, -np.inf), np.full(K, np.inf)
            dof, phases = np.full(K, float(self.n_human)), np.clip(guess, 1.0 / cfg.n_samples, 1.0)
            sub = idx
            if idx.size:
                sc = score_prefix(ys, guess[idx], pm.means_h[idx], inflate[idx], pm.chol, cfg.basis_human, noise,
                                  self._prefix_cache(), band[idx])
                logp[idx], d2[idx], dof[idx], phases[idx] = sc.log_likelihoods, sc.mahalanobis_sq, sc.dof, sc.phases
        new_ll = None
        if cfg.new_skill_weight > 0:   # a skill never taught: scored only when the answer would be a skill
            def new_ll():
                return self._new_skill_loglik(ys, path.length, noise)
        return self._decide(logp, d2, dof, phases, scored=sub, shares=guess, new_ll=new_ll)

    def _new_skill_loglik(self, ys: np.ndarray, length: float, noise: float) -> float:
        """log p(beginning | a skill never taught), its phase searched as a component's (``new_skill_weight``).

        The model is the population of every demonstration seen: their mean human weights, and as covariance the
        shared within-skill covariance ``Sigma`` plus the per-weight variance of all demonstrations (between and
        within skills), unshrunk as the components' are (``_prefix_model``); its path length the support-weighted
        mean of the components'. Kept per library version, with its own factors per phase (``prefix.loglik_one``).
        """
        def compute():
            h = self.n_human
            sc = self._scale
            spread = np.asarray(sc.total_m2[:h], float) / max(sc.n - 1, 1)
            U = self._unshrink_human()
            comps = self._components
            length0 = float(np.average(comps.path_length, weights=comps.support))
            mean = U @ np.asarray(sc.total_mean[:h], float)
            mean.setflags(write=False)
            chol = U @ np.linalg.cholesky(self._gating_cov() + np.diag(spread))
            return _NewSkill(mean, chol, max(length0, 1e-12), {})
        new = self._cached("new_skill", compute)
        ll = loglik_one(ys, band_of(length / new.length), new.mean, new.chol, self.config.basis_human, noise,
                        new.cache)
        # the phase is not known: the evidence is the likelihood averaged over the band (as score_prefix's)
        return float(logsumexp(ll) - np.log(ll.size))

    def predict_robot(self, human, observed_fraction: float | None = None, *, workspace: Workspace | None = None,
                      component: int | None = None, n_steps: int | None = None, normalized: bool = False,
                      restart: int | None = None, variances_only: bool = False):
        """Robot trajectory for an observed human motion (Eqs. 12-13).

        Recognizes the skill (unless ``component`` is given), conditions its
        Interaction ProMP on the observed human samples and returns the robot
        trajectory distribution over the component's phase (normalized time). With
        ``config.conditioning_gain`` (the default) Eq. (13)'s correction is scaled by
        the library's learned gains (:mod:`~drake_skills.library.gain`): the mean and
        covariance are those of the scaled predictor.
        Without ``observed_fraction`` the fraction observed is estimated as in
        :meth:`recognize`. ``normalized=True``: ``human`` is already in the library's
        normalized units (see :meth:`human_samples`). A motion recognized here is read as
        :meth:`recognize` reads it (from a restart after a false start, when that is what
        names the skill). ``restart``: read it from that sample on instead (the
        ``Recognition.restart`` of an earlier answer: pass it with ``component``); 0: the
        whole motion; None (default): as :meth:`recognize` reads it when it recognizes the
        motion here, the whole motion when ``component`` is given. ``variances_only``: each
        joint's per-step variance instead of the per-step covariance (what a controller that
        bounds or shows each joint's spread needs; about a fourth of the per-step covariance's
        cost for 7 joints).

        Returns
        -------
        mean : array, shape (n_steps, D_r)
            Joint positions; play them over ``component(k).duration`` seconds.
        cov : array, shape (n_steps, D_r, D_r)
            Per-step covariance; with ``variances_only``, its diagonals, shape (n_steps, D_r).

        Raises
        ------
        UnknownSkillError
            If the motion matches no component, or more than one and none clearly.
        ValueError
            For bad input, or a library without robot trajectories.
        KeyError
            If ``component`` is not a component id (e.g. it was deleted).
        """
        self._check_fitted()
        if not self.has_robot:
            raise ValueError("this library was learned from human-only demonstrations: it has no robot part")
        cfg = self.config
        if observed_fraction is None:
            path = self._normalized(human, workspace, normalized)
            self._guard(path.y, workspace, normalized, whole=False, query=True, where=None)
            path = self._restarted_at(path, restart)
            if component is None:
                rec, path = self._read_again(self._recognize_prefix(path), path, self._recognize_prefix, restart)
                if rec.component is None:
                    raise UnknownSkillError(_unknown_message(rec))
                component, f = rec.component, rec.phase
            else:
                f = self._phase_of(path, self._model(component))
            y = path.resample(max(2, int(round(cfg.n_samples * f))))
        else:
            f = check_fraction(observed_fraction)
            y = self.human_samples(human, workspace=workspace, observed_fraction=f, normalized=normalized)
            self._guard(y, workspace, normalized, whole=f == 1, query=True, where=None)
            if restart or (component is None and f == 1):
                path = self._restarted_at(self._normalized(human, workspace, normalized), restart)
                y = path.resample(y.shape[0])
            if component is None:
                rec = self._recognize_fixed(y, f)
                if f == 1:
                    rec, path = self._read_again(rec, path, self._recognize_whole, restart)
                    y = path.resample(y.shape[0])
                if rec.component is None:
                    raise UnknownSkillError(_unknown_message(rec))
                component = rec.component
        prior_w, prior_cov, mean_w, cov_w = self._condition(self._model(component), y, f)
        if cfg.conditioning_gain:  # Eq. (13)'s correction scaled by the learned gains (library.gain)
            gains = np.tile(self._gain.gains(), self.dim_robot_)
            mean_w, cov_w = scale_correction(prior_w, prior_cov, mean_w, cov_w, gains)
        n = cfg.n_samples if n_steps is None else check_integer(n_steps, "n_steps", 2)
        mean_r = cfg.basis_robot.phi_uniform(n) @ mean_w.reshape(self.dim_robot_, -1).T
        spread = trajectory_variance if variances_only else trajectory_covariance
        return mean_r, spread(cov_w, cfg.basis_robot, self.dim_robot_, n_steps=n)

    def _condition(self, c: ComponentModel, y: np.ndarray, f: float):
        """Eq. (13) for component ``c`` on samples ``y`` evenly spaced over phases [0, f], in robot weights.

        Returns the robot block before conditioning (mean, covariance) and after (mean,
        covariance). The human block is in the least-squares weights the samples are
        compared with (see :meth:`_prefix_model`).
        """
        h = self.n_human
        Phi_o = _basis_at(self.config.basis_human, float(f), int(y.shape[0]))[0]   # cached with prefix scoring's
        E = self._expert_cov(c)
        mean_h, cov_hh, cov_rh = self._seen_blocks(c)   # its human rows and columns seen through U (S^-1)
        mean_w, cov_w = condition_blocks(mean_h, c.mean[h:], cov_hh, cov_rh, E[h:, h:], Phi_o, y, self._noise())
        return c.mean[h:], E[h:, h:], mean_w, cov_w

    def _correction(self, c: ComponentModel, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Eq. (13)'s shift of component ``c``'s robot weights for a whole motion's samples ``y``, and their prior mean.

        What :meth:`_condition` gives for ``f = 1`` (``mean_w - prior_w``), from the two
        blocks of the expert covariance it needs (``partial_fit`` fits the gains with it,
        and every update would otherwise build the whole stacked covariance).
        """
        cfg = self.config
        h = self.n_human
        U = self._unshrink_human()
        F, denom = c.cluster.factor, cfg.expert_prior + c.support - 1.0
        cross = cross_covariance(self._scale, h, prior_strength=cfg.prior_strength, shrinkage=cfg.shrinkage)
        Sigma_hh = self._metric().cov   # gating_covariance of the current scale, cached per library version
        E_hh = (cfg.expert_prior * Sigma_hh + F[:h] @ F[:h].T) / denom
        E_rh = (cfg.expert_prior * cross + F[h:] @ F[:h].T) / denom
        Phi_o = cfg.basis_human.phi_uniform(y.shape[0])
        shift = conditioned_mean_shift(U @ c.mean[:h], U @ E_hh @ U.T, E_rh @ U.T, Phi_o, y, self._noise())
        return c.mean[h:], shift

    def _unshrink_human(self) -> np.ndarray:
        """``S^-1`` of every human dimension, block diagonal (h, h): the ridge undone (see :meth:`_prefix_model`)."""
        cfg = self.config
        return _unshrink_block(cfg.basis_human, int(cfg.n_samples), float(cfg.ridge), int(self.dim_human_))

    def _prefix_model(self) -> "_PrefixModel":
        """The components' human means and the gating covariance as the samples of a motion see them.

        The library's weights are ridge estimates (Eq. 3): over the ``n_samples`` phases a
        whole motion is resampled to, ``w = S w_ls`` with ``S = (Phi^T Phi + beta I)^-1
        Phi^T Phi`` and ``w_ls`` the least-squares weights, so the samples' expected
        in-span part is ``Phi w_ls = Phi S^-1 w``, not ``Phi w``. Comparing samples with
        ``Phi mu_k`` counts the ridge's shrinkage as misfit: with the defaults a whole
        taught motion recognized as a beginning got d^2 53 against a threshold of 47, and
        0.3 with the shrinkage undone. Prefix recognition, phase estimation and
        conditioning (Eq. 13) therefore use ``S^-1 mu_k`` and ``S^-1 Sigma S^-T`` (per
        dimension; ``pinv(S)`` where ``S`` is singular). The gating of whole motions
        compares weights with weights and needs no such step.
        """
        def compute():
            U = self._unshrink_human()
            return _PrefixModel(self._components.means_h @ U.T, U @ self._metric().chol, U)
        return self._cached("prefix_model", compute)

    def observation_noise(self) -> float:
        """The variance of an observed human sample prefix recognition and conditioning use (normalized units^2).

        ``config.observation_noise`` or, if larger, the mean residual of the demonstrations'
        paths around their basis fits (:func:`~drake_skills.library.scale.observation_noise`).
        """
        self._check_fitted()
        return self._noise()

    def _noise(self) -> float:
        return observation_noise(self._scale, self.config.observation_noise)

    def _prefix_cache(self) -> dict:
        """Eigendecompositions of prefix recognition for the current scale (emptied when the library learns)."""
        if getattr(self, "_prefix", (None,))[0] is not self._scale:
            self._prefix = (self._scale, {})
        return self._prefix[1]

    def estimate_phase(self, human, component: int, *, workspace: Workspace | None = None,
                       normalized: bool = False, restart: int | None = None) -> float:
        """How much of component ``component``'s motion ``human`` covers (0-1), as :meth:`recognize` estimates it
        (``restart``: from that sample on, as in :meth:`predict_robot`)."""
        self._check_fitted()
        path = self._restarted_at(self._normalized(human, workspace, normalized), restart)
        return self._phase_of(path, self._model(component))

    def _restarted_at(self, path: "_Path", restart: int | None) -> "_Path":
        """``path`` read from its sample ``restart`` on (None or 0: whole; see :meth:`predict_robot`)."""
        if restart is None:
            return path
        at = check_integer(restart, "restart", 0, path.y.shape[0] - 2)
        try:
            return self._restarted(path, at) or path
        except StillMotionError as exc:
            raise StillMotionError(f"restart {at}: the motion from there on does not move ({exc})") from None

    def _phase_of(self, path: "_Path", c: ComponentModel) -> float:
        """The phase of one component that explains the normalized path ``y`` best (see :mod:`.prefix`)."""
        cfg = self.config
        guess = path.length / max(c.cluster.path_length, 1e-12)
        ys = path.resample(_prefix_samples(cfg.n_samples, min(1.0, guess)))
        pm = self._prefix_model()
        # score_prefix's phase of one component, the likeliest of its band; its fit statistic is not needed here
        phases = band_of(guess)
        ll = prefix_loglik(ys, phases, pm.means_h[[self._components.index(c.id)]], np.array([1.0 + 1.0 / c.support]),
                           pm.chol, cfg.basis_human, self._noise(), self._prefix_cache())
        return float(phases[int(np.argmax(ll[:, 0]))])

    def _beginnings_missed(self, path: "_Path", k: int) -> np.ndarray:
        """Whether component row ``k`` rejects the beginnings of ``path`` (B,): 1 or 0, NaN where too short to test.

        The beginning at each of :data:`~drake_skills.library.scale.BEGINNING_FRACTIONS` of the
        path (its vertices cut at that arc length) is tested as :meth:`recognize` tests a
        beginning without a fraction: the most likely phase of the band around the component's
        path-length guess, the prefix test of the novelty rule there (the phase matters: a hand
        wave's beginning fits its component at some phase of the band, but not at the one its
        likelihood picks, and that is what recognition sees). Where recognition resamples a
        beginning to ``fraction n_samples`` points, all are resampled to the count of the last
        (20 of 100) and scored at the union of their bands (:func:`score_component`: one
        component, a Cholesky factorization per phase, not the eigendecompositions that serve
        all K; the other components' prefix means are not computed).
        ``partial_fit`` asks this of the component a demonstration joins, before it does (its
        record of beginnings).
        """
        cfg = self.config
        comps = self._components
        U = self._unshrink_human()                # as _prefix_model, for row k alone
        mean_h, chol = U @ comps.means_h[k], U @ self._metric().chol
        inflate = 1.0 + 1.0 / comps.support[k]
        F = BEGINNING_FRACTIONS
        m = _prefix_samples(cfg.n_samples, F[-1])
        subs = [path.cut(f * path.length) for f in F]
        done = [b for b, sub in enumerate(subs) if sub is not None]
        out = np.full(len(F), np.nan)
        if not done:
            return out
        guess = np.array([subs[b].length for b in done]) / max(float(comps.path_length[k]), 1e-12)
        bands = phase_band(guess)
        ys = [subs[b].resample(m) for b in done]
        noise = self._noise()
        cols = np.flatnonzero(bands.any(axis=0))
        phases = tuple(np.array(PHASE_GRID)[cols])   # every phase of the bands
        ll, d2, dof = score_component(np.stack(ys), phases, mean_h, inflate, chol, cfg.basis_human, noise)
        rows = np.arange(len(done))
        j = np.argmax(np.where(bands[:, cols], ll, -np.inf), axis=1)   # score_prefix's phase of each band
        novel = self._rule.novel(ll[rows, j], d2[rows, j], dof[rows, j])
        ok = np.isfinite(d2[rows, j])              # a statistic that is not a number tests nothing
        out[np.array(done)[ok]] = novel[ok].astype(float)
        return out


@lru_cache(maxsize=16)
def _unshrink(basis: GaussianBasis, n_samples: int, ridge: float) -> np.ndarray:
    """``S^-1`` (N, N) of :meth:`RecognitionMixin._prefix_model`: a function of the settings alone (cached, read-only)."""
    Phi = basis.phi_uniform(n_samples)
    G = Phi.T @ Phi
    S = np.linalg.pinv(G + ridge * np.eye(G.shape[0]), hermitian=True) @ G   # ridge 0: G may be singular
    Sinv = np.linalg.pinv(S)
    Sinv.setflags(write=False)
    return Sinv


@lru_cache(maxsize=16)
def _unshrink_block(basis: GaussianBasis, n_samples: int, ridge: float, dim: int) -> np.ndarray:
    """``I_dim (x) S^-1`` (dim N, dim N), block diagonal: :func:`_unshrink` for every dimension (cached, read-only)."""
    U = np.kron(np.eye(dim), _unshrink(basis, n_samples, ridge))
    U.setflags(write=False)
    return U


@dataclass(frozen=True, eq=False)
class _NewSkill:
    """:meth:`RecognitionMixin._new_skill_loglik`'s model: mean (h,), covariance factor (h, h), path length, and
    its factors per phase (``prefix.loglik_one``'s cache)."""

    mean: np.ndarray
    chol: np.ndarray
    length: float
    cache: dict


@dataclass(frozen=True, eq=False)
class _PrefixModel:
    """:meth:`RecognitionMixin._prefix_model`: means (K, h), the covariance's factor (h, h) and ``S^-1`` (h, h)."""

    means_h: np.ndarray
    chol: np.ndarray
    unshrink: np.ndarray


def _median(x: np.ndarray) -> float:
    """``np.median`` of a 1-D array without NaN (the same value; a tenth of its cost on a few elements)."""
    s = np.sort(x)
    n = s.shape[0]
    return float((s[(n - 1) // 2] + s[n // 2]) / 2.0)


def _prefix_samples(n_samples: int, fraction: float) -> int:
    """Samples a prefix covering ``fraction`` of a path is resampled to: ``fraction n_samples``, rounded up to a
    multiple of 5 (so that prefix recognition meets the same few sizes again and reuses their cached terms)."""
    return int(min(n_samples, max(5, 5 * np.ceil(fraction * n_samples / 5.0))))


@dataclass(frozen=True, eq=False)
class _Path:
    """A motion normalized (Eq. 14) with its path: the vertices counted as moves and their arc length.

    Computed once per query, so that recognizing, estimating the phase and
    resampling the same motion walk its samples once.
    """

    y: np.ndarray
    vertices: np.ndarray
    s: np.ndarray
    #: The sample of ``y`` each vertex starts at (None for a cut path).
    indices: np.ndarray | None = None
    #: The sample of the caller's motion ``y`` begins at (a reading from a restart).
    offset: int = 0

    @property
    def length(self) -> float:
        return float(self.s[-1])

    def cut(self, length: float) -> "_Path | None":
        """The path's first ``length`` of arc length (its last vertex interpolated); None if that holds one vertex."""
        s, v = self.s, self.vertices
        i = min(int(np.searchsorted(s, length, side="left")), s.shape[0] - 1)
        if i < 1 or not length > 0:
            return None
        t = (length - s[i - 1]) / (s[i] - s[i - 1]) if s[i] > s[i - 1] else 1.0
        vertices = np.vstack([v[:i], v[i - 1] + min(t, 1.0) * (v[i] - v[i - 1])])
        return _Path(vertices, vertices, np.append(s[:i], min(length, s[i])))

    def resample(self, n: int) -> np.ndarray:
        """``n`` samples equally spaced along the path (:func:`~drake_skills.promp.preprocessing.resample_by_arc_length`)."""
        grid = np.linspace(0.0, self.s[-1], int(n))
        return np.stack([np.interp(grid, self.s, self.vertices[:, d]) for d in range(self.vertices.shape[1])], axis=1)


def undecided_reason(rec: Recognition) -> str:
    """Why a recognition is "undecided", in a few words ("" for any other status).

    "seen once: k": the most probable component ``k`` was learned from one demonstration and the
    motion lies beyond its stricter limit (``Recognition.seen_once``); "blind: j, ...": the beginning
    fits, but those components miss their own beginnings there (``Recognition.blind``); "taught as
    several tasks: k" and "k lies near skills taught as other tasks: j, ..." (``Recognition.contested``,
    ``LibraryConfig.mixed_task_share`` and ``other_task_reach``); "may begin a skill never taught (p x); most
    probable k": a beginning one skill explains that may be of a skill not taught (``Recognition.new_skill``,
    ``LibraryConfig.new_skill_weight``); "between a and b": the two most
    probable components, neither ``1 - decision_risk`` probable.
    """
    if rec.status != "undecided":
        return ""
    if rec.contested:
        if rec.contested == (rec.best,):
            return f"taught as several tasks: {rec.best}"
        return f"{rec.best} lies near skills taught as other tasks: " + ", ".join(map(str, rec.contested))
    if rec.best in rec.seen_once:
        return f"seen once: {rec.best}"
    if rec.blind:
        return "blind: " + ", ".join(map(str, rec.blind))
    if rec.new_skill > 0:   # computed only when the answer would have been a skill: it held the answer
        return f"may begin a skill never taught (p {rec.new_skill:.2g}); most probable {rec.best}"
    top = np.argsort(rec.posterior)[::-1][:2]
    return "between " + " and ".join(str(rec.ids[i]) for i in top)


def _unknown_message(rec: Recognition) -> str:
    if rec.status == "undecided" and rec.contested == (rec.best,):
        return (f"the motion is skill {rec.best}, but that skill was taught under more than one task name "
                "(LibraryConfig.mixed_task_share): the library does not act on it; teach the tasks with motions "
                "that differ, or check the names")
    if rec.status == "undecided" and rec.contested:
        return (f"the motion is skill {rec.best}, but skill(s) {', '.join(map(str, rec.contested))}, taught as "
                "other tasks, lie about as near (LibraryConfig.other_task_reach): the human motion does not tell "
                "these tasks apart; the library does not act on it")
    if rec.status == "undecided" and rec.blind:
        return (f"the motion's beginning fits skill {rec.best}, but skill(s) {', '.join(map(str, rec.blind))} cannot "
                "be ruled out yet (they do not recognize their own beginnings this early): observe more")
    if rec.status == "undecided" and rec.best in rec.seen_once:
        p = rec.posterior[rec.ids.index(rec.best)]
        return (f"the motion is closest to skill {rec.best} ({p:.2f}), learned from one demonstration, but lies "
                "beyond the stricter limit for a skill seen once (single_demo_quantile): observe more, or "
                "demonstrate that skill again")
    if rec.status == "undecided" and rec.new_skill > 0:
        return (f"the motion's beginning fits skill {rec.best}, but may as well begin a skill never taught "
                f"(p {rec.new_skill:.2g}; LibraryConfig.new_skill_weight): observe more")
    if rec.status == "undecided":
        top = np.argsort(rec.posterior)[::-1][:2]
        cands = ", ".join(f"{rec.ids[i]} ({rec.posterior[i]:.2f})" for i in top)
        return f"the motion fits more than one skill and none clearly ({cands}): observe more, or ask"
    return "the motion matches no skill in the library: ask for a demonstration"
