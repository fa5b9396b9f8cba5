"""Batch baselines in weight space (Sec. 4.1): labeled maximum likelihood and EM.

Both see all weight vectors at once, unlike the incremental library:

- :func:`labeled_ml` fits one Gaussian per known label (the paper's
  "baseline computed with Maximum Likelihood estimation from labeled data");
- :func:`batch_em` fits a full-covariance Gaussian mixture with a given
  number of components by EM (scikit-learn's ``GaussianMixture``).

The result, :class:`Mixture`, plugs into
:func:`drake_skills.promp.gaussian.mc_kl_mixtures` through ``as_tuple()``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.special import logsumexp

from drake_skills._checks import as_finite_array
from drake_skills.promp.gaussian import check_random_state, log_density, symmetrize


@dataclass(frozen=True, eq=False)
class Mixture:
    """A Gaussian mixture over weight vectors.

    Parameters
    ----------
    weights : array, shape (K,)
        Mixing weights, non-negative, summing to 1.
    means : array, shape (K, d)
    covs : array, shape (K, d, d)
        Symmetric positive definite covariances.
    labels : tuple of str, optional
        One label per component (``labeled_ml`` sets them).
    """

    weights: np.ndarray
    means: np.ndarray
    covs: np.ndarray
    labels: tuple | None = None

    def __post_init__(self):
        w = as_finite_array(self.weights, "mixture weights", ndim=1, min_rows=1)
        K = w.shape[0]
        m = as_finite_array(self.means, "mixture means", shape=(K, None))
        d = m.shape[1]
        if d < 1:
            raise ValueError("mixture means have no columns")
        S = as_finite_array(self.covs, "mixture covariances", shape=(K, d, d))
        if (w < 0).any() or not np.isclose(w.sum(), 1.0, rtol=0, atol=1e-9):
            raise ValueError(f"mixture weights must be non-negative and sum to 1, got sum {w.sum():g}")
        S = 0.5 * (S + S.transpose(0, 2, 1))
        chols = np.empty_like(S)
        for k in range(K):
            try:  # no jitter here: a mixture's covariances must be positive definite as given
                chols[k] = np.linalg.cholesky(S[k])
            except np.linalg.LinAlgError:
                raise ValueError(f"mixture covariance {k} is not positive definite") from None
        if self.labels is not None and len(self.labels) != K:
            raise ValueError(f"{len(self.labels)} labels for {K} components")
        for a in (w, m, S, chols):
            a.setflags(write=False)
        object.__setattr__(self, "weights", w)
        object.__setattr__(self, "means", m)
        object.__setattr__(self, "covs", S)
        object.__setattr__(self, "_chols", chols)
        if self.labels is not None:
            object.__setattr__(self, "labels", tuple(self.labels))

    @property
    def n_components(self) -> int:
        return int(self.weights.shape[0])

    @property
    def dim(self) -> int:
        return int(self.means.shape[1])

    def _check_points(self, X) -> np.ndarray:
        X = as_finite_array(X, "points", ndim=None)
        if X.ndim == 1:
            X = X[None, :]
        if X.ndim != 2 or X.shape[1] != self.dim:
            raise ValueError(f"points must have shape (n, {self.dim}), got {X.shape}")
        return X

    def component_log_densities(self, X) -> np.ndarray:
        """``log w_k + log N(x | mu_k, Sigma_k)``.

        Parameters
        ----------
        X : array, shape (n, d) or (d,)

        Returns
        -------
        L : array, shape (n, K)
        """
        X = self._check_points(X)
        with np.errstate(divide="ignore"):
            lw = np.log(self.weights)
        comp = np.stack([log_density(X, self.means[k], self._chols[k]) for k in range(self.n_components)], axis=1)
        return comp + lw[None, :]

    def log_density(self, X) -> np.ndarray:
        """Mixture log-density ``log sum_k w_k N(x | mu_k, Sigma_k)``.

        Parameters
        ----------
        X : array, shape (n, d) or (d,)

        Returns
        -------
        log_p : array, shape (n,)
        """
        return logsumexp(self.component_log_densities(X), axis=1)

    def predict(self, X) -> np.ndarray:
        """Most responsible component of each point.

        Parameters
        ----------
        X : array, shape (n, d) or (d,)

        Returns
        -------
        k : array of int, shape (n,)
        """
        return np.argmax(self.component_log_densities(X), axis=1)

    def as_tuple(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(weights (K,), means (K, d), covs (K, d, d))`` as ``mc_kl_mixtures`` takes it."""
        return self.weights, self.means, self.covs


def _check_W(W, min_rows: int) -> np.ndarray:
    W = as_finite_array(W, "weights W", ndim=2)
    if W.shape[1] < 1:
        raise ValueError(f"weights W has no columns: shape {W.shape}")
    if W.shape[0] < min_rows:
        raise ValueError(f"weights W is too short: {W.shape[0]} sample(s), need at least {min_rows}")
    return W


def labeled_ml(W, labels: Sequence, min_variance: float = 1e-6) -> Mixture:
    """One maximum-likelihood Gaussian per label (the paper's labeled baseline).

    Parameters
    ----------
    W : array, shape (n, d)
        Weight vectors, one per demonstration.
    labels : sequence, length n
        Label of each row (any hashable; components are ordered by first
        appearance).
    min_variance : float
        Added to the diagonal of each covariance so that a label with fewer
        samples than dimensions still gives a positive definite Gaussian
        (>= 0; 0 only works with enough samples per label).

    Returns
    -------
    mixture : Mixture
        Means are the per-label sample means, covariances the biased
        (``1/n_k``) sample covariances plus ``min_variance I``, weights the
        label frequencies ``n_k / n``; ``labels`` holds ``str(label)``.
    """
    W = _check_W(W, 1)
    labels = list(labels)
    if len(labels) != W.shape[0]:
        raise ValueError(f"{len(labels)} labels for {W.shape[0]} weight vectors")
    if not np.isfinite(min_variance) or min_variance < 0:
        raise ValueError(f"min_variance must be >= 0, got {min_variance!r}")
    order = list(dict.fromkeys(labels))
    lab = np.array([order.index(x) for x in labels])
    d = W.shape[1]
    weights, means, covs = [], [], []
    for k in range(len(order)):
        Wk = W[lab == k]
        if min_variance == 0 and Wk.shape[0] <= d:
            raise ValueError(f"label {order[k]!r} has {Wk.shape[0]} sample(s) in {d} dimensions: its covariance "
                             f"is singular; use min_variance > 0")
        mu = Wk.mean(axis=0)
        diff = Wk - mu
        weights.append(Wk.shape[0] / W.shape[0])
        means.append(mu)
        covs.append(symmetrize(diff.T @ diff / Wk.shape[0]) + min_variance * np.eye(d))
    try:
        return Mixture(np.array(weights), np.stack(means), np.stack(covs), labels=tuple(str(x) for x in order))
    except ValueError as exc:
        raise ValueError(f"labeled_ml: {exc}; raise min_variance") from None


def batch_em(W, n_components: int, random_state=None, n_init: int = 5, reg_covar: float = 1e-6,
             max_iter: int = 500) -> Mixture:
    """Full-covariance Gaussian mixture with a fixed number of components, by batch EM.

    Parameters
    ----------
    W : array, shape (n, d)
        Weight vectors, one per demonstration.
    n_components : int
        K, the number of components (the paper gives EM the true number).
    random_state : None, int or numpy Generator
        Seeds the k-means initialization; the same seed gives the same result.
    n_init : int
        Number of EM restarts; the best likelihood is kept.
    reg_covar : float
        Added to the diagonal of every covariance (> 0).
    max_iter : int
        EM iterations per restart.

    Returns
    -------
    mixture : Mixture
    """
    from sklearn.mixture import GaussianMixture

    if isinstance(n_components, bool) or int(n_components) != n_components or n_components < 1:
        raise ValueError(f"n_components must be an integer >= 1, got {n_components!r}")
    n_components = int(n_components)
    W = _check_W(W, max(n_components, 2))
    if isinstance(n_init, bool) or int(n_init) != n_init or n_init < 1:
        raise ValueError(f"n_init must be an integer >= 1, got {n_init!r}")
    if not np.isfinite(reg_covar) or reg_covar <= 0:
        raise ValueError(f"reg_covar must be positive, got {reg_covar!r}")
    n_distinct = np.unique(W, axis=0).shape[0]
    if n_distinct < n_components:
        raise ValueError(f"weights W has only {n_distinct} distinct row(s), cannot fit {n_components} components")
    rng = check_random_state(random_state)
    seed = int(rng.integers(2 ** 31 - 1))
    gmm = GaussianMixture(n_components=n_components, covariance_type="full", n_init=int(n_init),
                          reg_covar=float(reg_covar), max_iter=int(max_iter), random_state=seed)
    gmm.fit(W)
    weights = gmm.weights_ / gmm.weights_.sum()
    return Mixture(weights, gmm.means_, gmm.covariances_)
