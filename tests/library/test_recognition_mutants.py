"""Recognition's queries against references written out in the test (the survivors of ``make mutate``).

Phase estimation and prediction of a beginning, the workspace and ``normalized``
arguments of every query, the data guard of ``predict_robot``, the answer of an
empty library, the "undecided" message and the pruning switch. The references are
independent of :mod:`drake_skills.library.recognition`: the phase is the grid phase of
highest :func:`~drake_skills.promp.interaction.prefix_statistics` likelihood within the
band, component by component; the prediction is the robot block of
:func:`~drake_skills.promp.interaction.condition_on_observations`.
"""
import warnings
from dataclasses import replace

import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary, Workspace
from drake_skills.library import recognition
from drake_skills.library.views import DataWarning, UnitsWarning, UnknownSkillError, WorkspaceWarning
from drake_skills.promp.interaction import condition_on_observations, prefix_statistics
from drake_skills.promp.preprocessing import arc_length, resample_by_arc_length

import library_states as ls
from synthetic import synthetic_demo

#: The phases prefix recognition tries and its band (written out: the reference does not read the library's).
GRID = np.round(np.arange(1, 21) / 20.0, 6)
BAND = 1.5
#: A subject whose workspace maps the synthetic demos (normalized units, |x| <= 7) into [0, 10] at half the size.
WS = Workspace(np.full(3, -10.0), np.full(3, 10.0))
#: The library's own configuration workspace in the normalized-input tests: another subject.
WS_CONFIG = Workspace(np.full(3, -6.0), np.full(3, 10.0))


def _cut(human, fraction):
    step = np.linalg.norm(np.diff(human, axis=0), axis=1)
    return human[:int(np.searchsorted(np.cumsum(step), fraction * step.sum())) + 1]


def _teach(config, workspace=None, tasks=(0, 1, 2), n=3, seed=0):
    rng = np.random.default_rng(seed)
    lib = SkillLibrary(config)
    for _ in range(n):
        for t in tasks:
            lib.partial_fit(synthetic_demo(t, rng, T=60), workspace=workspace)
    return lib


@pytest.fixture(scope="module")
def taught():
    """Three skills taught with a per-call workspace (the config has none), three demonstrations each."""
    lib = _teach(LibraryConfig(), WS)
    assert lib.n_components == 3 and lib.trained_with_workspace
    return lib


def _probes(seed=7):
    rng = np.random.default_rng(seed)
    out = []
    for t in (0, 1, 2):
        h = synthetic_demo(t, rng, T=60).human
        out += [_cut(h, f) for f in (0.2, 0.45, 0.7)] + [h]
    # a motion longer than any skill's mean path (guess > 1)
    out.append(np.concatenate([h, h[-1] + (h[1:] - h[0]) * 0.3]))
    return out


def _reference_phase(cfg, yn, mean_h, support, path_length, gating_cov, noise):
    """The grid phase of highest likelihood within the band around the path-length guess, one phase at a time."""
    _, s = arc_length(yn, cfg.resample_tolerance)
    guess = s[-1] / path_length
    n = int(min(cfg.n_samples, max(5, 5 * np.ceil(min(guess, 1.0) * cfg.n_samples / 5.0))))
    ys = resample_by_arc_length(yn, n, cfg.resample_tolerance)
    g = min(max(guess, GRID[0]), 1.0)
    band = [f for f in GRID if g / BAND - 1e-12 <= f <= min(g * BAND, 1.0) + 1e-12]
    nearest = GRID[np.abs(GRID - g).argmin()]
    band = sorted(set(band) | {nearest})
    ll = [prefix_statistics(mean_h, gating_cov * (1.0 + 1.0 / support), cfg.basis_human.phi(np.linspace(0, f, n)),
                            ys, noise)[0] for f in band]
    return float(band[int(np.argmax(ll))])


def _all_reference_phases(lib, yn, path_lengths=None):
    st = lib.state()
    from brute_force import unshrink

    h = lib.n_human
    U = unshrink(lib.config, h)               # the samples see the least-squares weights S^-1 w
    G, noise = U @ lib.shared_covariance("gating") @ U.T, lib.observation_noise()
    pl = [c.cluster.path_length for c in st.components] if path_lengths is None else path_lengths
    return [_reference_phase(lib.config, yn, U @ c.cluster.mean[:h], c.cluster.support, p, G, noise)
            for c, p in zip(st.components, pl)]


def test_estimate_phase_is_the_most_likely_phase_of_the_band_as_computed_component_by_component(taught):
    """Every component, beginnings of 20-100 % and a motion longer than any skill: the phase of estimate_phase,
    of recognize's .phases and of normalized input are all the reference's (exactly: grid values)."""
    lib = taught
    ids = [c.id for c in lib.components]
    seen = set()
    for human in _probes():
        yn = WS.normalize(human)
        expect = _all_reference_phases(lib, yn)
        got = [lib.estimate_phase(human, k, workspace=WS) for k in ids]
        assert got == expect
        assert [lib.estimate_phase(yn, k, normalized=True) for k in ids] == expect
        np.testing.assert_array_equal(lib.recognize(human, workspace=WS).phases, expect)
        seen |= set(expect)
    assert len(seen) >= 6 and 1.0 in seen and min(seen) <= 0.3, sorted(seen)


def test_phase_of_components_with_paths_shorter_than_one_unit(taught):
    """The guess is the path length over the component's, also below 1 unit (no floor but 1e-12 against 0)."""
    st = taught.state()
    short = [replace(c, cluster=replace(c.cluster, path_length=c.cluster.path_length / 12.0))
             for c in st.components]
    lib = SkillLibrary.from_state(replace(st, components=tuple(short)))
    pl = [c.cluster.path_length for c in lib.state().components]
    assert max(pl) < 1.0
    ids = [c.id for c in lib.components]
    for human in _probes()[:3]:
        yn = WS.normalize(human) / 12.0
        expect = _all_reference_phases(lib, yn, pl)
        assert [lib.estimate_phase(yn, k, normalized=True) for k in ids] == expect
        np.testing.assert_array_equal(lib.recognize(yn, normalized=True).phases, expect)


def _reference_prediction(lib, yn, cid, f, n_steps):
    """The robot trajectory mean of component ``cid`` conditioned on ``yn`` resampled over phases [0, f]."""
    cfg = lib.config
    c = lib.component(cid)
    m = max(2, int(round(cfg.n_samples * f))) if f < 1 else cfg.n_samples
    y = resample_by_arc_length(yn, m, cfg.resample_tolerance)
    from brute_force import unshrink

    h = lib.n_human
    T = np.eye(c.mean.shape[0])
    T[:h, :h] = unshrink(cfg, h)              # the samples see the least-squares human weights
    mu, _ = condition_on_observations(T @ c.mean, T @ c.cov @ T.T, cfg.basis_human.phi(np.linspace(0, f, m)), y,
                                      lib.observation_noise(), start=h)
    if cfg.conditioning_gain:  # Eq. (13)'s correction scaled by the library's learned gains (library.gain)
        g = lib.state().gain
        m0 = np.asarray(c.mean)[h:]
        mu = m0 + np.tile(g.gains(), lib.dim_robot_) * (mu - m0)
    return cfg.basis_robot.phi_uniform(n_steps) @ mu.reshape(lib.dim_robot_, -1).T


def _no_data_warning(fn):
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        out = fn()
    assert [str(w.message) for w in got if issubclass(w.category, DataWarning)] == []
    return out


def test_predict_robot_of_a_beginning_conditions_the_recognized_component_at_its_estimated_phase(taught):
    """No fraction given: the component recognize() answers, at the phase estimate_phase gives, conditioned on
    the samples of that phase; raw input with its workspace and the same input normalized agree, silently."""
    lib = taught
    for human in _probes()[:4]:
        yn = WS.normalize(human)
        rec = lib.recognize(human, workspace=WS)
        assert rec.status == "skill"
        f = lib.estimate_phase(human, rec.component, workspace=WS)
        assert rec.phase == f
        expect = _reference_prediction(lib, yn, rec.component, f, 25)
        got = _no_data_warning(lambda: lib.predict_robot(human, workspace=WS, n_steps=25)[0])
        np.testing.assert_allclose(got, expect, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(_no_data_warning(lambda: lib.predict_robot(yn, normalized=True, n_steps=25)[0]),
                                   expect, rtol=1e-9, atol=1e-9)
        other = (rec.component + 1) % 3
        g = lib.estimate_phase(human, other, workspace=WS)
        np.testing.assert_allclose(lib.predict_robot(human, workspace=WS, component=other, n_steps=25)[0],
                                   _reference_prediction(lib, yn, other, g, 25), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("f", [0.5, 1.0])
def test_predict_robot_with_a_fraction_takes_the_workspace_and_normalized_input(taught, f):
    lib = taught
    human = _cut(synthetic_demo(1, np.random.default_rng(3), T=60).human, f)
    yn = WS.normalize(human)
    k = lib.recognize(human, workspace=WS, observed_fraction=f).component
    assert k is not None
    expect = _reference_prediction(lib, yn, k, f, 20)
    np.testing.assert_allclose(_no_data_warning(lambda: lib.predict_robot(human, f, workspace=WS, n_steps=20)[0]),
                               expect, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(_no_data_warning(lambda: lib.predict_robot(yn, f, normalized=True, n_steps=20)[0]),
                               expect, rtol=1e-9, atol=1e-9)


@pytest.fixture(scope="module")
def taught_config_workspace():
    """Three skills taught under a configuration workspace: normalized input must not meet it again."""
    return _teach(LibraryConfig(workspace=WS_CONFIG))


def test_normalized_input_skips_the_configuration_workspace_in_every_query(taught_config_workspace):
    lib = taught_config_workspace
    human = _cut(synthetic_demo(2, np.random.default_rng(4), T=60).human, 0.6)
    yn = WS_CONFIG.normalize(human)
    k = lib.recognize(human).component
    assert k is not None
    for a, b in [(lambda: lib.predict_robot(human)[0], lambda: lib.predict_robot(yn, normalized=True)[0]),
                 (lambda: lib.predict_robot(human, 0.6)[0], lambda: lib.predict_robot(yn, 0.6, normalized=True)[0]),
                 (lambda: lib.estimate_phase(human, k), lambda: lib.estimate_phase(yn, k, normalized=True))]:
        np.testing.assert_array_equal(a(), b())
    # raw input is normalized by default: estimate_phase's `normalized` defaults to False
    assert lib.estimate_phase(human, k) != lib.estimate_phase(human, k, normalized=True)


WORKSPACE_MESSAGE = ("recognize()/predict_robot() without a workspace on a library trained with one: the motion is "
                     "taken in raw units and will likely be 'unknown'; give the subject's workspace (workspace= in "
                     "Python, --workspace or a workspace.json / calibration.npz beside the files on the command "
                     "line) or, for samples already in normalized units, normalized=True (warned once per library)")


def _fresh(lib):
    """The same library without the warnings already issued (they are once per object)."""
    return SkillLibrary.from_state(lib.state())


def _data_warnings(fn):
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        try:
            fn()
        except UnknownSkillError:
            pass
    return [(w.category, str(w.message)) for w in got if issubclass(w.category, DataWarning)]


@pytest.mark.parametrize("query", ["recognize", "predict_robot"])
@pytest.mark.parametrize("f", [None, 0.5, 1.0])
def test_a_query_without_the_training_workspace_warns_as_a_query_and_with_it_or_normalized_does_not(
        taught, f, query):
    human = _cut(synthetic_demo(0, np.random.default_rng(5), T=60).human, f or 0.6)

    def ask(lib, x, **kw):
        if query == "recognize":
            return lib.recognize(x, observed_fraction=f, **kw)
        return lib.predict_robot(x, f, component=0, **kw)

    assert _data_warnings(lambda: ask(_fresh(taught), human)) == [(WorkspaceWarning, WORKSPACE_MESSAGE)]
    assert _data_warnings(lambda: ask(_fresh(taught), human, workspace=WS)) == []
    assert _data_warnings(lambda: ask(_fresh(taught), WS.normalize(human), normalized=True)) == []


@pytest.mark.parametrize("f", [None, 0.5, 1.0])
def test_recognize_takes_normalized_input_as_it_is(taught_config_workspace, f):
    lib = taught_config_workspace
    human = _cut(synthetic_demo(0, np.random.default_rng(9), T=60).human, f or 0.6)
    a = lib.recognize(human, observed_fraction=f)
    b = lib.recognize(WS_CONFIG.normalize(human), observed_fraction=f, normalized=True)
    assert a.status == b.status == "skill" and a.component == b.component
    np.testing.assert_array_equal(a.log_likelihoods, b.log_likelihoods)
    np.testing.assert_array_equal(a.phases, b.phases)


@pytest.mark.parametrize("n, fraction, expect", [(100, 0.001, 5), (100, 0.03, 5), (100, 0.2, 20), (100, 0.21, 25),
                                                 (100, 0.97, 100), (100, 1.0, 100), (30, 0.5, 15), (30, 0.51, 20)])
def test_a_beginning_is_resampled_to_its_fraction_of_n_samples_rounded_up_to_a_multiple_of_5(n, fraction, expect):
    """At least 5 and at most n_samples (the sizes recur, so their cached terms are reused)."""
    assert recognition._prefix_samples(n, fraction) == expect


def test_the_median_of_the_path_length_guesses_is_numpys_exactly():
    """The beginning's sample count comes from the median guess: odd and even sizes, ties, one element."""
    rng = np.random.default_rng(3)
    cases = [np.array([0.4]), np.array([0.2, 0.9]), np.array([0.5, 0.5, 0.1]), np.array([1.0, 0.3, 0.3, 0.7])]
    cases += [rng.uniform(0, 1, n) * s for n in range(1, 12) for s in (1e-3, 1.0, 7.0)]
    for x in cases:
        assert recognition._median(x) == float(np.median(x)), x
    assert recognition._median(np.array([0.2, 0.9])) == 0.55


def test_predict_robot_warns_of_a_whole_motion_spanning_little_but_not_of_a_short_beginning(taught):
    """The units guard: a whole motion (fraction 1) must span 1 unit of the scale 10; a beginning may span less."""
    human = synthetic_demo(0, np.random.default_rng(6), T=60).human
    tiny = human[0] + (human - human[0]) * 0.05            # spans about 0.35 raw units: 0.06 normalized
    start = human[:4]                                         # a real beginning spanning under 1 unit
    assert np.ptp(WS.normalize(start), axis=0).max() < 1.0
    got = _data_warnings(lambda: _fresh(taught).predict_robot(tiny, 1.0, workspace=WS, component=0))
    assert [c for c, _ in got] == [UnitsWarning] and "far below the normalized range [0, 10]" in got[0][1]
    for f in (None, 0.05):
        assert _data_warnings(lambda: _fresh(taught).predict_robot(start, f, workspace=WS, component=0)) == []


def test_a_library_whose_components_were_all_deleted_answers_unknown_with_empty_arrays():
    cfg = LibraryConfig(n_samples=30, n_basis_human=5, n_basis_robot=5)
    lib = ls.library(cfg, [], dim_human=3, dim_robot=7, n_seen=4)
    human = synthetic_demo(0, np.random.default_rng(0), T=30).human
    for rec in (lib.recognize(human), lib.recognize(human, observed_fraction=1.0),
                lib.recognize(human[:10], observed_fraction=0.3)):
        assert rec.status == "unknown" and rec.component is None and rec.ids == ()
        for a in (rec.responsibilities, rec.log_likelihoods, rec.mahalanobis_sq, rec.phases, rec.posterior):
            assert isinstance(a, np.ndarray) and a.shape == (0,)
        assert rec.dof == 15 and np.isnan(rec.phase) and rec.confidence == 0.0


def test_the_undecided_message_names_the_two_most_probable_skills_most_probable_first():
    """Three skills at the motion's weights with supports 5, 3, 2 (posteriors s_k (1 + 1/s_k)^(-h/2) normalized:
    0.74, 0.20, 0.06) answer differently: the message lists the first two, in that order, with their posteriors."""
    H, R = 15, 35
    cfg = LibraryConfig(n_samples=30, n_basis_human=5, n_basis_robot=5, delete_min_age=1000)
    rng = np.random.default_rng(0)
    demo = synthetic_demo(0, rng, T=30)
    w = ls.encode(cfg, demo)
    S = ls.library(cfg, [], dim_human=3, dim_robot=7).shared_covariance("expert")
    comps = []
    for k, s in enumerate((5.0, 3.0, 2.0)):
        m = w.copy()
        m[:H] += 1e-3 * np.sqrt(S[0, 0]) * np.eye(H)[k]         # all three at the motion's weights
        m[H:] += 10.0 * k * np.sqrt(S[H, H]) * ls.unit(rng, R)   # and answer far apart
        comps.append(ls.component(k, m, support=s, age=3))
    lib = ls.library(cfg, comps, dim_human=3, dim_robot=7, n_seen=10)
    rec = lib.recognize(demo.human, observed_fraction=1.0)
    assert rec.status == "undecided"
    s = np.array([5.0, 3.0, 2.0])
    p = s * (1.0 + 1.0 / s) ** (-H / 2)
    np.testing.assert_allclose(rec.posterior, p / p.sum(), atol=1e-3)
    p = rec.posterior
    msg = (f"the motion fits more than one skill and none clearly (0 ({p[0]:.2f}), 1 ({p[1]:.2f})): "
           f"observe more, or ask")
    with pytest.raises(UnknownSkillError) as err:
        lib.predict_robot(demo.human, observed_fraction=1.0)
    assert str(err.value) == msg


def test_the_pruning_bound_is_used_only_above_prune_min_components(taught, monkeypatch):
    """A motion of one skill: with more components than PRUNE_MIN_COMPONENTS the others are ruled out unscored
    (log-likelihood -inf); with exactly as many, every component is scored."""
    human = _cut(synthetic_demo(0, np.random.default_rng(8), T=60).human, 0.7)
    monkeypatch.setattr(recognition, "PRUNE_MIN_COMPONENTS", taught.n_components)
    full = taught.recognize(human, workspace=WS)
    assert np.isfinite(full.log_likelihoods).all()
    monkeypatch.setattr(recognition, "PRUNE_MIN_COMPONENTS", taught.n_components - 1)
    pruned = taught.recognize(human, workspace=WS)
    assert pruned.status == full.status == "skill" and pruned.component == full.component
    assert np.isfinite(pruned.log_likelihoods).sum() == 1


def _hand_library(offsets, path_factors, *, shrinkage, delta=4.0):
    """A human-only library on a gating covariance of variance 4 along weight 0 and 1e-3 along the others (with
    ``shrinkage=0``), and a constant-speed probe motion ``yn``: component 0 is the probe's weights moved by
    ``delta`` along weight 0 (its path length the probe's), component k > 0 is moved by ``offsets[k-1]`` in x and
    minus two thirds of it in y, its path length ``path_factors[k-1]`` times the probe's."""
    from drake_skills.library.scale import SharedScale
    from drake_skills.promp.basis import ridge_weights

    cfg = LibraryConfig(shrinkage=shrinkage)
    h, N = 3 * cfg.n_basis_human, cfg.n_basis_human
    z = np.linspace(0.0, 1.0, 200)
    yn = np.stack([6 * z, 3 * np.sin(np.pi * z), 2 * z ** 2], axis=1)
    w = ridge_weights(resample_by_arc_length(yn, cfg.n_samples, cfg.resample_tolerance), cfg.basis_human, cfg.ridge)
    L = arc_length(yn, cfg.resample_tolerance)[1][-1]
    v = np.full(h, 1e-3)
    v[0] = 4.0
    scale = SharedScale(0, np.zeros(h), np.zeros(h), 1e6 * np.diag(v), 1e6, 0.0)
    comps = [ls.component(0, w - delta * np.eye(h)[0], support=10, age=10, path_length=L)]
    for k, (off, f) in enumerate(zip(offsets, path_factors), start=1):
        m = w.copy()
        m[:N] += off
        m[N:2 * N] -= 2.0 * off / 3.0
        comps.append(ls.component(k, m, support=10, age=10, path_length=L * f))
    return ls.library(cfg, comps, dim_human=3, dim_robot=0, scale=scale, n_seen=30), yn, L


def test_the_pruning_bound_uses_the_largest_within_skill_variance(monkeypatch):
    """The probe differs from its skill only along the one weight of large within-skill variance (4; the others
    1e-3): the bound, with the largest eigenvalue, keeps the skill and the answer is the one scoring every
    component gives; the second largest (1e-3) would rule the skill out and answer "unknown"."""
    lib, yn, _ = _hand_library((3.0, 6.0), (1.0, 1.0), shrinkage=0.0)
    ev = np.linalg.eigvalsh(lib.shared_covariance("gating"))
    assert ev[-1] == pytest.approx(4.0, rel=1e-4) and ev[-2] == pytest.approx(1e-3, rel=1e-3)
    monkeypatch.setattr(recognition, "PRUNE_MIN_COMPONENTS", 10 ** 9)
    full = lib.recognize(yn, normalized=True)
    monkeypatch.setattr(recognition, "PRUNE_MIN_COMPONENTS", 0)
    pruned = lib.recognize(yn, normalized=True)
    assert full.status == pruned.status == "skill" and full.component == pruned.component == 0
    assert full.mahalanobis_sq[0] < 10.0
    # the pruned path scores a subset of the rows: BLAS may sum them in another order (1e-16 relative seen)
    np.testing.assert_allclose(pruned.log_likelihoods[0], full.log_likelihoods[0], rtol=1e-12, atol=0)


def test_components_the_bound_rules_out_report_minus_inf_inf_zero_and_their_path_length_phase(monkeypatch):
    """Three components far from the motion are ruled out unscored (Recognition's contract): log-likelihood
    -inf, distance inf, responsibility and posterior 0, dof h, and as phase the path-length guess clipped to
    [1 / n_samples, 1] (guesses 0.005, 1/60 and 2 here)."""
    lib, yn, L = _hand_library((300.0, 600.0, 900.0), (200.0, 60.0, 0.5), shrinkage=0.1)
    monkeypatch.setattr(recognition, "PRUNE_MIN_COMPONENTS", 0)
    rec = lib.recognize(yn, normalized=True)
    assert rec.status == "skill" and rec.component == 0
    out = slice(1, None)
    assert (rec.log_likelihoods[out] == -np.inf).all() and (rec.mahalanobis_sq[out] == np.inf).all()
    assert (rec.responsibilities[out] == 0).all() and (rec.posterior[out] == 0).all()
    np.testing.assert_array_equal(rec.dof[out], [21.0, 21.0, 21.0])
    np.testing.assert_allclose(rec.phases[out], [1.0 / 100, 1.0 / 60, 1.0], rtol=1e-12)
    assert np.isfinite(rec.log_likelihoods[0]) and rec.responsibilities[0] == pytest.approx(1.0, abs=1e-12)


def test_a_beginning_of_under_5_percent_is_conditioned_on_two_samples_at_phase_005():
    """n_samples 30: the phase 0.05 of a beginning the band cannot place later gives round(1.5) = 2 samples."""
    lib = _teach(LibraryConfig(n_samples=30, n_basis_human=5, n_basis_robot=5), WS)
    human = synthetic_demo(0, np.random.default_rng(10), T=60).human
    start = human[:int(np.searchsorted(np.linalg.norm(human - human[0], axis=1), 0.1)) + 2]
    yn = WS.normalize(start)
    for k in (c.id for c in lib.components):
        assert lib.estimate_phase(start, k, workspace=WS) == 0.05
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DataWarning)
            got = lib.predict_robot(start, workspace=WS, component=k, n_steps=10)[0]
        np.testing.assert_allclose(got, _reference_prediction(lib, yn, k, 0.05, 10), rtol=1e-9, atol=1e-9)
