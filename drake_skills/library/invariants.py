"""What must hold of every library state, as a pure function: the checks of ``load``, the property tests and the soak.

Algorithm 1 on a learned scale (:mod:`~drake_skills.library.algorithm`) keeps running
sums in two places: each component's moments and its two sub-clusters', and the
shared scale's pooled scatter and degrees of freedom, which are the sums of the
components'. Every update adds and subtracts the same terms in both places, so they
agree up to rounding, whatever the stream; a disagreement is a bug (or a crafted
file). :func:`invariant_violations` lists them:

* finite, positive supports; finite means and scatter factors of the right shape;
* the two sub-clusters of a component sum to it: support, mean (support-weighted)
  and scatter (``S = S_a + S_b + g g^T`` with the between term
  ``g = sqrt(s_a s_b / s) (mu_a - mu_b)``);
* the pooled scatter is the sum of the components' scatters,
  ``P = sum_k S_k``, and its degrees of freedom ``nu = sum_k (s_k - 1)``;
* the scale counted every demonstration once (``n == n_seen``) and its totals are
  finite with non-negative variances;
* the shared covariance (stacked and gating block) is symmetric positive definite.

Scatters are compared through what they do to a few fixed random probe vectors
(``S V`` with ``V`` (d, 4), from the factors: ``F (F^T V)``), which finds any
difference of the matrices but a set of measure zero, at O(d r) per cluster instead
of O(d^2 r): a 1000-component library is checked in milliseconds.

Relative differences are measured against the size of the terms compared
(``|a - b| <= rtol (|a| + |b|) + atol``), with ``atol`` a tiny multiple of the
weights' overall variance so that sums that cancel to zero compare sanely.
"""
from __future__ import annotations

import numpy as np

from drake_skills.library.scale import Cluster, shared_covariance
from drake_skills.library.state import LibraryState

#: Default relative tolerance: rounding over ~10^5 updates stays far below it.
RTOL = 1e-9


#: Number of random probe vectors the scatters are compared through.
N_PROBES = 4


def _probes(d: int) -> np.ndarray:
    return np.random.default_rng(12345).standard_normal((d, N_PROBES))


def _close(a, b, rtol: float, atol: float) -> tuple[bool, float]:
    a, b = np.asarray(a, float), np.asarray(b, float)
    scale = float(np.linalg.norm(a) + np.linalg.norm(b))
    err = float(np.linalg.norm(a - b))
    return err <= rtol * scale + atol, err / max(scale, 1e-300)


def _asymmetry(A: np.ndarray) -> float:
    return float(np.abs(A - A.T).max(initial=0.0))


def _cluster_ok(cl: Cluster, d: int, what: str, out: list) -> bool:
    if not (np.isfinite(cl.support) and cl.support > 0):
        out.append(f"{what}: support {cl.support} is not positive")
        return False
    if np.shape(cl.mean) != (d,) or np.ndim(cl.factor) != 2 or np.shape(cl.factor)[0] != d:
        out.append(f"{what}: mean {np.shape(cl.mean)} and scatter factor {np.shape(cl.factor)} for {d} weights")
        return False
    if not (np.isfinite(cl.mean).all() and np.isfinite(cl.factor).all()):
        out.append(f"{what}: NaN or inf in its mean or scatter")
        return False
    return True


def invariant_violations(state: LibraryState, *, rtol: float = RTOL, check_covariance: bool = True) -> list[str]:
    """The invariants ``state`` breaks, one sentence each (empty: none).

    Parameters
    ----------
    state : LibraryState
    rtol : float
        Relative tolerance of the sums (see the module docstring).
    check_covariance : bool
        Also check that the shared covariance is SPD (a Cholesky factorization, O(d^3)).

    Returns
    -------
    list of str
    """
    out: list[str] = []
    if state.dim_human is None:
        if state.components:
            out.append("components but no dimensions")
        return out
    d, h = state.n_weights, state.n_human
    sc = state.scale
    if sc is None:
        return ["a fitted library without its shared scale"]
    var_scale = float(np.sum(np.abs(sc.total_m2))) / max(sc.n, 1) + 1e-300
    atol = 1e-12 * var_scale
    if sc.n != state.n_seen:
        out.append(f"the shared scale counted {sc.n} demonstrations, the library has seen {state.n_seen}")
    if not (np.isfinite(sc.total_mean).all() and np.isfinite(sc.total_m2).all() and np.isfinite(sc.pooled).all()):
        out.append("the shared scale has NaN or inf entries")
        return out
    if (sc.total_m2 < -atol).any():
        out.append("the shared scale has a negative variance")
    V = _probes(d)
    pooled = np.zeros((d, N_PROBES))  # (sum_k S_k) V
    dof = 0.0
    for c in state.components:
        what = f"component {c.id}"
        if not _cluster_ok(c.cluster, d, what, out):
            continue
        F = c.cluster.factor
        S = F @ (F.T @ V)
        pooled += S
        dof += c.cluster.support - 1.0
        a, b = c.subclusters
        if a is None or not _cluster_ok(a, d, f"sub-cluster 0 of {what}", out):
            continue
        if b is None:
            parts = [(a.support, c.cluster.support, "support"), (a.mean, c.cluster.mean, "mean"),
                     (a.factor @ (a.factor.T @ V), S, "scatter")]
        else:
            if not _cluster_ok(b, d, f"sub-cluster 1 of {what}", out):
                continue
            s = a.support + b.support
            g = np.sqrt(a.support * b.support / s) * (a.mean - b.mean)
            parts = [(s, c.cluster.support, "support"),
                     ((a.support * a.mean + b.support * b.mean) / s, c.cluster.mean, "mean"),
                     (a.factor @ (a.factor.T @ V) + b.factor @ (b.factor.T @ V) + np.outer(g, g @ V), S,
                      "scatter")]
        for x, y, name in parts:
            scale_atol = atol if name == "scatter" else 1e-12 * (1.0 + float(np.abs(y).max(initial=0.0)))
            ok, rel = _close(x, y, rtol, scale_atol)
            if not ok:
                out.append(f"{what}: its sub-clusters' {name} differs from its own by {rel:.2e} (relative)")
    ok, rel = _close(sc.pooled @ V, pooled, rtol, atol * max(1, len(state.components)))
    if not ok:
        out.append(f"the pooled scatter differs from the sum of the components' scatters by {rel:.2e} (relative)")
    if abs(sc.dof - dof) > rtol * (abs(sc.dof) + abs(dof)) + 1e-9 * max(1, len(state.components)):
        out.append(f"the pooled degrees of freedom {sc.dof:.9g} differ from the components' sum(s_k - 1) {dof:.9g}")
    if _asymmetry(sc.pooled) > 1e-12 * float(np.abs(sc.pooled).max(initial=0.0)) + atol:
        out.append("the pooled scatter is not symmetric")
    if check_covariance and not out:
        cfg = state.config
        S = shared_covariance(sc, h, prior_scale=cfg.prior_scale, prior_strength=cfg.prior_strength,
                              shrinkage=cfg.shrinkage, prior_floor=cfg.prior_floor)
        for block, name in ((S, "stacked"), (S[:h, :h], "gating")):
            if _asymmetry(block) > 1e-12 * float(np.abs(block).max(initial=1.0)):
                out.append(f"the shared {name} covariance is not symmetric")
            try:
                np.linalg.cholesky(block)
            except np.linalg.LinAlgError:
                out.append(f"the shared {name} covariance is not positive definite")
    return out
