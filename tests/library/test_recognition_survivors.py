"""Prefix recognition where ``make mutate`` found it untested: the pruning bound under a strong ridge, and the
number of samples a beginning is resampled to when the components disagree on how much of them it covers.

Human-only libraries built by hand (``library_states``), a constant-speed probe path in normalized units; the
references are written out here: the band, the per-phase ``prefix_statistics`` and their average, as in
``test_recognition_mutants.py``.
"""
import numpy as np
import pytest
from scipy.special import logsumexp

from drake_skills import LibraryConfig
from drake_skills.library import recognition
from drake_skills.promp.basis import ridge_weights
from drake_skills.promp.interaction import prefix_statistics
from drake_skills.promp.preprocessing import arc_length, resample_by_arc_length

import library_states as ls
from brute_force import unshrink

GRID = np.round(np.arange(1, 21) / 20.0, 6)
BAND = 1.5


def _probe():
    z = np.linspace(0.0, 1.0, 400)
    return np.stack([6 * z, 3 * np.sin(np.pi * z), 2 * z ** 2], axis=1)


def _library(cfg, offsets, path_factors, var):
    """Component k: the probe's ridge weights plus ``offsets[k]`` in every weight, path length ``path_factors[k]``
    times the probe's; a shared gating covariance ``var I``."""
    yn = _probe()
    h = 3 * cfg.n_basis_human
    w = ridge_weights(resample_by_arc_length(yn, cfg.n_samples, cfg.resample_tolerance), cfg.basis_human, cfg.ridge)
    L = arc_length(yn, cfg.resample_tolerance)[1][-1]
    comps = [ls.component(k, w + off, support=10, age=10, path_length=L * f)
             for k, (off, f) in enumerate(zip(offsets, path_factors))]
    return ls.library(cfg, comps, dim_human=3, dim_robot=0, scale=ls.iso_scale(h, var), n_seen=30), yn, L


@pytest.mark.parametrize("fraction", [0.6, 1.0])
def test_a_strong_ridge_does_not_let_the_pruning_bound_rule_out_the_skill_a_beginning_lies_on(fraction, monkeypatch):
    """ridge 10: the library's weights are far shrunk from the least-squares weights the samples see. The bound
    must compare the samples with the same S^-1 mu as the scoring (with Phi mu it rules the skill out and the
    answer is "unknown"): pruned and unpruned, the beginning is skill 0, with the same statistics (rtol 1e-12)."""
    lib, yn, _ = _library(LibraryConfig(shrinkage=0.0, ridge=10.0), (0.0, 5.0), (1.0, 1.0), var=1e-2)
    part = yn[:int(len(yn) * fraction)]
    monkeypatch.setattr(recognition, "PRUNE_MIN_COMPONENTS", 10 ** 9)
    full = lib.recognize(part, normalized=True)
    monkeypatch.setattr(recognition, "PRUNE_MIN_COMPONENTS", 0)
    pruned = lib.recognize(part, normalized=True)
    assert full.status == pruned.status == "skill" and full.component == pruned.component == 0
    assert full.mahalanobis_sq[0] < 0.2 * recognition.chi2_ppf(lib.config.novelty_quantile, int(full.dof[0]))
    np.testing.assert_allclose(pruned.log_likelihoods[0], full.log_likelihoods[0], rtol=1e-12)
    np.testing.assert_allclose(pruned.mahalanobis_sq[0], full.mahalanobis_sq[0], rtol=1e-12, atol=1e-12)


def _reference_scores(lib, yn, n):
    """Per component: the band-averaged log-likelihood and the phase of highest likelihood, on ``n`` samples."""
    cfg, h = lib.config, lib.n_human
    U = unshrink(cfg, h)
    G, noise = U @ lib.shared_covariance("gating") @ U.T, lib.observation_noise()
    ys = resample_by_arc_length(yn, n, cfg.resample_tolerance)
    length = arc_length(yn, cfg.resample_tolerance)[1][-1]
    logp, phases = [], []
    for c in lib.state().components:
        g = min(max(length / c.cluster.path_length, GRID[0]), 1.0)
        band = sorted({f for f in GRID if g / BAND - 1e-12 <= f <= min(g * BAND, 1.0) + 1e-12}
                      | {GRID[np.abs(GRID - g).argmin()]})
        ll = [prefix_statistics(U @ c.cluster.mean[:h], G * (1.0 + 1.0 / c.cluster.support),
                                cfg.basis_human.phi(np.linspace(0.0, f, n)), ys, noise)[0] for f in band]
        logp.append(logsumexp(ll) - np.log(len(band)))
        phases.append(band[int(np.argmax(ll))])
    return np.array(logp), np.array(phases)


def test_a_beginning_is_resampled_by_the_median_over_components_of_the_fraction_each_sees_capped_at_1():
    """Two components: the probe covers half of the first's path and 1.25 times the second's, which sees all of
    it (fraction 1). The median of (0.5, 1) is 0.75: 75 of 100 samples, not 90 (the median of 0.5 and 1.25). The
    log-likelihoods are those of the reference on 75 samples (rtol 1e-9) and differ from those on 90 by far more."""
    lib, yn, _ = _library(LibraryConfig(), (0.0, 0.05), (2.0, 0.8), var=1e-2)
    rec = lib.recognize(yn, normalized=True)
    logp, phases = _reference_scores(lib, yn, 75)
    np.testing.assert_allclose(rec.log_likelihoods, logp, rtol=1e-9)
    np.testing.assert_array_equal(rec.phases, phases)
    other, _ = _reference_scores(lib, yn, 90)
    assert np.abs(other - logp).min() > 1.0
