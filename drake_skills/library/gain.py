"""How far to trust the human-robot correlation in Eq. (13): a gain per robot basis function, learned online.

**A deviation from the paper.** Eq. (13) moves the robot's weights from the component's mean
by the full regression on the observed human motion, ``delta = Sigma_rh S^-1 (y - Phi mu_h)``.
That regression is estimated from the few demonstrations of one component (about 8 in 21
human weights on the real interactions), and where the person's motion does not carry to
the robot's it adds error: on the buetepage training split the conditioned response was
worse than the component's unconditioned mean (0.236 against 0.198 rad, RESULTS.md).

The library therefore scales the correction by a gain per robot basis function
(``lambda_j``, the same for every joint): ``mean = mu_r + Lambda delta``. The gains are
fitted by least squares on the library's own demonstrations, *before* each one joins its
component (prequentially, so the fit judges predictions of demonstrations the component
had not seen): each demonstration ``n`` that the library recognizes contributes its
correction ``delta_n`` and its error ``e_n = w_r - mu_r`` (both D_r x B), in the robot
trajectory's metric ``G = Phi_r^T Phi_r``, to the normal equations

    A = sum_n sum_d diag(delta_nd) G diag(delta_nd),   b = sum_n sum_d delta_nd * (G e_nd),

and ``lambda = (A + P)^-1 (b + P 1)`` clipped to [0, 1], with ``P = GAIN_PRIOR trace(A) / (B N) I``:
``GAIN_PRIOR`` demonstrations' worth of belief in the paper's gain of 1. A library that has
not yet predicted a demonstration conditions exactly as Eq. (13). The covariance is the one
of the scaled predictor under the component's joint Gaussian,
``Sigma_rr - (Lambda M + M Lambda - Lambda M Lambda)`` with ``M`` the reduction Eq. (13)
gives, so a gain of 0 returns the prior and a gain of 1 Eq. (13).

The gains are fitted on whole motions (each demonstration conditioned on all of it) and applied
at every observed fraction, so a beginning's correction is scaled as a whole motion's would be
(RESULTS.md, "Conditioning against the mean", has the salad's response against the fraction).

``LibraryConfig.conditioning_gain = False`` keeps the paper's Eq. (13); the library then keeps no
record (and ``partial_fit`` skips the one conditioning per demonstration the fit costs).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Pseudo-demonstrations of gain 1 in the fit (see the module).
GAIN_PRIOR = 2.0


@dataclass(frozen=True, eq=False)
class ConditioningGain:
    """The normal equations of the gain fit: ``normal`` (B, B), ``target`` (B,), over ``count`` demonstrations."""

    normal: np.ndarray
    target: np.ndarray
    count: int

    def __post_init__(self):
        A, b = np.array(self.normal, dtype=float), np.array(self.target, dtype=float)  # copies: frozen below
        B = b.shape[0] if b.ndim == 1 else -1
        if b.ndim != 1 or A.shape != (B, B):
            raise ValueError(f"conditioning gain: normal must be (B, B) and target (B,), got {A.shape} and {b.shape}")
        if not (np.isfinite(A).all() and np.isfinite(b).all()):
            raise ValueError("conditioning gain: normal and target must be finite")
        if not np.allclose(A, A.T, rtol=1e-9, atol=1e-12):
            raise ValueError("conditioning gain: normal is not symmetric")
        if A.size:
            scale = float(np.abs(A).max())
            with np.errstate(over="ignore", invalid="ignore"):  # an overflowing record fails the test below
                bad = not np.isfinite(np.trace(A)) or np.linalg.eigvalsh(0.5 * (A + A.T)).min() < -1e-9 * max(scale, 1e-300)
            if bad:
                raise ValueError("conditioning gain: normal must be positive semidefinite (a sum of squares) with a "
                                 "finite trace")
        try:
            whole = not isinstance(self.count, bool) and int(self.count) == self.count
        except (TypeError, ValueError, OverflowError):
            whole = False
        if not whole or self.count < 0:
            raise ValueError(f"conditioning gain: count must be an integer >= 0, got {self.count!r}")
        if self.count == 0 and (A.any() or b.any()):
            raise ValueError("conditioning gain: a record of 0 demonstrations must be zero")
        _freeze(self, A, b, int(self.count))

    @classmethod
    def empty(cls, n_basis: int) -> "ConditioningGain":
        return cls(np.zeros((n_basis, n_basis)), np.zeros(n_basis), 0)

    @property
    def n_basis(self) -> int:
        return self.target.shape[0]

    def add(self, correction: np.ndarray, error: np.ndarray, gram: np.ndarray) -> "ConditioningGain":
        """The record with one more demonstration: ``correction`` and ``error`` (D_r, B), ``gram`` (B, B)."""
        d, e = np.asarray(correction, float), np.asarray(error, float)
        B = self.n_basis
        if d.ndim != 2 or d.shape[1] != B or e.shape != d.shape or np.shape(gram) != (B, B):
            raise ValueError(f"conditioning gain: correction and error must be (D_r, {B}) and gram ({B}, {B}), "
                             f"got {d.shape}, {e.shape}, {np.shape(gram)}")
        A = self.normal + np.einsum("da,ab,db->ab", d, gram, d)
        b = self.target + np.einsum("da,da->a", d, e @ gram)   # gram is symmetric: (G e)_a = (e G)_a
        if not (np.isfinite(A).all() and np.isfinite(b).all()):
            raise ValueError("conditioning gain: a correction or error is not finite")
        # a sum of the record and a positive semidefinite term: valid by construction, so the
        # checks of __post_init__ (an eigendecomposition, a quarter of a partial_fit) are skipped
        out = object.__new__(ConditioningGain)
        _freeze(out, 0.5 * (A + A.T), b, self.count + 1)
        return out

    def gains(self) -> np.ndarray:
        """``lambda`` (B,) in [0, 1], read-only; all 1 before the first demonstration (see the module)."""
        hit = self.__dict__.get("_gains")  # computed once per record (every predict_robot asks)
        if hit is None:
            hit = self._fit()
            hit.setflags(write=False)
            object.__setattr__(self, "_gains", hit)
        return hit

    def _fit(self) -> np.ndarray:
        B = self.n_basis
        if self.count == 0:
            return np.ones(B)
        P = GAIN_PRIOR * max(float(np.trace(self.normal)), 0.0) / (B * self.count)
        if P <= 0.0:  # every correction so far was zero: nothing to learn from
            return np.ones(B)
        lam = np.linalg.solve(self.normal + P * np.eye(B), self.target + P)
        if not np.isfinite(lam).all():
            raise ValueError("conditioning gain: the fit is not finite (the record overflows)")
        return np.clip(lam, 0.0, 1.0)


def _freeze(record: ConditioningGain, normal: np.ndarray, target: np.ndarray, count: int) -> None:
    """Set the fields of a (frozen) record, its arrays made read-only."""
    normal.setflags(write=False)
    target.setflags(write=False)
    object.__setattr__(record, "normal", normal)
    object.__setattr__(record, "target", target)
    object.__setattr__(record, "count", count)


def scale_correction(prior_mean, prior_cov, mean, cov, gains) -> tuple[np.ndarray, np.ndarray]:
    """Eq. (13)'s posterior ``(mean, cov)`` with its correction scaled by ``gains`` (one per weight, in [0, 1]).

    ``prior_mean`` (n,), ``prior_cov`` (n, n): before conditioning; ``mean``, ``cov``: Eq. (13).
    Returns ``prior_mean + g (mean - prior_mean)`` and
    ``prior_cov - (G M + M G - G M G)`` with ``G = diag(g)``, ``M = prior_cov - cov``, computed as
    ``cov + (1 - g)(1 - g)^T * M`` (elementwise; the same matrix, and symmetric as M is).
    """
    g = np.asarray(gains, float)
    q = 1.0 - g
    M = np.asarray(prior_cov) - np.asarray(cov)
    M *= np.outer(q, q)
    M += cov
    mean = np.asarray(mean)
    return mean - q * (mean - np.asarray(prior_mean)), M
