"""The novelty, "unknown", merge and split tests: the one place where chi2 or loglik is chosen.

All tests look at squared Mahalanobis distances under the shared gating covariance
``Sigma`` (:mod:`drake_skills.library.scale`):

* novelty / "unknown" (Eq. 9, Algorithm 1, Sec. 3.3): the distance of a motion's
  weights to component k under its predictive covariance ``Sigma (1 + 1/s_k)``. The
  paper thresholds ``p(w|k)`` in one place and the responsibility in another; we use
  the likelihood test for both learning and recognition: a motion is novel when no
  component explains it.
* merge (Eq. 10): the two-sample distance of two components' means,
  ``|mu_i - mu_j|^2_Sigma / (1/s_i + 1/s_j)``, i.e. the likelihood of their mean
  difference under ``N(0, Sigma (1/s_i + 1/s_j))``. It already consolidates: the
  larger the supports, the closer two means must be to merge. The paper's explicit
  ``T_merge s^beta`` is kept as ``consolidation`` (0 by default).
* split: a component whose two sub-clusters lie further apart than the
  ``split_quantile`` of the same statistic is split in two again (hysteresis:
  ``split_quantile`` > ``merge_quantile``, so a merge is not undone by the next step).

Two forms, chosen by ``LibraryConfig.novelty_test`` in :func:`novelty_rule`:

* :class:`Chi2Rule` (default, scale free): thresholds are chi-square quantiles with as
  many degrees of freedom as gating weights (a whole motion), or as the directions a
  beginning's samples see well (recognition from a prefix; ``promp.interaction.prefix_statistics``).
* :class:`LogLikRule`, the paper's literal test on ``log p`` (``log_T_nov``,
  ``log_T_merge``); its settings depend on the dimension. Splits use the chi-square
  quantile in both forms.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Protocol

import numpy as np
from scipy.stats import chi2

_LOG_2PI = np.log(2.0 * np.pi)


class NoveltyRule(Protocol):
    """What the learning loop and recognition ask of a test."""

    def novel(self, log_likelihoods: np.ndarray, mahalanobis_sq: np.ndarray, dof: int) -> np.ndarray:
        """Per component, shape (K,): does it fail to explain the motion?"""

    def merge_scores(self, mahalanobis_sq: np.ndarray, support: np.ndarray, inflate: np.ndarray, logdet: float,
                     dof: int) -> np.ndarray:
        """Scores (K,) of merging pairs; below 0 merges, lowest first (kept in the log domain for the
        log-likelihood form, so pairs far inside the threshold are still ordered).

        ``mahalanobis_sq`` are two-sample distances, ``support`` the larger support of
        each pair, ``inflate`` ``1/s_i + 1/s_j`` and ``logdet`` that of ``Sigma``.
        """

    def merge_limit(self, support: np.ndarray, logdet: float, dof: int) -> float:
        """A two-sample distance at or beyond which no pair of components with these supports (K,) merges
        under a covariance of log-determinant ``logdet``: pairs whose distance is known to lie beyond it are
        not scored."""

    def splits(self, mahalanobis_sq: np.ndarray, dof: int) -> np.ndarray:
        """Per component: do its two sub-clusters this far apart (two-sample distance) make two components?"""


#: Integer dof spanning fewer values than this are looked up in a table over their range (every
#: prefix test: 3-60); wider spans are computed per distinct value. Below the quantile cache's size,
#: so that one call cannot flush it.
_TABLE_SPAN = 64


@lru_cache(maxsize=256)
def _chi2_ppf(q: float, dof: int) -> float:
    return float(chi2.ppf(q, dof))


def chi2_ppf(q: float, dof):
    """``scipy.stats.chi2.ppf(q, dof)``: cached for integer degrees of freedom, a scalar or an array.

    A prefix spans fewer directions than a whole motion, so its test has fewer (and,
    per component, different) degrees of freedom; they are integers, and the
    quantile of each distinct value is computed once. Non-integer ``dof`` is passed
    to scipy as is.
    """
    if np.ndim(dof) == 0:
        if float(dof) == int(dof):
            return _chi2_ppf(float(q), int(dof))
        return float(chi2.ppf(q, float(dof)))
    d = np.asarray(dof, float)
    if d.size:
        lo, hi = float(d.min()), float(d.max())
        if np.isfinite(lo) and np.isfinite(hi) and hi - lo < _TABLE_SPAN:
            whole = d.astype(np.int64)
            if np.array_equal(whole, d):
                # Integer dof (every prefix test): a table over their range, indexed; no sort of
                # the (K, J) array, whose size grows with the library.
                table = np.array([_chi2_ppf(float(q), v) for v in range(int(lo), int(hi) + 1)])
                return table[whole - int(lo)]
    values, inverse = np.unique(d, return_inverse=True)
    out = [_chi2_ppf(float(q), int(v)) if v == int(v) else float(chi2.ppf(q, v)) for v in values]
    return np.array(out)[inverse].reshape(d.shape)


@dataclass(frozen=True)
class Chi2Rule:
    """Scale-free tests on the squared Mahalanobis distance (chi-square quantiles)."""

    novelty_quantile: float
    merge_quantile: float
    split_quantile: float
    consolidation: float

    def novel(self, log_likelihoods, mahalanobis_sq, dof) -> np.ndarray:
        return np.asarray(mahalanobis_sq) > chi2_ppf(self.novelty_quantile, dof)

    def merge_scores(self, mahalanobis_sq, support, inflate, logdet, dof) -> np.ndarray:
        threshold = chi2_ppf(self.merge_quantile, int(dof)) / np.asarray(support, float) ** self.consolidation
        return np.asarray(mahalanobis_sq) / threshold - 1.0

    def merge_limit(self, support, logdet, dof) -> float:
        # a pair's threshold is q / s^beta with s the larger of its two supports, at least the smallest
        # (beta >= 0, LibraryConfig checks it)
        return float(chi2_ppf(self.merge_quantile, int(dof)) / float(np.min(support)) ** self.consolidation)

    def splits(self, mahalanobis_sq, dof) -> np.ndarray:
        return np.asarray(mahalanobis_sq) > chi2_ppf(self.split_quantile, int(dof))


@dataclass(frozen=True)
class LogLikRule:
    """The paper's tests on ``log p`` (Algorithm 1, Eq. 10)."""

    log_T_nov: float
    log_T_merge: float
    split_quantile: float
    consolidation: float

    def novel(self, log_likelihoods, mahalanobis_sq, dof) -> np.ndarray:
        return np.asarray(log_likelihoods) < self.log_T_nov

    def merge_scores(self, mahalanobis_sq, support, inflate, logdet, dof) -> np.ndarray:
        # log N(mu_i - mu_j | 0, Sigma (1/s_i + 1/s_j))
        logp = -0.5 * (dof * _LOG_2PI + logdet + dof * np.log(inflate) + np.asarray(mahalanobis_sq))
        threshold = self.log_T_merge + self.consolidation * np.log(np.asarray(support, float))
        return threshold - logp  # not exp(): clipped, pairs deep inside the threshold all tied

    def merge_limit(self, support, logdet, dof) -> float:
        # merge iff d2 < -2 (log T_merge + beta log s) - dof log 2 pi - logdet - dof log(1/s_i + 1/s_j): largest
        # for s (the pair's larger support) at the smallest support (beta >= 0) and both supports at the largest
        s = np.asarray(support, float)
        return float(-2.0 * (self.log_T_merge + self.consolidation * np.log(s.min())) - dof * _LOG_2PI - logdet
                     - dof * np.log(2.0 / s.max()))

    def splits(self, mahalanobis_sq, dof) -> np.ndarray:
        return np.asarray(mahalanobis_sq) > chi2_ppf(self.split_quantile, int(dof))


def novelty_rule(config) -> NoveltyRule:
    """The test ``config.novelty_test`` names, with its settings."""
    if config.novelty_test == "chi2":
        return Chi2Rule(config.novelty_quantile, config.merge_quantile, config.split_quantile, config.consolidation)
    if config.novelty_test == "loglik":
        return LogLikRule(config.log_T_nov, config.log_T_merge, config.split_quantile, config.consolidation)
    raise ValueError(f"unknown novelty_test {config.novelty_test!r}")
