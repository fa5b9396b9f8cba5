"""The prefix test is calibrated: under the model its statistic is chi-square with the dof it reports.

Recognition from a beginning (``library.prefix.score_phases`` and its reference
``promp.interaction.prefix_statistics``) calls a component novel when ``d2`` exceeds
the chi-square quantile at ``dof``. If ``dof`` is too small, the right skill is
rejected far more often than ``1 - novelty_quantile`` (it was: about 8 % at the 0.999
quantile for a prefix of 10-50 %, with ``dof`` the effective number of weight
directions observed). Samples drawn exactly from a component's predictive
distribution must be rejected at the nominal rate. (Since 2026-12-01 the statistic
counts only the directions of the weights the samples see well; it stays exact.)
"""
import numpy as np
import pytest

from drake_skills.library.config import LibraryConfig
from drake_skills.library.novelty import chi2_ppf
from drake_skills.library.prefix import score_phases
from drake_skills.promp.interaction import SEEN_RCOND, prefix_statistics

D, N = 3, 7
H = D * N
DRAWS = 1000


def _model(seed=0):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(H, H))
    cov = 0.05 * (A @ A.T / H + 0.5 * np.eye(H))
    return rng, rng.normal(size=H), np.linalg.cholesky(cov)


@pytest.mark.parametrize("f, m", [(0.1, 10), (0.3, 30), (0.5, 50), (1.0, 100), (0.3, 5)])
def test_prefix_d2_is_chi_square_with_the_reported_dof(f, m):
    """Mean d2 within 3 standard errors of dof (sqrt(2 dof / DRAWS) each), and the 0.99 quantile rejects 1 % within 3
    standard errors (sqrt(0.01 * 0.99 / DRAWS): +- 0.94 % at 1000 draws)."""
    basis = LibraryConfig().basis_human
    rng, mu, L = _model()
    noise = 0.002
    Phi = basis.phi(np.linspace(0.0, f, m))
    d2s = np.empty(DRAWS)
    for i in range(DRAWS):
        w = mu + L @ rng.normal(size=H)
        y = Phi @ w.reshape(D, N).T + np.sqrt(noise) * rng.normal(size=(m, D))
        _, d2, dof = score_phases(y, (f,), mu[None], np.ones(1), L, basis, noise)
        d2s[i], k = d2[0, 0], dof[0, 0]
    assert abs(d2s.mean() - k) <= 3.0 * np.sqrt(2.0 * k / DRAWS), (d2s.mean(), k)
    rate = np.mean(d2s > chi2_ppf(0.99, k))
    assert abs(rate - 0.01) <= 3.0 * np.sqrt(0.01 * 0.99 / DRAWS), rate
    # the reference agrees on the dof: D times the directions the samples see well (eigenvalues
    # of Phi^T Phi at least SEEN_RCOND of the largest)
    _, _, dof_ref = prefix_statistics(mu, L @ L.T, Phi, y, noise)
    assert dof_ref == pytest.approx(k, abs=1e-9)
    g = np.linalg.eigvalsh(Phi.T @ Phi)
    assert k == D * np.sum(g >= SEEN_RCOND * g[-1]) and 1 <= k <= D * min(m, N)
