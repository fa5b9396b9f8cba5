"""Benchmarks of the ProMP core (issue 2) against movement_primitives 0.9.1.

(a) weights of one demonstration, T = 150, 10 dimensions, 15 basis functions:
    our ``ridge_weights`` versus ``ProMP.weights``;
(b) conditioning on a full 3-D human trajectory of 150 samples: our
    ``InteractionProMP(3, 7, 15 + 15 basis).condition(y, z)`` on all 150 points
    at once versus movement_primitives' chained ``condition_position``, one
    call per observed point. movement_primitives has no human/robot split,
    so its ProMP conditions on all 10 dimensions at each point (the observed 3
    with noise, the other 7 with a variance of 1e6, i.e. unobserved); each of
    its calls costs the same, so a fixed number of calls is timed and the
    per-point time is multiplied by 150.
"""
from __future__ import annotations


import numpy as np

from drake_skills.benchmarks._timing import median_ms
from drake_skills.promp.basis import GaussianBasis, phases, ridge_weights
from drake_skills.promp.interaction import InteractionProMP

T, D, N = 150, 10, 15
D_H, D_R = 3, 7


def _row(name, ours_ms, ref_ms, notes):
    return {"name": name, "ours_ms": round(ours_ms, 4), "reference_ms": round(ref_ms, 4),
            "speedup": round(ref_ms / ours_ms, 1), "notes": notes}


def run(quick: bool = False, config=None) -> list[dict]:
    """The ProMP core has no library settings: ``config`` is ignored."""
    from movement_primitives.promp import ProMP

    rng = np.random.default_rng(0)
    repeats = 20 if quick else 200
    rows = []

    # (a) weights of one demonstration
    z = phases(T)
    Y = np.cumsum(rng.standard_normal((T, D)), axis=0) * 0.1 + np.sin(np.pi * z)[:, None]
    basis = GaussianBasis(N)
    ours = median_ms(lambda: ridge_weights(Y, basis), repeats)
    mp = ProMP(D, N)
    ref = median_ms(lambda: mp.weights(z.copy(), Y), max(5, repeats // 10))
    rows.append(_row("weights of one demo (T=150, D=10, N=15)", ours, ref,
                     "ours: cached (Phi^T Phi + rI)^-1 Phi^T, one N x N system for all dims; "
                     "reference: pinv of the (D N)^2 block system"))

    ours_z = median_ms(lambda: ridge_weights(Y, basis, z=z), repeats)
    rows.append(_row("weights of one demo, phases given (no cache)", ours_z, ref,
                     "ours: Phi computed and an N x N system solved on every call"))

    # (b) conditioning on a full 150-sample 3-D human trajectory
    p = InteractionProMP(D_H, D_R, basis_human=GaussianBasis(N), basis_robot=GaussianBasis(N),
                         observation_noise=0.01)
    n = p.n_weights
    A = rng.standard_normal((n, n))
    p.fit_weights(rng.standard_normal((3 * n, n)) @ A * 0.1 + rng.standard_normal(n))
    y_obs = Y[:, :D_H]
    ours = median_ms(lambda: p.condition(y_obs, z), repeats)

    # movement_primitives: one ProMP over all 10 dims (same weight layout), one call per point
    mp = ProMP(D, N).from_weight_distribution(p.mean_.copy(), p.cov_.copy())
    y_cov = np.diag([0.01] * D_H + [1e6] * D_R)
    y_full = np.concatenate([y_obs, np.zeros((T, D_R))], axis=1)
    n_calls = 10 if quick else 30

    def chained():
        q = mp
        for i in range(n_calls):
            q = q.condition_position(y_full[i], y_cov=y_cov, t=z[i], t_max=1.0)

    per_point = median_ms(chained, 3 if quick else 10) / n_calls
    rows.append(_row("condition on 150 human samples (3+7 dims, 15 basis)", ours, per_point * T,
                     f"reference: chained condition_position, {n_calls} calls timed, "
                     f"{per_point:.3f} ms per point x 150"))
    return rows
