"""Beginnings are compared with the least-squares weights: the ridge's shrinkage is not misfit.

The library's weights are ridge estimates, ``w = S w_ls`` with ``S = (Phi^T Phi + beta
I)^-1 Phi^T Phi`` over the ``n_samples`` phases of a whole motion; the samples of a motion
lie around ``Phi w_ls``. Before the fix a beginning's samples were compared with ``Phi mu``,
so the shrinkage counted as misfit: a whole taught motion recognized without a fraction got
d^2 53 against a threshold of 47 and was "unknown".
"""
import warnings

import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.data.synthetic import skill_bank
from drake_skills.library.novelty import chi2_ppf


def _taught(seed=0, **cfg):
    rng = np.random.default_rng(seed)
    bank = skill_bank(4, rng)
    lib = SkillLibrary(LibraryConfig(**cfg))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # synthetic paths in normalized units, no workspace
        for k in (0, 1, 2, 3) * 3:
            lib.partial_fit(bank.demo(k, rng))
    return lib, bank, rng


def test_a_whole_taught_motion_recognized_as_a_beginning_fits_its_skill():
    lib, bank, rng = _taught()
    human = bank.demo(0, rng).human
    whole = lib.recognize(human, observed_fraction=1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = lib.recognize(human)                      # phase estimated
    k = list(rec.ids).index(whole.component)
    assert rec.status == "skill" and rec.component == whole.component
    assert rec.phases[k] == pytest.approx(1.0, abs=0.05)
    # far inside the threshold (it was 52.9 against 46.8 with the ridge weights as they are)
    assert rec.mahalanobis_sq[k] < 0.1 * chi2_ppf(lib.config.novelty_quantile, int(rec.dof[k]))


def test_without_a_ridge_the_prefix_model_is_the_library_itself():
    lib, _, _ = _taught(ridge=0.0)
    pm = lib._prefix_model()
    np.testing.assert_allclose(pm.unshrink, np.eye(lib.n_human), rtol=0, atol=1e-8)
    np.testing.assert_allclose(pm.means_h, lib._components.means_h, rtol=1e-8, atol=1e-8)


def test_the_prefix_model_maps_ridge_weights_to_least_squares_weights():
    """``S^-1`` applied to a motion's ridge weights gives its least-squares weights (to 1e-8)."""
    lib, bank, rng = _taught()
    cfg = lib.config
    y = lib.human_samples(bank.demo(2, rng).human)
    Phi = cfg.basis_human.phi_uniform(cfg.n_samples)
    w_ls = np.linalg.lstsq(Phi, y, rcond=None)[0].T.reshape(-1)
    w_ridge = np.linalg.solve(Phi.T @ Phi + cfg.ridge * np.eye(Phi.shape[1]), Phi.T @ y).T.reshape(-1)
    np.testing.assert_allclose(lib._prefix_model().unshrink @ w_ridge, w_ls, rtol=1e-8, atol=1e-8)


def test_fewer_samples_than_basis_functions_still_give_finite_answers():
    """n_samples < n_basis_human: Phi^T Phi is singular, S is inverted where it can be (pinv)."""
    lib, bank, rng = _taught(n_samples=4, n_basis_human=10)
    human = bank.demo(1, rng).human
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = lib.recognize(human[: len(human) // 2])
        mean, cov = lib.predict_robot(human[: len(human) // 2], component=lib.components[0].id)
    assert np.isfinite(rec.mahalanobis_sq).all() and np.isfinite(rec.log_likelihoods).all()
    assert np.isfinite(mean).all() and np.isfinite(cov).all()
