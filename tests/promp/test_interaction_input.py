"""Interaction ProMP input validation not covered by test_interaction.py."""
import numpy as np
import pytest

from drake_skills.promp.basis import GaussianBasis
from drake_skills.promp.interaction import InteractionProMP


def _model():
    rng = np.random.default_rng(0)
    p = InteractionProMP(2, 1, basis_human=GaussianBasis(4), basis_robot=GaussianBasis(5))
    return p.fit_weights(rng.standard_normal((30, p.n_weights)))


def test_log_likelihood_human_rejects_bad_noise_and_floor():
    p = _model()
    y, z = np.zeros((3, 2)), [0.0, 0.5, 1.0]
    assert np.isfinite(p.log_likelihood_human(y, z)[0])
    with pytest.raises(ValueError, match="observation_noise"):
        p.log_likelihood_human(y, z, observation_noise=-1.0)
    with pytest.raises(ValueError, match="cov_floor"):
        p.log_likelihood_human(y, z, cov_floor=np.nan)
    with pytest.raises(ValueError, match="NaN"):
        p.log_likelihood_human(np.full((3, 2), np.nan), z)


def test_fit_and_moments_reject_bad_input():
    p = InteractionProMP(2, 1, basis_human=GaussianBasis(4), basis_robot=GaussianBasis(5))
    with pytest.raises(ValueError, match="at least one"):
        p.fit([])
    with pytest.raises(ValueError, match="2 human but 1 robot"):
        p.fit([np.zeros((10, 2))] * 2, [np.zeros((10, 1))])
    with pytest.raises(ValueError, match="robot trajectory has inf"):
        p.fit([np.zeros((10, 2))], [np.full((10, 1), np.inf)])
    with pytest.raises(ValueError, match=r"weights must have shape \(any, 13\)"):
        p.fit_weights(np.zeros((5, 12)))
    with pytest.raises(ValueError, match="covariance must have shape"):
        InteractionProMP.from_moments(np.zeros(13), np.eye(12), 2, 1, basis_human=GaussianBasis(4),
                                      basis_robot=GaussianBasis(5))
    with pytest.raises(ValueError, match="dim_human"):
        InteractionProMP(0)
    with pytest.raises(ValueError, match="observation_noise"):
        InteractionProMP(2, observation_noise=0.0)
    with pytest.raises(ValueError, match="too short"):
        _model().condition_prefix(np.zeros((1, 2)), 0.5)
    with pytest.raises(ValueError, match="no robot part"):
        InteractionProMP(2).fit_weights(np.zeros((3, 20))).robot_distribution()
