"""SkillLibrary's own methods (``library.incremental``) where ``make mutate`` found changes no test noticed.

The expert covariances a large library keeps (at most 64, each equal to the formula),
the errors of ``shared_covariance`` and ``path_length`` as the user reads them, and
``path_length``'s ``normalized`` argument.
"""
import re

import numpy as np
import pytest

from drake_skills import LibraryConfig, Workspace

import library_states as ls
from synthetic import synthetic_demo

SMALL = dict(n_samples=30, n_basis_human=5, n_basis_robot=5)


def _many(K, cfg=None):
    """K hand-set components of distinct scatter on an isotropic scale (3 human, 7 robot dimensions)."""
    cfg = cfg or LibraryConfig(**SMALL)
    d = 10 * 5
    rng = np.random.default_rng(0)
    comps = [ls.component(k, rng.normal(0, 3, d), factor=rng.normal(0, 0.2, (d, 2)), support=2.0 + k % 5, age=3)
             for k in range(K)]
    return ls.library(cfg, comps, dim_human=3, dim_robot=7, n_seen=10), comps


def test_a_large_library_keeps_64_expert_covariances_and_each_is_the_formula():
    """70 components asked for in turn, then the first again: every covariance is (kappa Sigma + S_k) /
    (kappa + s_k - 1) (rtol 1e-12), read-only, and the cache holds exactly 64 (the oldest dropped first)."""
    lib, comps = _many(70)
    S = lib.shared_covariance("expert")
    kappa = lib.config.expert_prior
    items = lib._components.items
    for c, st in zip(items + items[:3], comps + comps[:3]):
        C = lib._expert_cov(c)
        F = st.cluster.factor
        expect = (kappa * S + F @ F.T) / (kappa + st.cluster.support - 1.0)
        np.testing.assert_allclose(C, expect, rtol=1e-12, atol=1e-14)
        assert not C.flags.writeable
    cache = lib._expert_cache[1]
    assert len(cache) == 64
    assert [v[0] for v in cache.values()][-3:] == [c.cluster for c in items[:3]]
    assert [v[0] for v in cache.values()][0] is items[9].cluster


def test_shared_covariance_names_the_parts_it_knows():
    lib, _ = _many(2)
    with pytest.raises(ValueError, match=r"^part must be 'gating' or 'expert', got 'robot'$"):
        lib.shared_covariance("robot")


def test_path_length_takes_normalized_input_as_it_is_and_names_the_motion_in_its_error():
    ws = Workspace(np.full(3, -6.0), np.full(3, 10.0))
    lib, _ = _many(2, LibraryConfig(**SMALL, workspace=ws))
    human = synthetic_demo(0, np.random.default_rng(1), T=30).human
    yn = ws.normalize(human)
    steps = np.linalg.norm(np.diff(yn, axis=0), axis=1)
    assert lib.path_length(yn, normalized=True) == lib.path_length(human)
    assert lib.path_length(human) == pytest.approx(steps.sum(), rel=0.05)   # the polyline through the vertices
    assert lib.path_length(yn, normalized=True) != lib.path_length(yn)
    with pytest.raises(ValueError, match="^" + re.escape("demo 'x': human trajectory does not move: its path "
                                                         "length is 0") + "$"):
        lib.path_length(np.ones((5, 3)), where="demo 'x'")
