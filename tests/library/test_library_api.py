"""SkillLibrary's public surface: configuration, views, workspaces, input checks (with the messages a
user sees), deletion, and predictions against a direct computation of Eq. (13)."""
import re

import numpy as np
import pytest

from drake_skills import Demonstration, InteractionProMP, LibraryConfig, SkillLibrary
from drake_skills.promp.basis import GaussianBasis
from drake_skills.promp.gaussian import condition_gaussian
from drake_skills.promp.preprocessing import Workspace, resample_by_arc_length

import library_states as ls
from synthetic import synthetic_demo

SMALL = dict(n_samples=30, n_basis_human=5, n_basis_robot=5)


def _raises(message, fn, *a, exc=ValueError, **k):
    with pytest.raises(exc, match="^" + re.escape(message)):
        fn(*a, **k)


def _lib(n=6, tasks=(0, 1), robot=True, seed=0, **cfg):
    rng = np.random.default_rng(seed)
    lib = SkillLibrary(LibraryConfig(**{**SMALL, **cfg}))
    for i in range(n):
        lib.partial_fit(synthetic_demo(tasks[i % len(tasks)], rng, T=30, robot=robot))
    return lib


# ------------------------------------------------------------------------------ configuration
def test_config_integer_fields_and_their_bounds():
    cfg = LibraryConfig(n_samples=4.0, n_basis_human=2, n_basis_robot=2, merge_min_age=0, delete_min_age=0)
    assert (cfg.n_samples, cfg.n_basis_human, cfg.n_basis_robot, cfg.merge_min_age, cfg.delete_min_age) == (4, 2, 2, 0, 0)
    assert type(cfg.n_samples) is int
    for name, lo in [("merge_min_age", 0), ("delete_min_age", 0)]:
        _raises(f"LibraryConfig.{name} must be an integer >= {lo}, got {lo - 1}", LibraryConfig, **{name: lo - 1})
        _raises(f"LibraryConfig.{name} must be an integer >= {lo}, got {lo + 0.5}", LibraryConfig,
                **{name: lo + 0.5})
    # sizes have an upper bound too: a typo or a corrupt file's metadata must not ask for gigabytes
    for name, lo, hi in [("n_samples", 4, 100_000), ("n_basis_human", 2, 200), ("n_basis_robot", 2, 200)]:
        for bad in (lo - 1, lo + 0.5, hi + 1, 10**12):
            _raises(f"LibraryConfig.{name} must be an integer in {lo}..{hi}, got {bad}", LibraryConfig, **{name: bad})
        assert getattr(LibraryConfig(**{name: hi}), name) == hi


@pytest.mark.parametrize("name", ["basis_width", "prior_scale", "prior_strength", "expert_prior",
                                  "observation_noise"])
def test_config_positive_fields(name):
    _raises(f"LibraryConfig.{name} must be positive, got 0.0", LibraryConfig, **{name: 0.0})
    _raises(f"LibraryConfig.{name} must be positive, got nan", LibraryConfig, **{name: float("nan")})
    _raises(f"LibraryConfig.{name} must be positive, got inf", LibraryConfig, **{name: float("inf")})
    assert getattr(LibraryConfig(**{name: 1e-3}), name) == 1e-3


@pytest.mark.parametrize("name", ["ridge", "consolidation", "delete_min_support", "resample_tolerance", "prior_floor"])
def test_config_non_negative_fields(name):
    assert getattr(LibraryConfig(**{name: 0.0}), name) == 0.0
    _raises(f"LibraryConfig.{name} must be >= 0, got -0.1", LibraryConfig, **{name: -0.1})
    _raises(f"LibraryConfig.{name} must be >= 0, got inf", LibraryConfig, **{name: float("inf")})
    _raises(f"LibraryConfig.{name} must be >= 0, got nan", LibraryConfig, **{name: float("nan")})


@pytest.mark.parametrize("name", ["novelty_quantile", "merge_quantile", "split_quantile", "decision_risk"])
def test_config_quantiles_lie_strictly_between_0_and_1(name):
    for bad in (0.0, 1.0, -0.5):
        _raises(f"LibraryConfig.{name} must be in (0, 1), got {bad!r}", LibraryConfig, **{name: bad})
    small = dict(merge_quantile=1e-6) if name == "split_quantile" else {}
    assert getattr(LibraryConfig(**{name: 2e-6, **small}), name) == 2e-6


def test_config_shrinkage_split_above_merge_and_retired_fields():
    for bad in (-0.1, 1.0):
        _raises(f"LibraryConfig.shrinkage must be in [0, 1), got {bad!r}", LibraryConfig, shrinkage=bad)
    assert LibraryConfig(shrinkage=0.0).shrinkage == 0.0
    _raises("LibraryConfig.split_quantile (0.99) must be above merge_quantile (0.99), or a merge would be split "
            "again at once", LibraryConfig, merge_quantile=0.99, split_quantile=0.99)
    _raises("LibraryConfig fields ['gating_floor'] are gone: the novelty scale is now learned", LibraryConfig.from_dict,
            {"gating_floor": 1.0, "ridge": 0.1})


def test_config_novelty_test_workspace_and_dict_round_trip():
    _raises("LibraryConfig.novelty_test must be one of ('chi2', 'loglik'), got 'magic'", LibraryConfig,
            novelty_test="magic")
    ws = Workspace([0.0, 0.0, 0.0], [1.0, 2.0, 3.0])
    cfg = LibraryConfig(workspace=ws.dict(), n_basis_human=7)  # a dict (from YAML) becomes a Workspace
    assert isinstance(cfg.workspace, Workspace) and cfg.workspace.dict() == ws.dict()
    assert LibraryConfig(workspace=ws).workspace is ws
    d = cfg.dict()
    assert d["workspace"] == ws.dict() and d["n_basis_human"] == 7 and LibraryConfig().dict()["workspace"] is None
    back = LibraryConfig.from_dict(d)
    assert back.workspace.dict() == ws.dict() and back.n_basis_human == 7
    _raises("unknown LibraryConfig fields: ['a', 'b']", LibraryConfig.from_dict, {"b": 1, "a": 2, "ridge": 0.1})
    assert cfg.basis_human == GaussianBasis(7, 1.0, True)
    assert LibraryConfig(n_basis_robot=9, basis_width=2.0, basis_normalized=False).basis_robot == GaussianBasis(9, 2.0)


def test_library_takes_only_a_library_config():
    _raises("config must be a LibraryConfig, got dict", SkillLibrary, {"ridge": 0.1})
    assert SkillLibrary().config == LibraryConfig()
    cfg = LibraryConfig(ridge=0.1)
    assert SkillLibrary(cfg).config == cfg and SkillLibrary(cfg).config is not cfg  # a sealed copy


# ------------------------------------------------------------------------------ views
def test_new_library_is_empty_and_not_fitted():
    lib = SkillLibrary()
    assert lib.n_components == 0 and lib.n_seen == 0 and lib.components == () and lib.history == ()
    assert lib.dim_human_ is None and lib.dim_robot_ is None and not lib.has_robot
    assert repr(lib) == "SkillLibrary(n_components=0, n_seen=0)"
    msg = "this SkillLibrary is not fitted yet: call partial_fit() with a demonstration first"
    for fn in (lambda: lib.n_human, lambda: lib.recognize(np.eye(3)), lambda: lib.predict_robot(np.eye(3)),
               lambda: lib.as_mixture()):
        _raises(msg, fn)


def test_component_views_ids_weights_and_lookup():
    lib = _lib(n=6, tasks=(0, 1, 2))
    assert repr(lib) == "SkillLibrary(n_components=3, n_seen=6)"
    comps = lib.components
    assert [c.id for c in comps] == [0, 1, 2] and [c.age for c in comps] == [6, 5, 4]
    total = sum(c.support for c in comps)
    assert [c.weight for c in comps] == pytest.approx([c.support / total for c in comps], rel=1e-12)
    c1 = lib.component(1)
    assert c1.id == 1 and c1.n_human == 15
    np.testing.assert_array_equal(c1.mean_gating, c1.mean[:15])
    np.testing.assert_allclose(c1.cov_gating, lib.shared_covariance() * (1 + 1 / c1.support), rtol=1e-12)
    np.testing.assert_array_equal(c1.cov, lib.as_mixture("expert")[2][1])
    assert c1.cov.flags.writeable is False and c1.mean.flags.writeable is False
    _raises("'no component with id 9; ids are [0, 1, 2]'", lib.component, 9, exc=KeyError)
    _raises("'no component with id 9; ids are [0, 1, 2]'", lib.predict_robot, np.eye(3), component=9, exc=KeyError)
    for bad in ("0", True, 1.0):   # a cold review found True taken as component 1
        _raises(repr(f"component ids are integers, got {bad!r}; ids are [0, 1, 2]"), lib.predict_robot, np.eye(3),
                component=bad, exc=KeyError)
    history = lib.history
    history[0]["event"] = "changed"  # a copy: the library's history is not touched
    assert lib.history[0]["event"] == "created"


def test_as_mixture_gives_the_gating_and_the_expert_mixtures():
    lib = _lib(n=6, tasks=(0, 1, 2))
    w, means, covs = lib.as_mixture()
    comps = lib.components
    s = np.array([c.support for c in comps])
    np.testing.assert_allclose(w, s / s.sum(), rtol=1e-12)
    assert means.shape == (3, 15) and covs.shape == (3, 15, 15)
    np.testing.assert_allclose(covs[2], lib.shared_covariance() * (1 + 1 / comps[2].support), rtol=1e-12)
    w2, means2, covs2 = lib.as_mixture("expert")
    np.testing.assert_array_equal(w2, w)
    assert means2.shape == (3, 50) and covs2.shape == (3, 50, 50)
    np.testing.assert_array_equal(means2[1], comps[1].mean)
    _raises("part must be 'gating' or 'expert', got 'robot'", lib.as_mixture, "robot")


def test_as_mixture_of_a_single_component():
    lib = _lib(n=1)
    w, means, covs = lib.as_mixture("expert")
    assert w.tolist() == [1.0] and means.shape == (1, 50) and covs.shape == (1, 50, 50)


def test_as_mixture_of_a_library_whose_components_were_all_deleted(tmp_path):
    lib = ls.library(LibraryConfig(**SMALL), [], dim_human=3, dim_robot=7, next_id=3)
    _raises("the library has no components", lib.as_mixture)


def test_interaction_promp_of_a_component_is_a_copy_with_the_library_settings():
    lib = _lib(n=4, observation_noise=0.07, ridge=1e-4)
    c = lib.component(1)
    ip = lib.interaction_promp(1)
    assert isinstance(ip, InteractionProMP)
    assert (ip.dim_human, ip.dim_robot, ip.ridge, ip.observation_noise) == (3, 7, 1e-4, 0.07)
    assert ip.basis_human == lib.config.basis_human and ip.basis_robot == lib.config.basis_robot
    np.testing.assert_array_equal(ip.mean_, c.mean)
    np.testing.assert_allclose(ip.cov_, c.cov, rtol=0, atol=1e-15)
    ip.mean_[0] = 99.0
    assert lib.component(1).mean[0] != 99.0


def test_fit_resets_then_folds_in_the_demonstrations_in_order():
    rng = np.random.default_rng(1)
    demos = [synthetic_demo(i % 2, rng, T=30) for i in range(5)]
    cfg = LibraryConfig(**SMALL)
    a = SkillLibrary(cfg)
    a.partial_fit(synthetic_demo(3, rng, T=30))
    assert a.fit(demos) is a
    b = SkillLibrary(cfg)
    for d in demos:
        b.partial_fit(d)
    assert a.n_seen == 5 and a.history == b.history
    for x, y in zip(a.components, b.components):
        np.testing.assert_array_equal(x.mean, y.mean)
    ws = Workspace([-10.0, -10.0, -10.0], [10.0, 10.0, 10.0])
    c = SkillLibrary(LibraryConfig(**SMALL, resample_tolerance=0.0)).fit(demos, workspace=ws)
    a = SkillLibrary(LibraryConfig(**SMALL, resample_tolerance=0.0)).fit(demos)
    np.testing.assert_allclose(c.components[0].mean[:15], 0.5 * a.components[0].mean[:15], rtol=1e-9, atol=1e-12)


# ------------------------------------------------------------------------------ workspaces
def test_partial_fit_and_recognize_use_the_workspace_argument_over_the_config():
    """Raw positions with a workspace give the weights of the normalized positions without one."""
    rng = np.random.default_rng(2)
    demo = synthetic_demo(1, rng, T=30)
    lo, hi = np.array([-1.0, 2.0, 0.5]), np.array([3.0, 4.0, 1.5])
    ws = Workspace(lo, hi)
    raw = Demonstration(t=demo.t, human=lo + demo.human * (hi - lo) / 10.0, robot=demo.robot)
    plain = SkillLibrary(LibraryConfig(**SMALL))
    plain.partial_fit(demo)
    given = SkillLibrary(LibraryConfig(**SMALL))
    given.partial_fit(raw, workspace=ws)
    in_config = SkillLibrary(LibraryConfig(**SMALL, workspace=ws))
    in_config.partial_fit(raw)
    overridden = SkillLibrary(LibraryConfig(**SMALL, workspace=Workspace(lo, hi + 5.0)))
    overridden.partial_fit(raw, workspace=ws)
    for lib in (given, in_config, overridden):
        np.testing.assert_allclose(lib.components[0].mean, plain.components[0].mean, rtol=1e-9, atol=1e-9)
    raw_without = SkillLibrary(LibraryConfig(**SMALL))
    raw_without.partial_fit(raw)
    assert not np.allclose(raw_without.components[0].mean[:15], plain.components[0].mean[:15], atol=0.1)
    np.testing.assert_allclose(given.recognize(raw.human, workspace=ws).mahalanobis_sq,
                               plain.recognize(demo.human).mahalanobis_sq, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(given.predict_robot(raw.human, workspace=ws)[0], plain.predict_robot(demo.human)[0],
                               rtol=1e-6, atol=1e-9)


def test_workspace_must_match_the_human_dimensions():
    lib = _lib(n=2)
    human = synthetic_demo(0, np.random.default_rng(3), T=30).human
    _raises("workspace is 2-D but human has 3 columns", lib.recognize, human, workspace=Workspace([0, 0], [1, 1]))
    _raises("workspace must be a Workspace, got dict", lib.recognize, human, workspace={"lower": [0, 0, 0]})
    _raises("workspace must be a Workspace, got dict", lib.partial_fit, synthetic_demo(0, np.random.default_rng(3)),
            workspace={"lower": [0, 0, 0]})


# ------------------------------------------------------------------------------ input checks
def test_recognize_input_messages():
    lib = _lib(n=2)
    human = synthetic_demo(0, np.random.default_rng(4), T=30).human
    bad = human.copy()
    bad[3:5] = np.nan
    _raises("human has NaN at rows 3..4", lib.recognize, bad)
    _raises("human has 2 columns, the library was built on 3", lib.recognize, human[:, :2])
    _raises("human must have 2 dimension(s), got shape (30,)", lib.recognize, human[:, 0])
    _raises("human is too short: 1 sample(s), need at least 2", lib.recognize, human[:1])
    _raises("human trajectory does not move: its path length is 0", lib.recognize, np.ones((5, 3)))
    for f in (0.0, 1.5, -0.2, "a", True, float("nan"), [0.5]):
        _raises(f"observed_fraction must be a number in (0, 1], got {f!r}", lib.recognize, human, observed_fraction=f)
        _raises(f"observed_fraction must be a number in (0, 1], got {f!r}", lib.predict_robot, human, f)
    assert lib.recognize(human[:2]).status in ("skill", "undecided", "unknown")  # two samples are enough
    assert lib.recognize(human, observed_fraction=1).dof == 15
    assert lib.recognize(human, observed_fraction=1).component == lib.recognize(human).component


def test_partial_fit_input_messages_name_the_demonstration():
    lib = _lib(n=2)
    rng = np.random.default_rng(5)
    good = synthetic_demo(0, rng, T=30)
    _raises("partial_fit takes a Demonstration, got ndarray", lib.partial_fit, good.human)
    _raises("demo 'x.npz': human has 2 columns, the library has 3", lib.partial_fit,
            Demonstration(t=good.t, human=good.human[:, :2], robot=good.robot, name="x.npz"))
    _raises("demonstration: human has 2 columns, the library has 3", lib.partial_fit,
            Demonstration(t=good.t, human=good.human[:, :2], robot=good.robot))
    _raises("demo 'x.npz': has no robot, the library has 7 robot joints", lib.partial_fit,
            Demonstration(t=good.t, human=good.human, name="x.npz"))
    _raises("demo 'x.npz': has 6 robot columns, the library has 7 robot joints", lib.partial_fit,
            Demonstration(t=good.t, human=good.human, robot=good.robot[:, :6], name="x.npz"))
    _raises("demo 'x.npz': human trajectory does not move: its path length is 0", lib.partial_fit,
            Demonstration(t=good.t, human=np.zeros((30, 3)), robot=good.robot, name="x.npz"))
    human_only = _lib(n=2, robot=False)
    _raises("demo 'y': has 7 robot columns, the library has no robot", human_only.partial_fit,
            Demonstration(t=good.t, human=good.human, robot=good.robot, name="y"))
    assert lib.n_seen == 2 and human_only.n_seen == 2


def test_first_demonstration_sets_the_dimensions():
    lib = SkillLibrary(LibraryConfig(**SMALL))
    rng = np.random.default_rng(6)
    d = synthetic_demo(0, rng, T=30)
    two = Demonstration(t=d.t, human=d.human[:, :2], robot=d.robot[:, :4])
    lib.partial_fit(two)
    assert (lib.dim_human_, lib.dim_robot_, lib.n_human, lib.has_robot) == (2, 4, 10, True)
    assert lib.components[0].mean.shape == (10 + 20,)
    h_only = SkillLibrary(LibraryConfig(**SMALL))
    h_only.partial_fit(Demonstration(t=d.t, human=d.human))
    assert (h_only.dim_human_, h_only.dim_robot_, h_only.has_robot) == (3, 0, False)
    _raises("this library was learned from human-only demonstrations: it has no robot part", h_only.predict_robot,
            d.human)


# ------------------------------------------------------------------------------ learning
def test_one_skill_library_holds_the_exact_running_moments():
    """K = 1, responsibility 1 every time: mean = average weight, scatter = sum of squared deviations, support n,
    age n, duration and path length their means (Eqs. 6-8, exact); the expert covariance is
    (kappa Sigma + S) / (kappa + n - 1) and the shared scale pooled the same scatter."""
    cfg = LibraryConfig(**SMALL, prior_floor=3.0)
    rng = np.random.default_rng(7)
    demos = [synthetic_demo(0, rng, T=30, noise=0.05, scale=s) for s in (1.0, 1.3, 0.8, 1.1, 0.9)]
    lib = SkillLibrary(cfg)
    for d in demos:
        lib.partial_fit(d)
    assert lib.n_components == 1
    W = np.stack([ls.encode(cfg, d) for d in demos])
    c = lib.components[0]
    st = lib.state()
    mean = W.mean(0)
    S = (W - mean).T @ (W - mean)
    np.testing.assert_allclose(c.mean, mean, rtol=0, atol=1e-10)
    np.testing.assert_allclose(st.components[0].cluster.scatter, S, rtol=0, atol=1e-10)
    np.testing.assert_allclose(st.scale.pooled, S, rtol=0, atol=1e-10)
    assert st.scale.dof == pytest.approx(4.0, abs=1e-12) and st.scale.n == 5
    np.testing.assert_allclose(st.scale.total_mean, mean, rtol=0, atol=1e-10)
    np.testing.assert_allclose(st.scale.total_m2, np.diag(S), rtol=0, atol=1e-10)
    np.testing.assert_allclose(c.cov, (lib.shared_covariance("expert") + S) / (1.0 + 4.0), rtol=1e-10, atol=1e-12)
    assert c.support == pytest.approx(5.0, abs=1e-12) and c.age == 5
    assert c.duration == pytest.approx(np.mean([d.duration for d in demos]), rel=1e-12)
    assert c.path_length == pytest.approx(np.mean([lib.path_length(d.human) for d in demos]), rel=1e-12)





def test_new_component_starts_at_the_demonstration_with_the_shared_covariance():
    cfg = LibraryConfig(**SMALL)
    rng = np.random.default_rng(9)
    lib = SkillLibrary(cfg)
    d = synthetic_demo(2, rng, T=30, scale=1.5)
    u = lib.partial_fit(d)
    assert u == type(u)(0, None, created=(0,))
    c = lib.components[0]
    np.testing.assert_array_equal(c.mean, ls.encode(cfg, d))
    np.testing.assert_allclose(c.cov, lib.shared_covariance("expert"), rtol=1e-12, atol=0)
    assert (c.support, c.age, c.duration) == (1.0, 1, pytest.approx(1.8))
    assert lib.history == ({"event": "created", "id": 0, "demo": 0},)
    u = lib.partial_fit(synthetic_demo(0, rng, T=30))
    assert u.demo_index == 1 and u.created == (1,) and lib.components[0].age == 2  # the others age too


@pytest.mark.parametrize("support, deleted", [(1.5, True), (1.5 + 1e-9, False)])
def test_component_past_its_deletion_age_is_deleted_at_the_minimum_support(support, deleted):
    """delete_min_age 30 (K = 2 <= 5: not scaled), delete_min_support 1.5: a component aged 31 with support <= 1.5
    is deleted, and its scatter and degrees of freedom leave the shared scale."""
    cfg = LibraryConfig(**SMALL)
    rng = np.random.default_rng(10)
    far = synthetic_demo(3, rng, T=30)
    w = ls.encode(cfg, synthetic_demo(0, rng, T=30))
    F = 0.1 * rng.standard_normal((50, 2))
    lib = ls.library(cfg, [ls.component(4, w, factor=F, support=support, age=30)], dim_human=3, dim_robot=7,
                     n_seen=40)
    before = lib.state().scale
    u = lib.partial_fit(far)  # novel: creates 5, ages 4 to 31
    assert u.created == (5,)
    assert u.deleted == ((4,) if deleted else ())
    assert [c.id for c in lib.components] == ([5] if deleted else [4, 5])
    after = lib.state().scale
    if deleted:
        assert lib.history[-1] == {"event": "deleted", "id": 4, "demo": 40, "age": 31, "support": 1.5}
        np.testing.assert_allclose(after.pooled, before.pooled - F @ F.T, rtol=1e-12, atol=1e-6)
        assert after.dof == pytest.approx(before.dof - 0.5, abs=1e-9)
    else:
        np.testing.assert_array_equal(after.pooled, before.pooled)


def test_young_component_is_not_deleted():
    cfg = LibraryConfig(**SMALL)
    rng = np.random.default_rng(11)
    w = ls.encode(cfg, synthetic_demo(0, rng, T=30))
    lib = ls.library(cfg, [ls.component(0, w, support=1.0, age=29)], dim_human=3, dim_robot=7, n_seen=29)
    assert lib.partial_fit(synthetic_demo(3, rng, T=30)).deleted == ()  # age 30 is not past 30


# ------------------------------------------------------------------------------ prediction
def _conditioned_robot_reference(lib, k, y, f):
    """Eq. (13) by brute force: the joint Gaussian of [w; vec(y)] conditioned on vec(y).

    The samples see the least-squares human weights ``S^-1 w_h`` (the ridge undone,
    ``brute_force.unshrink``), so ``vec(y) = H^T S^-1 w_h + noise``.
    """
    from brute_force import unshrink

    cfg = lib.config
    c = lib.component(k)
    Phi = cfg.basis_human.phi(np.linspace(0.0, f, y.shape[0]))
    HT = np.zeros((y.size, c.mean.shape[0]))
    HT[:, :15] = np.kron(np.eye(3), Phi) @ unshrink(cfg, 15)
    d, m = c.mean.shape[0], y.size
    mean_j = np.r_[c.mean, HT @ c.mean]
    noise = lib.observation_noise()
    assert noise >= cfg.observation_noise
    cov_j = np.block([[c.cov, c.cov @ HT.T], [HT @ c.cov, HT @ c.cov @ HT.T + noise * np.eye(m)]])
    mu, S = condition_gaussian(mean_j, cov_j, np.arange(d, d + m), y.T.reshape(-1))
    return mu[15:], S[15:, 15:]


@pytest.mark.parametrize("gain", [False, True], ids=["eq13", "learned_gain"])
@pytest.mark.parametrize("f", [1.0, 0.5])
def test_predict_robot_is_the_conditioned_robot_block_over_the_components_phase(f, gain):
    """Eq. (13) by brute force; with the learned gain (library.gain) the predictor
    ``m0 + G K (y - E y)`` and its error covariance, from the joint Gaussian's blocks."""
    lib = _lib(n=8, tasks=(0, 1), conditioning_gain=gain)
    demo = synthetic_demo(1, np.random.default_rng(12), T=30)
    human = demo.human
    if f < 1:
        step = np.linalg.norm(np.diff(human, axis=0), axis=1)
        human = human[:int(np.searchsorted(np.cumsum(step), f * step.sum())) + 2]
    k = lib.recognize(human, observed_fraction=f).component
    y = lib.human_samples(human, observed_fraction=f)
    assert y.shape == (30 if f == 1 else 15, 3)
    mu_r, S_r = _conditioned_robot_reference(lib, k, y, f)
    if gain:
        g = np.tile(lib.state().gain.gains(), 7)
        assert lib.state().gain.count >= 5 and not np.allclose(g, 1.0)  # learned from the 8 demonstrations
        m0, C0 = np.asarray(lib.component(k).mean)[15:], np.asarray(lib.component(k).cov)[15:, 15:]
        mu_r = m0 + g * (mu_r - m0)
        # error covariance of m0 + G K r with Cov(r) = R, Cov(w_r, r) = C_ry, K = C_ry R^-1:
        # C0 - G K C_yr - C_ry K^T G + G K R K^T G, where K C_yr = K R K^T = C0 - S_r (Eq. 13's reduction)
        M, G = C0 - S_r, np.diag(g)
        S_r = C0 - G @ M - M @ G + G @ M @ G
    mean, cov = lib.predict_robot(human, observed_fraction=f, n_steps=12)
    Phi_r = lib.config.basis_robot.phi(np.linspace(0, 1, 12))
    np.testing.assert_allclose(mean, Phi_r @ mu_r.reshape(7, 5).T, rtol=1e-7, atol=1e-9)
    Psi = np.kron(np.eye(7), Phi_r[4][None, :])
    np.testing.assert_allclose(cov[4], Psi @ S_r @ Psi.T, rtol=1e-6, atol=1e-10)


def test_a_short_prefix_is_resampled_to_at_least_two_samples():
    lib = _lib(n=4, n_samples=100)
    human = synthetic_demo(0, np.random.default_rng(13), T=60).human
    assert lib.human_samples(human[:5], observed_fraction=0.004).shape == (2, 3)  # round(0.4) = 0: 2 are used
    assert lib.human_samples(human[:20], observed_fraction=0.25).shape == (25, 3)
    assert lib.human_samples(human).shape == (100, 3)
    rec = lib.recognize(human[:5], observed_fraction=0.004)
    assert rec.mahalanobis_sq.shape == (lib.n_components,) and np.all(rec.phases == 0.004)


def test_encoding_uses_the_configured_ridge_tolerance_and_start_subtraction():
    """A component created by a demonstration sits at the weights computed here from the documented
    pipeline: normalize (Eq. 14), arc-length resample the human, time-resample the robot, ridge (Eq. 3)."""
    from drake_skills.promp.basis import ridge_weights
    from drake_skills.promp.preprocessing import resample_in_time

    rng = np.random.default_rng(14)
    demo = synthetic_demo(2, rng, T=40)
    noisy = Demonstration(t=demo.t, human=demo.human + 0.02 * rng.standard_normal(demo.human.shape), robot=demo.robot)
    ws = Workspace([-5.0, -5.0, -5.0], [15.0, 15.0, 15.0])
    for kw in (dict(ridge=1e-2), dict(resample_tolerance=0.1), dict(subtract_start=False, workspace=ws),
               dict(subtract_start=False)):
        cfg = LibraryConfig(**SMALL, **kw)
        human = noisy.human
        if cfg.workspace is not None:
            human = ws.normalize(human, subtract_start=cfg.subtract_start)
        elif cfg.subtract_start:
            human = human - human[0]
        y_h = resample_by_arc_length(human, 30, cfg.resample_tolerance)
        y_r = resample_in_time(noisy.t, noisy.robot, 30)
        w = np.r_[ridge_weights(y_h, cfg.basis_human, cfg.ridge), ridge_weights(y_r, cfg.basis_robot, cfg.ridge)]
        lib = SkillLibrary(cfg)
        lib.partial_fit(noisy)
        np.testing.assert_allclose(lib.components[0].mean, w, rtol=1e-10, atol=1e-12, err_msg=str(kw))
        assert lib.recognize(noisy.human, observed_fraction=1.0).mahalanobis_sq[0] == pytest.approx(0.0, abs=1e-12)
    default = SkillLibrary(LibraryConfig(**SMALL))
    default.partial_fit(noisy)
    assert not np.allclose(default.components[0].mean, lib.components[0].mean, atol=1e-3)


def test_messages_of_an_unnamed_demonstration_say_demonstration():
    lib = _lib(n=2)
    d = synthetic_demo(0, np.random.default_rng(15), T=30)
    _raises("demonstration: human trajectory does not move: its path length is 0", lib.partial_fit,
            Demonstration(t=d.t, human=np.zeros((30, 3)), robot=d.robot))
    _raises("demonstration: has no robot, the library has 7 robot joints", lib.partial_fit,
            Demonstration(t=d.t, human=d.human))


def test_deleted_support_is_recorded_to_six_decimals():
    cfg = LibraryConfig(**SMALL)
    rng = np.random.default_rng(16)
    w = ls.encode(cfg, synthetic_demo(0, rng, T=30))
    lib = ls.library(cfg, [ls.component(0, w, support=1.23456789, age=30)], dim_human=3, dim_robot=7, n_seen=30)
    assert lib.partial_fit(synthetic_demo(3, rng, T=30)).deleted == (0,)
    assert lib.history[-1]["support"] == 1.234568

@pytest.mark.parametrize("age, deleted", [(65, False), (66, True)])
def test_the_deletion_age_is_delete_min_age_times_k_over_5(age, deleted):
    """K = 11 components after the step: the age limit is 30 * 11 / 5 = 66. A component of support 1 aged 66
    after the step is kept, aged 67 deleted; ten others (support 5, far apart) stay."""
    cfg = LibraryConfig(**SMALL)
    rng = np.random.default_rng(21)
    demo = synthetic_demo(0, rng, T=30)
    w = ls.encode(cfg, demo)
    comps = [ls.component(k, w + 60.0 * np.eye(50)[k], support=5.0, age=10) for k in range(9)]
    comps.append(ls.component(9, w - 60.0 * np.eye(50)[0], support=1.0, age=age))
    lib = ls.library(cfg, comps, dim_human=3, dim_robot=7, n_seen=100)
    u = lib.partial_fit(demo)
    assert u.created == (10,) and u.merged == () and lib.n_components + len(u.deleted) == 11
    assert u.deleted == ((9,) if deleted else ())
