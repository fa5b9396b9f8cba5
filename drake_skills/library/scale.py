"""The library's novelty scale: one within-skill covariance, learned from what the library has seen.

The paper gives every new component the same hand-set ``Sigma_init`` and judges
novelty and merges on it. No fixed scale serves real data (``../shared/DESIGN.md``,
"What we measured on real motion"): the within-skill scatter of real human motion is
ten times wider than that of letters, and it is far from isotropic. Here the scale is
estimated online, as in a hierarchical (Normal-inverse-Wishart) mixture whose
components share one within-skill covariance:

* :class:`Cluster` holds the exact moments of a set of weight vectors: support ``s``,
  mean, and the scatter ``S = sum_i lam_i (w_i - mean)(w_i - mean)^T`` as a factor
  ``F`` with ``S = F F^T`` (a few columns per demonstration, so a library of a
  thousand small components stays small; never more columns than dimensions).
* :class:`SharedScale` holds the running totals of every demonstration's weights and
  the scatter pooled over all components, ``P = sum_k S_k`` with
  ``nu = sum_k (s_k - 1)`` degrees of freedom.
* :func:`shared_covariance` turns them into the within-skill covariance

      Sigma = shrink((nu_0 W_0 + P) / (nu_0 + nu)),
      W_0   = rho^2 blkdiag(t_h I, t_r I),

  where ``t_h`` (``t_r``) is the mean variance per human (robot) weight of all
  demonstrations seen so far, ``rho = prior_scale`` and ``nu_0 = prior_strength``:
  before the library has seen a skill twice, a skill is assumed to spread ``rho``
  times as much as all motions together (a scale-free prior); as components absorb
  demonstrations their pooled scatter takes over. ``shrink`` pulls each block
  towards its mean diagonal (``shrinkage``), so the estimate is positive definite
  from the first pooled demonstration on, whatever the dimension.

Everything here is a pure function of immutable values.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Shares of a demonstration's own path at which its beginning is tested, before it joins a
#: component, against that component's prefix model (``Cluster.tested``,
#: ``Cluster.missed``; :meth:`~drake_skills.library.recognition.RecognitionMixin._beginnings_missed`).
BEGINNING_FRACTIONS = (0.1, 0.2)
#: A component's record of beginnings stops growing once every share has this much tested weight:
#: enough to tell a miss rate of one half from none (the blind components of the real interactions
#: miss 60-100 %), and the test's cost in ``partial_fit`` then stops too.
RECORD_TESTS = 10.0
#: A component that misses more than this share of its own beginnings (at a share of its path)
#: cannot be ruled out from a beginning there (:func:`beginning_blind`). Chosen on the buetepage
#: training split: taught task by task, a wave component that missed one of its three 20 %
#: beginnings (and all at 10 %) ruled itself out at 17-20 % of a held-out wave, and a rocket
#: fragment was committed to (0.010 of first commits wrong with 0.5, 0 with 0.3 or 0.2; the
#: interleaved teaching and the salad replay are the same at all three). The price is one miss in
#: two or three of a young component's tests: of 100 synthetic skills' beginnings at 30 %, 21
#: are undecided on a blind one instead of 18.
BLIND_RATE = 0.3


def _no_beginnings() -> np.ndarray:
    return np.zeros(len(BEGINNING_FRACTIONS))


def _no_pending() -> np.ndarray:
    return np.full(len(BEGINNING_FRACTIONS), np.nan)

#: Relative floor added to the diagonal of the shared covariance (keeps it positive
#: definite before any spread has been seen, e.g. after one demonstration).
_FLOOR = 1e-9


@dataclass(frozen=True, eq=False)
class Cluster:
    """Exact moments of a (responsibility-weighted) set of weight vectors.

    Attributes
    ----------
    support : float
        s, the total weight of its members (> 0).
    mean : array, shape (d,)
    factor : array, shape (d, r)
        Scatter factor: ``S = factor @ factor.T``; ``r <= d``.
    duration : float
        Mean duration of its demonstrations (s).
    path_length : float
        Mean length of their normalized human paths (arc length, workspace units).
    tested : array, shape (B,)
        The record of its beginnings: the weight of the member demonstrations whose
        beginning at ``BEGINNING_FRACTIONS[b]`` of their path was tested against this
        cluster's component before they joined it (a component's first demonstration was
        not: there was nothing to test it against).
    missed : array, shape (B,)
        Of that weight, the part whose beginning the component's prefix test rejected
        (``0 <= missed <= tested``). A component that misses its own beginnings cannot be
        ruled out from a beginning (:func:`beginning_blind`).
    tasks : tuple of (str, float)
        The task names its member demonstrations were taught under (``Demonstration.task``) with their
        weight, sorted by name (demonstrations without a name have none): taught as one task, a skill
        answers; taught as several, the library does not act on it
        (``LibraryConfig.mixed_task_share``).
    pending : array, shape (B,)
        The outcome (1 missed, 0 explained, NaN none) of the cluster's first demonstration's
        beginnings tested, when it made a new component, against the component nearest to it:
        not yet a test against its own skill, it joins the record when the cluster merges with
        another (:meth:`pool`; a skill shown several times in a row fragments while the scale is
        its prior, and its fragments' first demonstrations are otherwise never tested).
    """

    support: float
    mean: np.ndarray
    factor: np.ndarray
    duration: float
    path_length: float
    tested: np.ndarray = field(default_factory=_no_beginnings)
    missed: np.ndarray = field(default_factory=_no_beginnings)
    pending: np.ndarray = field(default_factory=_no_pending)
    tasks: tuple = ()

    @classmethod
    def of_sample(cls, w: np.ndarray, duration: float, path_length: float, support: float = 1.0,
                  missed: np.ndarray | None = None, pending: np.ndarray | None = None,
                  task: str | None = None) -> "Cluster":
        """One demonstration with weights ``w`` (d,) (its beginnings' test, see :meth:`add`; ``pending``: see
        the attribute; ``task``: its task name, None: none)."""
        w = np.array(w, dtype=float)
        tested, miss = _recorded(_no_beginnings(), _no_beginnings(), float(support), missed)
        pend = _no_pending() if pending is None else np.array(pending, dtype=float)
        if pend.shape != tested.shape:
            raise ValueError(f"a pending test of beginnings has shape {pend.shape}, expected {tested.shape}")
        return cls(float(support), w, np.zeros((w.shape[0], 0)), float(duration), float(path_length), tested, miss,
                   pend, with_task((), task, float(support)))

    @property
    def scatter(self) -> np.ndarray:
        """S, shape (d, d)."""
        return self.factor @ self.factor.T

    def add(self, w: np.ndarray, lam: float, duration: float, path_length: float,
            missed: np.ndarray | None = None, task: str | None = None) -> tuple["Cluster", np.ndarray]:
        """The cluster with ``w`` added at weight ``lam`` (Eqs. 6-8 with the exact running moments).

        ``missed`` (B,): whether the component's prefix test rejected the demonstration's
        beginning at each of ``BEGINNING_FRACTIONS`` (1 or 0; NaN: not tested); None: none tested.
        ``task``: the demonstration's task name (counted at weight ``lam``); None: none.

        Returns the new cluster and the scatter increment's factor column
        ``g`` (d,), with ``S_new = S + g g^T``.

        Notes
        -----
        With ``s = s_old + lam``, ``gamma = lam / s`` and ``e = w - mu_old``::

            mu = mu_old + gamma e,    S = S_old + lam (s_old / s) e e^T.

        (Eqs. 7-8 as printed drop a factor ``(1 - gamma)`` of the new scatter; this is
        the exact weighted scatter, so a component's covariance ``S / s`` equals the
        biased sample covariance of its members.)
        """
        s = self.support + lam
        gamma = lam / s
        e = w - self.mean
        g = np.sqrt(lam * self.support / s) * e
        mean = self.mean + gamma * e
        factor = _compress(np.column_stack([self.factor, g]))
        dur = self.duration + gamma * (duration - self.duration)
        path = self.path_length + gamma * (path_length - self.path_length)
        tested, miss = _recorded(self.tested, self.missed, lam, missed)
        return Cluster(s, mean, factor, dur, path, tested, miss, self.pending, with_task(self.tasks, task, lam)), g

    def pool(self, other: "Cluster") -> tuple["Cluster", np.ndarray]:
        """The union of two clusters (moment matching; the corrected Eq. 11).

        Returns the pooled cluster and the factor column ``g`` of the between term,
        ``S = S_a + S_b + g g^T`` with ``g = sqrt(s_a s_b / s) (mu_a - mu_b)``.
        """
        sa, sb = self.support, other.support
        s = sa + sb
        dm = self.mean - other.mean
        g = np.sqrt(sa * sb / s) * dm
        mean = (sa * self.mean + sb * other.mean) / s
        factor = _compress(np.column_stack([self.factor, other.factor, g]))
        dur = (sa * self.duration + sb * other.duration) / s
        path = (sa * self.path_length + sb * other.path_length) / s
        # each side's pending first test joins the record: the two are one skill now (weight 1: one demonstration)
        tested, missed = _recorded(self.tested + other.tested, self.missed + other.missed, 1.0, self.pending)
        tested, missed = _recorded(tested, missed, 1.0, other.pending)
        return Cluster(s, mean, factor, dur, path, tested, missed, tasks=pooled_tasks(self.tasks, other.tasks)), g


def with_task(tasks: tuple, task: str | None, weight: float) -> tuple:
    """``tasks`` ((name, weight) pairs sorted by name) with ``weight`` more of ``task`` (None: unchanged)."""
    if task is None:
        return tasks
    d = dict(tasks)
    d[str(task)] = d.get(str(task), 0.0) + float(weight)
    return tuple(sorted(d.items()))


def pooled_tasks(a: tuple, b: tuple) -> tuple:
    """The task weights of two clusters together."""
    d = dict(a)
    for name, weight in b:
        d[name] = d.get(name, 0.0) + weight
    return tuple(sorted(d.items()))


def mixed_share(tasks: tuple) -> float:
    """The share of a cluster's task weight that is not its main task's (0 with one task or none)."""
    weights = [w for _, w in tasks]
    total = sum(weights)
    return (total - max(weights)) / total if total > 0 else 0.0


def main_task(tasks: tuple) -> str | None:
    """The task with the most weight (None without tasks or with no positive weight; of equal weights the first
    name)."""
    named = [t for t in tasks if t[1] > 0]
    return max(named, key=lambda t: t[1])[0] if named else None


def task_of(tasks: tuple, mixed_task_share: float) -> str | None:
    """The task a cluster was taught as: its main task name (:func:`main_task`), None without names or when
    the other names hold ``mixed_task_share`` or more of its weight (:func:`mixed_share`)."""
    return main_task(tasks) if mixed_share(tasks) < mixed_task_share else None


def beginning_blind(tested: np.ndarray, missed: np.ndarray, shares: np.ndarray) -> np.ndarray:
    """Which components (K,) miss too many of their own beginnings at ``shares`` (K,) of their path.

    The records (K, B) (:attr:`Cluster.tested`, :attr:`Cluster.missed`) give the miss rate
    ``missed / tested`` at each of the ``BEGINNING_FRACTIONS`` (0 where nothing was tested),
    interpolated linearly between them (the first one's below it); above
    :data:`BLIND_RATE` is blind: the component's own prefix test rejects its own motion
    there so often that its rejection does not rule it out. A share past the
    last fraction by more than half a step is never blind (not tested).
    """
    F = np.asarray(BEGINNING_FRACTIONS)
    tested = np.asarray(tested, float)
    rate = np.divide(np.asarray(missed, float), tested, out=np.zeros_like(tested), where=tested > 0)
    shares = np.asarray(shares, float)
    # np.interp row by row, vectorized: the segment of F each share falls in, clamped at both ends
    i = np.clip(np.searchsorted(F, shares), 1, F.size - 1)
    t = np.clip((shares - F[i - 1]) / (F[i] - F[i - 1]), 0.0, 1.0)
    k = np.arange(shares.shape[0])
    at = rate[k, i - 1] + t * (rate[k, i] - rate[k, i - 1])
    return (shares <= F[-1] + 0.5 * (F[-1] - F[-2])) & (at > BLIND_RATE)


def _recorded(tested: np.ndarray, missed: np.ndarray, lam: float, outcome) -> tuple[np.ndarray, np.ndarray]:
    """The record with one demonstration's ``outcome`` (B,) (1 missed, 0 explained, NaN not tested) added at
    weight ``lam``; ``outcome`` None adds nothing."""
    if outcome is None:
        return tested, missed
    m = np.asarray(outcome, float)
    if m.shape != tested.shape:
        raise ValueError(f"a record of beginnings has shape {m.shape}, expected {tested.shape}")
    ok = np.isfinite(m)
    return tested + lam * ok, missed + lam * np.where(ok, np.clip(m, 0.0, 1.0), 0.0)


def _compress(factor: np.ndarray) -> np.ndarray:
    """An equivalent factor with at most ``d`` columns (``F F^T`` unchanged).

    A full lower-triangular factor with one column appended (a cluster's update once it has more
    members than dimensions: every update from then on) is re-triangularized by Givens rotations
    (``scipy.linalg.qr_insert``: O(d^2), about 7x faster than the QR at d = 150); anything else by a QR.
    """
    d, r = factor.shape
    if r <= d:
        return factor
    if r == d + 1 and not np.triu(factor[:, :d], 1).any():
        from scipy.linalg import qr_insert  # noqa: PLC0415 (scipy.linalg is slow to import; only for full factors)

        # [L g]^T = [L^T; g^T]: insert the row g^T into the QR (Q = I, R = L^T) of L^T
        R = qr_insert(np.eye(d), factor[:, :d].T, factor[:, d], d, which="row", check_finite=False)[1]
        return np.ascontiguousarray(R[:d].T)
    R = np.linalg.qr(factor.T, mode="r")  # F^T = Q R  =>  F F^T = R^T R
    return np.ascontiguousarray(R.T)


@dataclass(frozen=True, eq=False)
class SharedScale:
    """Running totals of all demonstrations and the within-skill scatter pooled over components.

    Attributes
    ----------
    n : int
        Demonstrations counted in the totals.
    total_mean : array, shape (d,)
        Mean of their weights.
    total_m2 : array, shape (d,)
        Per weight, the sum of squared deviations from ``total_mean`` (Welford).
    pooled : array, shape (d, d)
        P, the sum of the components' scatters.
    dof : float
        nu, the sum over components of ``s_k - 1``.
    fit_m2 : float
        Sum over the demonstrations of the mean squared residual of their human path
        around its own basis fit (normalized units^2): what the weights cannot hold (the
        sensor noise, an oscillation finer than the basis). Its mean is the observation
        noise prefix recognition and conditioning need (:func:`observation_noise`).
    """

    n: int
    total_mean: np.ndarray
    total_m2: np.ndarray
    pooled: np.ndarray
    dof: float
    fit_m2: float = 0.0

    @classmethod
    def empty(cls, d: int) -> "SharedScale":
        return cls(0, np.zeros(d), np.zeros(d), np.zeros((d, d)), 0.0, 0.0)

    def count(self, w: np.ndarray, fit_residual: float = 0.0) -> "SharedScale":
        """The totals with one more demonstration ``w`` (d,) whose human fit left ``fit_residual`` (mean square)."""
        n = self.n + 1
        delta = w - self.total_mean
        mean = self.total_mean + delta / n
        m2 = self.total_m2 + delta * (w - mean)
        return SharedScale(n, mean, m2, self.pooled, self.dof, self.fit_m2 + float(fit_residual))

    def with_scatter(self, columns: np.ndarray, sign: float, dof: float) -> "SharedScale":
        """``P +- columns columns^T`` and ``nu + dof`` (``columns`` (d,) or (d, r))."""
        g = np.asarray(columns, float).reshape(self.pooled.shape[0], -1)
        pooled = self.pooled + sign * (g @ g.T)
        return SharedScale(self.n, self.total_mean, self.total_m2, 0.5 * (pooled + pooled.T), self.dof + dof,
                           self.fit_m2)

    def block_variances(self, n_human: int) -> tuple[float, float]:
        """Mean variance per weight over all demonstrations: human block, robot block."""
        var = self.total_m2 / max(self.n, 1)
        d = var.shape[0]
        # sum / count is np.mean's own arithmetic, without its dispatch (this runs several times per update)
        t_h = float(var[:n_human].sum()) / n_human if n_human else 0.0
        t_r = float(var[n_human:].sum()) / (d - n_human) if d > n_human else 0.0
        return t_h, t_r


def observation_noise(scale: SharedScale, floor: float) -> float:
    """Variance of an observed human sample: the mean out-of-basis residual of the demonstrations seen, at least ``floor``.

    With a fixed value (``LibraryConfig.observation_noise``) a motion whose path
    holds more than the basis can (a wave, a shake: its oscillation is finer than
    seven Gaussians) looks impossibly far from every prefix of its own skill; the
    residual the library has seen says how far samples lie off a fit.
    """
    seen = scale.fit_m2 / scale.n if scale.n else 0.0
    return max(float(floor), float(seen))


def _blend(P: np.ndarray, dof: float, W0_diag: np.ndarray, prior_strength: float) -> np.ndarray:
    S = P / (prior_strength + dof)
    S.reshape(-1)[::S.shape[0] + 1] += prior_strength * W0_diag / (prior_strength + dof)  # the diagonal, in place
    return S


def _shrunk(S: np.ndarray, shrinkage: float, floor_scale: float) -> np.ndarray:
    d = S.shape[0]
    m = float(np.trace(S)) / d if d else 0.0
    out = (1.0 - shrinkage) * S
    out.reshape(-1)[::d + 1] += shrinkage * m + _FLOOR * (m + floor_scale) + 1e-300  # the diagonal, in place
    return out


def gating_covariance(scale: SharedScale, n_human: int, *, prior_scale: float, prior_strength: float,
                      shrinkage: float, prior_floor: float = 0.0) -> np.ndarray:
    """The shared within-skill covariance of the human (gating) weights, shape (h, h)."""
    h = n_human
    t_h, _ = scale.block_variances(h)
    W0 = np.full(h, max(prior_scale ** 2 * t_h, prior_floor ** 2))
    S = _blend(scale.pooled[:h, :h].copy(), scale.dof, W0, prior_strength)
    return _shrunk(S, shrinkage, float(np.mean(scale.total_mean[:h] ** 2)) if h else 0.0)


def cross_covariance(scale: SharedScale, n_human: int, *, prior_strength: float, shrinkage: float) -> np.ndarray:
    """The robot-human block ``[h:, :h]`` of :func:`shared_covariance`, shape (d - h, h), without the rest.

    Off the diagonal the prior adds nothing and the shrinkage only scales, so the block is
    ``(1 - shrinkage) pooled[h:, :h] / (prior_strength + dof)``.
    """
    h = n_human
    return (1.0 - shrinkage) * scale.pooled[h:, :h] / (prior_strength + scale.dof)


def shared_covariance(scale: SharedScale, n_human: int, *, prior_scale: float, prior_strength: float,
                      shrinkage: float, prior_floor: float = 0.0) -> np.ndarray:
    """The shared within-skill covariance of the stacked weights ``[w_h; w_r]``, shape (d, d).

    The human block equals :func:`gating_covariance`; each block is shrunk towards its
    own mean diagonal (the blocks have different units), the cross block by the same
    factor, so the result is a convex combination of positive semidefinite matrices.
    """
    d, h = scale.pooled.shape[0], n_human
    t_h, t_r = scale.block_variances(h)
    W0 = np.concatenate([np.full(h, max(prior_scale ** 2 * t_h, prior_floor ** 2)),
                         np.full(d - h, prior_scale ** 2 * t_r)])
    S = _blend(scale.pooled.copy(), scale.dof, W0, prior_strength)
    out = (1.0 - shrinkage) * S
    for sl in (slice(0, h), slice(h, d)):
        block = _shrunk(S[sl, sl], shrinkage, float(np.mean(scale.total_mean[sl] ** 2)) if sl.stop > sl.start else 0.0)
        out[sl, sl] = block
    return 0.5 * (out + out.T)
