"""The novelty, "unknown" and merge tests of the library: the one place where chi2 or loglik is chosen.

The paper thresholds ``p(w|k)`` (Algorithm 1) in one place and the
responsibility in another. We implement the likelihood test for both novelty
(a new component) and "unknown" (recognition): a motion is novel for component
``k`` when ``k`` does not explain it, and novel when no component does. The merge
test of Eq. (10) is the same test applied to another component's mean, with a
threshold that tightens as the component's support grows.

Two forms, chosen by ``LibraryConfig.novelty_test`` in :func:`novelty_rule`:

* :class:`Chi2Rule` (default, scale free): novel when the squared Mahalanobis
  distance exceeds the ``novelty_quantile`` of a chi-square with as many degrees of
  freedom as gating weights; merge ``j`` into ``i`` when ``d^2(mu_j | i)`` is below
  ``chi2.ppf(merge_quantile, dof) / s_i^beta``.
* :class:`LogLikRule`, the paper's literal test: novel when ``log p(w|k) < log T_nov``;
  merge when ``log p(mu_j | i) > log T_merge + beta log s_i``. Its settings depend on
  the dimension.

A rule is a small frozen object with two methods, so a different test (e.g. a
learned shared covariance) replaces it without touching the learning loop.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Protocol

import numpy as np
from scipy.stats import chi2

from drake_skills.library.config import LibraryConfig
from drake_skills.promp.gaussian import log_density_from_mahalanobis


class NoveltyRule(Protocol):
    """What the learning loop and recognition ask of a test."""

    def novel(self, log_likelihoods: np.ndarray, mahalanobis_sq: np.ndarray, dof: int) -> np.ndarray:
        """Per component, shape (K,): does it fail to explain the motion?"""

    def merge_scores(self, mahalanobis_sq: np.ndarray, support: float, chol: np.ndarray) -> np.ndarray:
        """Scores (n,) of merging candidates into one component; below 1 merges, lowest first.

        ``mahalanobis_sq`` (n,) are the candidates' gating means' squared distances to the
        component, ``support`` its s_i and ``chol`` (h, h) the Cholesky factor of its
        floored gating covariance.
        """


@lru_cache(maxsize=256)
def chi2_ppf(q: float, dof: int) -> float:
    """``scipy.stats.chi2.ppf(q, dof)``, cached (the same few quantiles are asked for all the time)."""
    return float(chi2.ppf(q, dof))


@dataclass(frozen=True)
class Chi2Rule:
    """Scale-free tests on the squared Mahalanobis distance (chi-square quantiles)."""

    novelty_quantile: float
    merge_quantile: float
    consolidation: float

    def novel(self, log_likelihoods, mahalanobis_sq, dof) -> np.ndarray:
        return mahalanobis_sq > chi2_ppf(self.novelty_quantile, int(dof))

    def merge_scores(self, mahalanobis_sq, support, chol) -> np.ndarray:
        threshold = chi2_ppf(self.merge_quantile, chol.shape[0]) / support ** self.consolidation
        return mahalanobis_sq / threshold


@dataclass(frozen=True)
class LogLikRule:
    """The paper's tests on ``log p(w | k)`` (Algorithm 1, Eq. 10)."""

    log_T_nov: float
    log_T_merge: float
    consolidation: float

    def novel(self, log_likelihoods, mahalanobis_sq, dof) -> np.ndarray:
        return log_likelihoods < self.log_T_nov

    def merge_scores(self, mahalanobis_sq, support, chol) -> np.ndarray:
        threshold = self.log_T_merge + self.consolidation * np.log(support)
        logp = log_density_from_mahalanobis(mahalanobis_sq, chol)
        return np.exp(np.clip(threshold - logp, -50, 50))


def novelty_rule(config: LibraryConfig) -> NoveltyRule:
    """The test ``config.novelty_test`` names, with its settings."""
    if config.novelty_test == "chi2":
        return Chi2Rule(config.novelty_quantile, config.merge_quantile, config.consolidation)
    if config.novelty_test == "loglik":
        return LogLikRule(config.log_T_nov, config.log_T_merge, config.consolidation)
    raise ValueError(f"unknown novelty_test {config.novelty_test!r}")
