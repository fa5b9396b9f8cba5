"""benchmarks/own_scatter.py (the experiment behind RESULTS.md's "A component's own scatter as its scale"): its
widened distance is the one the covariance it describes gives, and the library is restored after it."""

import numpy as np

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.data.synthetic import skill_bank
from drake_skills.library import algorithm, recognition
from drake_skills.promp.basis import ridge_weights

from bench_scripts import load


def _script():
    return load("own_scatter")


def _library():
    bank = skill_bank(3, 0, separation=3.0)
    rng = np.random.default_rng(4)
    lib = SkillLibrary(LibraryConfig())
    for _ in range(4):
        for k in range(3):
            lib.partial_fit(bank.demo(k, rng, scatter=0.3 if k == 0 else 0.01))
    return lib, bank, rng


def test_widened_distance_is_that_of_the_larger_of_the_shared_and_the_own_covariance_per_direction():
    m = _script()
    lib, bank, rng = _library()
    comps, metric, h = lib._components, lib._metric(), lib.n_human
    kappa = lib.config.expert_prior
    w = ridge_weights(lib.human_samples(bank.demo(0, rng).human), lib.config.basis_human, lib.config.ridge)
    logp, d2 = m._widened_scores(kappa)(w, comps, metric)
    logp0, d20 = algorithm.gating_scores(w, comps, metric)
    widened_any = False
    for k, c in enumerate(comps.items):
        Z = metric.inv_chol @ c.cluster.factor[:h]
        E = (kappa * np.eye(h) + Z @ Z.T) / (kappa + c.support - 1.0)
        lam, U = np.linalg.eigh(E)
        C = (U * np.maximum(lam, 1.0)) @ U.T * (1.0 + 1.0 / c.support)   # whitened, predictive
        dz = metric.whiten(c.mean[:h]) - metric.whiten(w)
        expected = dz @ np.linalg.solve(C, dz)
        np.testing.assert_allclose(d2[k], expected, rtol=1e-9)
        np.testing.assert_allclose(logp[k] - logp0[k], -0.5 * (np.sum(np.log(np.maximum(lam, 1.0))) + d2[k] - d20[k]),
                                   rtol=1e-9, atol=1e-9)
        assert d2[k] <= d20[k] * (1 + 1e-12)    # it only widens
        widened_any |= bool(np.any(lam > 1.0))
    assert widened_any                           # the wide skill spreads beyond the shared scale somewhere


def test_the_variant_is_patched_in_only_within_its_context():
    m = _script()
    before = algorithm.gating_scores, recognition.gating_scores
    with m.variant("own scatter", 1.0):
        assert algorithm.gating_scores is not before[0] and recognition.gating_scores is algorithm.gating_scores
    assert (algorithm.gating_scores, recognition.gating_scores) == before
    with m.variant("shared", 1.0):
        assert (algorithm.gating_scores, recognition.gating_scores) == before
