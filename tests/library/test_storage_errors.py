"""Library files: the round trip against the saved library, and every load error with the message a user sees.

Kept apart from ``test_storage.py`` (atomic writes, size checks, older schemas): each
case here changes one thing in a good file and expects the exact error naming the file.
"""
import json
import re

import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.library import storage

from synthetic import WORKSPACE, synthetic_demo


@pytest.fixture(scope="module")
def lib():
    """Three skills (merged sub-clusters, an outlier deleted), taught with a workspace."""
    rng = np.random.default_rng(0)
    lib = SkillLibrary(LibraryConfig(delete_min_age=5, n_samples=40))
    lib.partial_fit(synthetic_demo(3, rng, T=40), workspace=WORKSPACE)  # an outlier that gets deleted
    for i in range(15):
        lib.partial_fit(synthetic_demo(i % 3, rng, T=40, scale=rng.uniform(0.8, 1.2)), workspace=WORKSPACE)
    return lib


@pytest.fixture(scope="module")
def good(lib, tmp_path_factory):
    return lib.save(tmp_path_factory.mktemp("good") / "good.npz")


def _assert_same_cluster(a, b, what):
    assert (a is None) == (b is None), what
    if a is None:
        return
    assert (a.support, a.duration, a.path_length) == (b.support, b.duration, b.path_length), what
    np.testing.assert_array_equal(a.mean, b.mean, err_msg=what)
    np.testing.assert_array_equal(a.factor, b.factor, err_msg=what)


def test_round_trip_restores_everything_the_saved_library_holds(lib, good):
    """Compared with the library before saving (not with another load): ages, supports, durations, path lengths,
    means, scatters, sub-clusters, history, ids, counts, the shared scale and the workspace flag."""
    a, b = lib.state(), SkillLibrary.load(good).state()
    assert any(e["event"] == "deleted" for e in a.history) and any(e["event"] == "merged" for e in a.history) \
        or any(c.subclusters[1] is not None for c in a.components)
    assert b.config == a.config and b.history == a.history
    assert (b.dim_human, b.dim_robot, b.next_id, b.n_seen, b.trained_with_workspace) == \
        (a.dim_human, a.dim_robot, a.next_id, a.n_seen, True)
    assert [(c.id, c.age) for c in b.components] == [(c.id, c.age) for c in a.components]
    assert len({c.age for c in a.components}) > 1  # ages differ: a reset would show
    for ca, cb in zip(a.components, b.components):
        _assert_same_cluster(ca.cluster, cb.cluster, f"component {ca.id}")
        for j in range(2):
            _assert_same_cluster(ca.subclusters[j], cb.subclusters[j], f"sub-cluster {j} of {ca.id}")
    assert any(c.subclusters[1] is not None for c in a.components)
    sa, sb = a.scale, b.scale
    assert (sb.n, sb.dof, sb.fit_m2) == (sa.n, sa.dof, sa.fit_m2)
    for name in ("total_mean", "total_m2", "pooled"):
        np.testing.assert_array_equal(getattr(sb, name), getattr(sa, name), err_msg=name)


def test_round_trip_answers_and_learns_as_the_saved_library(lib, good):
    back = SkillLibrary.load(good)
    rng = np.random.default_rng(1)
    for task in range(3):
        h = synthetic_demo(task, rng, T=40).human
        for kw in (dict(observed_fraction=1.0), {}):
            r1, r2 = lib.recognize(h, workspace=WORKSPACE, **kw), back.recognize(h, workspace=WORKSPACE, **kw)
            assert (r1.status, r1.component) == (r2.status, r2.component)
            np.testing.assert_array_equal(r1.log_likelihoods, r2.log_likelihoods)
            np.testing.assert_array_equal(r1.phases, r2.phases)
    assert back.observation_noise() == lib.observation_noise()
    d = synthetic_demo(3, rng, T=40)
    copy = SkillLibrary.load(good)
    u = copy.partial_fit(d, workspace=WORKSPACE)
    assert u == back.partial_fit(d, workspace=WORKSPACE) and u.created == (lib.state().next_id,)


def test_a_human_only_library_and_one_never_taught_with_a_workspace_round_trip(tmp_path):
    rng = np.random.default_rng(2)
    lib = SkillLibrary(LibraryConfig(n_samples=30, n_basis_human=5))
    for i in range(4):
        lib.partial_fit(synthetic_demo(i % 2, rng, T=30, robot=False))
    back = SkillLibrary.load(lib.save(tmp_path / "h"))
    assert (back.dim_human_, back.dim_robot_, back.has_robot, back.trained_with_workspace) == (3, 0, False, False)
    assert [c.id for c in back.components] == [c.id for c in lib.components]
    empty = SkillLibrary.load(SkillLibrary(LibraryConfig(n_basis_human=4)).save(tmp_path / "e"))
    assert empty.n_components == 0 and empty.dim_human_ is None and empty.config == LibraryConfig(n_basis_human=4)


def test_save_rejects_what_is_not_a_state(tmp_path):
    with pytest.raises(ValueError, match="^save_state takes a LibraryState, got dict$"):
        storage.save_state({}, tmp_path / "x.npz")


# ------------------------------------------------------------------------------------------ bad files
def _parts(path):
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: np.array(z[k]) for k in z.files}
    return json.loads(str(arrays.pop("metadata"))), arrays


def _meta(**changes):
    def f(meta, arrays):
        meta.update(changes)
    return f


def _comp(i, **changes):
    def f(meta, arrays):
        meta["components"][i].update(changes)
    return f


def _sub(i, j, **changes):
    def f(meta, arrays):
        meta["components"][i]["subclusters"][j].update(changes)
    return f


def _array(name, fn):
    def f(meta, arrays):
        arrays[name] = fn(arrays[name].copy())
    return f


def _set(a, idx, v):
    a[idx] = v
    return a


def _drop(name):
    def f(meta, arrays):
        del arrays[name]
    return f


def _second_ids(meta, arrays):
    meta["components"][1]["id"] = meta["components"][0]["id"]


def _sub_support(meta, arrays):
    c = meta["components"][0]
    assert c["subclusters"][1] is not None
    c["subclusters"][1]["support"] += 0.5


def _asym(p):
    p[0, 1] += 1e-3
    return p


# case -> (change, message after "library file '<path>'")
CASES = {
    "no_format": (_meta(format=None), " is not a drake-skills library (format tag None)"),
    "other_format": (_meta(format="x"), " is not a drake-skills library (format tag 'x')"),
    "schema_missing": (_meta(schema_version=None), ": schema_version missing or not an integer"),
    "schema_text": (_meta(schema_version="3"), ": schema_version missing or not an integer"),
    "schema_bool": (_meta(schema_version=True), ": schema_version missing or not an integer"),
    "newer": (_meta(schema_version=4), " has schema version 4, newer than this drake-skills supports (3): "
                                       "upgrade drake-skills"),
    "schema_0": (_meta(schema_version=0), ": schema_version 0 is not a version of this format"),
    "config_missing": (_meta(config=None), ": bad metadata (TypeError: 'NoneType' object is not iterable)"),
    "config_unknown": (lambda m, a: m["config"].update(magic=1),
                       ": bad metadata (ValueError: unknown LibraryConfig fields: ['magic'])"),
    "config_retired": (lambda m, a: m["config"].update(gating_floor=1.0),
                       ": bad metadata (ValueError: LibraryConfig fields ['gating_floor'] are gone: the novelty "
                       "scale is now learned from the demonstrations (prior_scale, prior_strength, shrinkage); "
                       "delete them)"),
    "config_bad_value": (lambda m, a: m["config"].update(ridge=-1.0),
                         ": bad metadata (ValueError: LibraryConfig.ridge must be >= 0, got -1.0)"),
    "components_missing": (_meta(components=None), ": bad metadata (TypeError: 'NoneType' object is not iterable)"),
    "components_number": (_meta(components=3), ": bad metadata (TypeError: 'int' object is not iterable)"),
    "no_key": (lambda m, a: m.pop("n_seen"), ": bad metadata (KeyError: 'n_seen')"),
    "dim_human_zero": (_meta(dim_human=0), ": bad metadata (ValueError: dim_human must be an integer >= 1, got 0)"),
    "dim_robot_text": (_meta(dim_robot="7"), ": bad metadata (ValueError: dim_robot must be an integer >= 0, "
                                             "got '7')"),
    "next_id_negative": (_meta(next_id=-1), ": bad metadata (ValueError: next_id must be an integer >= 0, got -1)"),
    "n_seen_float": (_meta(n_seen=3.0), ": bad metadata (ValueError: n_seen must be an integer >= 0, got 3.0)"),
    "n_seen_bool": (_meta(n_seen=True), ": bad metadata (ValueError: n_seen must be an integer >= 0, got True)"),
    "history_entries": (_meta(history=[1, 2]), ": bad metadata (ValueError: history entries must be objects)"),
    "workspace_flag": (_meta(trained_with_workspace="yes"),
                       ": bad metadata (ValueError: trained_with_workspace must be true, false or null, got 'yes')"),
    "no_dimensions": (_meta(dim_human=None, dim_robot=None), ": components but no dimensions"),
    "too_many_weights": (_meta(dim_human=2000), ": metadata declares 14140 weights per demonstration (more than "
                                                "10000)"),
    "rank_missing": (lambda m, a: m["components"][0].pop("rank"), ": bad component metadata (KeyError: 'rank')"),
    "rank_negative": (_comp(0, rank=-1), ": bad component metadata (ValueError: component 0 rank must be an "
                                         "integer >= 0, got -1)"),
    "sub_rank_text": (_sub(0, 0, rank="1"), ": bad component metadata (ValueError: component 0 sub-cluster rank "
                                            "must be an integer >= 0, got '1')"),
    "scale_missing": (lambda m, a: m.pop("scale"), ": bad component metadata (KeyError: 'scale')"),
    "rank_above_d": (_comp(0, rank=1000), ": a scatter factor of rank above 161 (the number of weights)"),
    "rank_mismatch": (_comp(0, rank=0), ": array 'factors' has shape (161, 12), the metadata says (161, 8)"),
    "means_short": (_array("means", lambda a: a[:, :-1]), ": array 'means' has shape (3, 160), the metadata says (3, 161)"),
    "missing_pooled": (_drop("pooled"), " is not a drake-skills library (missing ['pooled'])"),
    "text_array": (_array("total_m2", lambda a: a.astype(str)), ": array 'total_m2' is not numeric (<U32)"),
    "nan_mean": (_array("means", lambda a: _set(a, (1, 2), np.nan)), ": array 'means' contains NaN or inf"),
    "inf_factor": (_array("factors", lambda a: _set(a, (0, 0), np.inf)), ": array 'factors' contains NaN or inf"),
    "support_text": (_comp(1, support="lots"), ": component metadata is bad (ValueError: could not convert string "
                                              "to float: 'lots')"),
    "subclusters_three": (lambda m, a: m["components"][0]["subclusters"].append(None),
                        ": component metadata is bad (ValueError: component 0 needs two sub-cluster entries)"),
    "id_text": (_comp(0, id="0"), ": component metadata is bad (ValueError: component 0 id must be an integer >= 0, "
                                  "got '0')"),
    "age_negative": (_comp(1, age=-2), ": component metadata is bad (ValueError: component 1 age must be an integer "
                                       ">= 0, got -2)"),
    "scale_n_negative": (lambda m, a: m["scale"].update(n=-1), ": component metadata is bad (ValueError: scale n "
                                                              "must be an integer >= 0, got -1)"),
    "beginnings_text": (_comp(0, beginnings="x"), ": component metadata is bad (ValueError: beginnings must be an "
                                                  "object of lists of numbers (tested, missed, pending), got 'x')"),
    "beginnings_strings": (_comp(0, beginnings={"tested": ["a"]}),
                           ": component metadata is bad (ValueError: beginnings must be an object of lists of "
                           "numbers (tested, missed, pending), got {'tested': ['a']})"),
    "next_id_huge": (_meta(next_id=2 ** 63 + 5), ": bad metadata (ValueError: next_id must be at most 2**53, got "
                                                 "9223372036854775813)"),
    "pooled_asymmetric": (_array("pooled", _asym), ": the pooled scatter is not symmetric"),
    "duplicate_id": (_second_ids, ": component id 1 is duplicated or out of range (next id 4)"),
    "id_at_next_id": (_comp(0, id=4), ": component id 4 is duplicated or out of range (next id 4)"),
    "age_zero": (_comp(0, age=0), ": component 1 has age 0; the library has seen 16 demonstrations"),
    "age_above_seen": (_comp(0, age=17), ": component 1 has age 17; the library has seen 16 demonstrations"),
    "support_zero": (_comp(0, support=0.0), ": component 1 has support 0.0"),
    # the path length as the file holds it: its last digits depend on the machine's BLAS kernels
    "duration_negative": (_comp(0, duration=-1.0),
                          lambda meta: f": component 1 has duration -1.0 and path length {meta['components'][0]['path_length']!r}"),
    "sub_support_sum": (_sub_support, ": component 1 has support 5.0 but its sub-clusters 5.5"),
    "scale_dof_negative": (lambda m, a: m["scale"].update(dof=-1.0),
                           ": shared scale has negative variances or degrees of freedom"),
    "total_m2_negative": (_array("total_m2", lambda a: _set(a, 0, -1.0)),
                          ": shared scale has negative variances or degrees of freedom"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_file_wrong_in_one_way_is_rejected_with_a_message_naming_it(good, tmp_path, case):
    change, message = CASES[case]
    meta, arrays = _parts(good)
    change(meta, arrays)
    if callable(message):
        message = message(meta)
    p = tmp_path / f"{case}.npz"
    np.savez(p, metadata=np.array(json.dumps(meta)), **arrays)
    with pytest.raises(ValueError, match="^" + re.escape(f"library file '{p}'{message}") + "$"):
        SkillLibrary.load(p)


def test_the_good_file_rewritten_unchanged_loads(good, tmp_path):
    """The baseline of the cases above: reading and rewriting the parts gives a loadable file."""
    meta, arrays = _parts(good)
    p = tmp_path / "same.npz"
    np.savez(p, metadata=np.array(json.dumps(meta)), **arrays)
    assert SkillLibrary.load(p).state().next_id == 4


def test_deeply_nested_metadata_and_a_directory_are_refused_with_the_path(good, tmp_path):
    """A cold review found a RecursionError and an IsADirectoryError traceback here."""
    _, arrays = _parts(good)
    p = tmp_path / "deep.npz"
    np.savez(p, metadata=np.array("[" * 100_000 + "]" * 100_000), **arrays)
    with pytest.raises(ValueError, match="^" + re.escape(f"library file '{p}': metadata is nested too deeply")):
        SkillLibrary.load(p)
    d = tmp_path / "lib.npz"
    d.mkdir()
    with pytest.raises(ValueError, match="^" + re.escape(f"library file '{d}' is a directory; give the library's "
                                                         f".npz file") + "$"):
        SkillLibrary.load(d)


def _zip_with(path, entries):
    import zipfile

    with zipfile.ZipFile(path, "w") as z:
        for name, data in entries.items():
            z.writestr(name, data)


def _npy(a) -> bytes:
    import io

    buf = io.BytesIO()
    np.lib.format.write_array(buf, a, allow_pickle=True)
    return buf.getvalue()


@pytest.mark.parametrize("case, message", [
    ("missing", " does not exist"),
    ("text", " is truncated or not an .npz file"),
    ("not_an_array", ": entry 'metadata' is not a numpy array ("),
    ("objects", ": entry 'metadata' holds Python objects; library files hold only numbers and text (refusing to "
                "unpickle)"),
    ("no_metadata", " is not a drake-skills library (missing ['metadata'])"),
    ("metadata_number", ": metadata entry is not a JSON string"),
    ("metadata_list", ": metadata entry is not a JSON string"),
    ("metadata_not_json", ": metadata is not valid JSON ("),
    ("metadata_json_list", " is not a drake-skills library (format tag None)"),
])
def test_unreadable_files_give_clear_errors(tmp_path, case, message):
    p = tmp_path / f"{case}.npz"
    if case == "text":
        p.write_text("hello")
    elif case == "not_an_array":
        _zip_with(p, {"metadata.npy": b"not an npy file at all"})
    elif case == "objects":
        _zip_with(p, {"metadata.npy": _npy(np.array([{"a": 1}], dtype=object))})
    elif case == "no_metadata":
        np.savez(p, x=np.arange(3))
    elif case == "metadata_number":
        np.savez(p, metadata=np.array(3.0))
    elif case == "metadata_list":
        np.savez(p, metadata=np.array(["{}", "{}"]))
    elif case == "metadata_not_json":
        np.savez(p, metadata=np.array("{not json"))
    elif case == "metadata_json_list":
        np.savez(p, metadata=np.array("[1, 2]"))
    exc = FileNotFoundError if case == "missing" else ValueError
    with pytest.raises(exc, match="^" + re.escape(f"library file '{p}'{message}")):
        SkillLibrary.load(p)


# ------------------------------------------------------------------------------- schema 1-2 (dense) files
def _dense(path, comps, *, n_seen=9, version=2, d_h=3, d_r=0, config=None):
    """A schema-2 file of the fixed-scale library: components (id, age, support, duration, mean, cov)."""
    cfg = (config or LibraryConfig(n_basis_human=5, n_basis_robot=5)).dict()
    cfg.update(sigma_init_human=0.5, sigma_init_robot=0.1, gating_floor=1.0, fast_forgetting=True)
    meta = {"format": storage.FORMAT, "schema_version": version, "config": cfg, "dim_human": d_h, "dim_robot": d_r,
            "next_id": max(c[0] for c in comps) + 1, "n_seen": n_seen, "history": [],
            "components": [{"id": c[0], "age": c[1], "support": c[2], "duration": c[3]} for c in comps]}
    np.savez(path, metadata=np.array(json.dumps(meta)), means=np.stack([c[4] for c in comps]),
             covs=np.stack([c[5] for c in comps]))
    return path


def _spd(rng, d, scale):
    A = rng.standard_normal((d, d))
    return scale * (A @ A.T / d + 0.1 * np.eye(d))


def test_a_dense_file_becomes_scatters_and_a_shared_scale_estimated_from_its_components(tmp_path, caplog):
    """Each covariance C_k becomes the scatter s_k C_k; the scale's totals are the support-weighted moments of the
    components, its pooled scatter their sum over sum(s_k - 1) degrees of freedom; ages at least 1; no path lengths
    (a warning says so)."""
    rng = np.random.default_rng(3)
    d = 15
    comps = [(2, 0, 3.0, 1.5, rng.standard_normal(d), _spd(rng, d, 0.2)),
             (5, 4, 1.5, 2.5, rng.standard_normal(d), _spd(rng, d, 0.05))]
    with caplog.at_level("WARNING", logger="drake_skills.library.storage"):
        st = SkillLibrary.load(_dense(tmp_path / "v2.npz", comps)).state()
    assert "has schema version < 3 (fixed Sigma_init scale)" in caplog.text and "v2.npz" in caplog.text
    assert [(c.id, c.age, c.support, c.duration, c.path_length) for c in st.components] == \
        [(2, 1, 3.0, 1.5, 0.0), (5, 4, 1.5, 2.5, 0.0)]
    s = np.array([3.0, 1.5])
    means = np.stack([c[4] for c in comps])
    covs = np.stack([c[5] for c in comps])
    for c, (_, _, sk, _, m, C) in zip(st.components, comps):
        np.testing.assert_array_equal(c.mean, m)
        np.testing.assert_allclose(c.cluster.scatter, sk * C, rtol=1e-10, atol=1e-12)
        assert c.subclusters[0] is c.cluster and c.subclusters[1] is None
    mean = s @ means / s.sum()
    sc = st.scale
    assert sc.n == 9 and sc.dof == pytest.approx(np.sum(s - 1.0), rel=1e-12)
    np.testing.assert_allclose(sc.total_mean, mean, rtol=1e-12)
    np.testing.assert_allclose(sc.total_m2, s @ (np.stack([np.diag(C) for C in covs]) + (means - mean) ** 2),
                               rtol=1e-12)
    np.testing.assert_allclose(sc.pooled, 3.0 * covs[0] + 1.5 * covs[1], rtol=1e-10, atol=1e-12)
    assert st.config.n_basis_human == 5 and st.config.ridge == LibraryConfig().ridge


def test_a_dense_file_without_components_gets_an_empty_scale_and_a_schema_1_file_no_tolerance(tmp_path):
    rng = np.random.default_rng(4)
    p = _dense(tmp_path / "v1.npz", [(0, 1, 1.0, 1.0, rng.standard_normal(15), np.eye(15))], version=1)
    meta, arrays = _parts(p)
    del meta["config"]["resample_tolerance"]
    meta["components"], meta["n_seen"] = [], 0
    arrays["means"], arrays["covs"] = np.zeros((0, 15)), np.zeros((0, 15, 15))
    np.savez(p, metadata=np.array(json.dumps(meta)), **arrays)
    st = SkillLibrary.load(p).state()
    assert st.components == () and st.config.resample_tolerance == 0.0 and st.dim_human == 3
    assert st.scale.n == 0 and not st.scale.pooled.any() and st.scale.dof == 0.0


@pytest.mark.parametrize("case, message", [
    ("asymmetric", ": covariance of component 7 is not symmetric"),
    ("indefinite", ": covariance of component 7 is not positive definite"),
    ("no_duration", ": 'duration'"),
])
def test_a_bad_dense_covariance_is_an_error_naming_the_component(tmp_path, case, message):
    rng = np.random.default_rng(5)
    C = _spd(rng, 15, 0.1)
    if case == "asymmetric":
        C[0, 1] += 1e-3
    elif case == "indefinite":
        w, V = np.linalg.eigh(C)
        w[0] = -1e-6 * w.max()
        C = (V * w) @ V.T
        C = 0.5 * (C + C.T)
    p = _dense(tmp_path / f"{case}.npz", [(7, 2, 2.0, 1.0, rng.standard_normal(15), C)])
    if case == "no_duration":
        meta, arrays = _parts(p)
        del meta["components"][0]["duration"]
        np.savez(p, metadata=np.array(json.dumps(meta)), **arrays)
    with pytest.raises(ValueError, match="^" + re.escape(f"library file '{p}'{message}")):
        SkillLibrary.load(p)


def test_a_compressed_library_file_loads(lib, good, tmp_path):
    """Entries may be compressed (within MAX_EXPANSION of their bytes): np.savez_compressed of the same parts."""
    meta, arrays = _parts(good)
    p = tmp_path / "compressed.npz"
    np.savez_compressed(p, metadata=np.array(json.dumps(meta)), **arrays)
    assert p.stat().st_size < good.stat().st_size
    back = SkillLibrary.load(p).state()
    np.testing.assert_array_equal(back.scale.pooled, lib.state().scale.pooled)


def _dense_cov(rng, fix):
    C = _spd(rng, 15, 0.1)
    return fix(C) or C


def _with_min_eigenvalue(C, value):
    w, V = np.linalg.eigh(C)
    w[0] = value
    out = (V * w) @ V.T
    return 0.5 * (out + out.T)


@pytest.mark.parametrize("case, message", [
    ("asymmetric_1e-7", ": covariance of component 7 is not symmetric"),
    ("asymmetric_small_entry", ": covariance of component 7 is not symmetric"),
    ("indefinite_small", ": covariance of component 7 is not positive definite"),
    ("no_id", ": covariance of component 0 is not symmetric"),
    ("no_id_indefinite", ": covariance of component 0 is not positive definite"),
    ("id_text", ": component 0 id must be an integer >= 0, got 'x'"),
    ("age_negative", ": age must be an integer >= 0, got -1"),
])
def test_dense_covariances_are_checked_at_their_tolerances_naming_the_component(tmp_path, case, message):
    """Symmetric to rtol 1e-9 and atol 1e-12; eigenvalues above -1e-9 times the largest (at least 1)."""
    rng = np.random.default_rng(6)
    C = _spd(rng, 15, 0.1)
    cid, age = 7, 2
    if case == "asymmetric_1e-7":
        C[0, 1] *= 1 + 1e-7
    elif case == "asymmetric_small_entry":
        C[0, 5] = C[5, 0] = 1e-3
        C[0, 5] += 1e-10
    elif case in ("indefinite_small", "no_id_indefinite"):
        C = _with_min_eigenvalue(C, -1.5e-9)  # largest eigenvalue < 1: the tolerance is -1e-9
    elif case == "no_id":
        C[0, 1] += 1e-3
    elif case == "id_text":
        cid = "x"
    elif case == "age_negative":
        age = -1
    p = _dense(tmp_path / f"{case}.npz", [(cid if cid != "x" else 7, age, 2.0, 1.0, rng.standard_normal(15), C)])
    if case.startswith("no_id") or case == "id_text":
        meta, arrays = _parts(p)
        if case == "id_text":
            meta["components"][0]["id"] = "x"
        else:
            del meta["components"][0]["id"]
        np.savez(p, metadata=np.array(json.dumps(meta)), **arrays)
    with pytest.raises(ValueError, match="^" + re.escape(f"library file '{p}'{message}") + "$"):
        SkillLibrary.load(p)


def test_dense_covariances_within_rounding_are_accepted(tmp_path):
    """A smallest eigenvalue of -1e-10 of the largest (~100), asymmetry of 1e-15 relative: loaded, the scatter
    clipped at 0 in that direction (finite)."""
    rng = np.random.default_rng(7)
    C = _with_min_eigenvalue(_spd(rng, 15, 100.0), 0.0)
    C = _with_min_eigenvalue(C, -1e-10 * np.linalg.eigvalsh(C).max())
    C[0, 1] *= 1 + 1e-15
    st = SkillLibrary.load(_dense(tmp_path / "ok.npz", [(0, 1, 2.0, 1.0, rng.standard_normal(15), C)])).state()
    assert np.isfinite(st.components[0].cluster.factor).all()
    np.testing.assert_allclose(st.components[0].cluster.scatter, 2.0 * C, rtol=1e-9, atol=1e-8)


def test_save_appends_npz_and_syncs_before_renaming(lib, tmp_path, monkeypatch):
    import os

    assert lib.save(tmp_path / "lib") == tmp_path / "lib.npz" and (tmp_path / "lib.npz").is_file()
    assert lib.save(tmp_path / "other.npz") == tmp_path / "other.npz"
    calls = []
    real_fsync, real_replace = os.fsync, os.replace
    monkeypatch.setattr(os, "fsync", lambda fd: (calls.append("fsync"), real_fsync(fd))[1])
    monkeypatch.setattr(os, "replace", lambda a, b: (calls.append("replace"), real_replace(a, b))[1])
    lib.save(tmp_path / "lib.npz")
    assert calls[:2] == ["fsync", "replace"]


def test_a_fitted_library_whose_components_were_all_deleted_round_trips(tmp_path):
    import library_states as ls

    from drake_skills.library.scale import SharedScale

    cfg = LibraryConfig(n_basis_human=4, n_basis_robot=3)
    d = 2 * 4 + 1 * 3
    # as a real library whose components were all deleted: the scale counted the 9 demonstrations,
    # its pooled scatter (the sum of the components') is empty
    gone = SharedScale(9, np.zeros(d), np.full(d, 9.0), np.zeros((d, d)), 0.0)
    lib = ls.library(cfg, [], dim_human=2, dim_robot=1, next_id=5, n_seen=9, scale=gone)
    back = SkillLibrary.load(lib.save(tmp_path / "gone")).state()
    assert (back.dim_human, back.dim_robot, back.next_id, back.n_seen, back.components) == (2, 1, 5, 9, ())
    np.testing.assert_array_equal(back.scale.pooled, lib.state().scale.pooled)
    with np.load(tmp_path / "gone.npz") as z:
        assert z["means"].shape == (0, 11) and z["factors"].shape == (11, 0) and z["sub_factors"].shape == (11, 0)


def _entries_of(path, version=None, compress=False, overrides=None):
    """The .npy entries of a library file, rewritten with another header version or compression."""
    import io
    import zipfile

    out = {}
    with np.load(path, allow_pickle=False) as z:
        for k in z.files:
            buf = io.BytesIO()
            np.lib.format.write_array(buf, z[k], version=version)
            out[f"{k}.npy"] = buf.getvalue()
    out.update(overrides or {})
    p = path.with_name(path.stem + "_re.npz")
    with zipfile.ZipFile(p, "w", compression=zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED) as zf:
        for name, data in out.items():
            zf.writestr(name, data)
    return p


def test_entries_with_version_2_headers_load(lib, good):
    p = _entries_of(good, version=(2, 0))
    np.testing.assert_array_equal(SkillLibrary.load(p).state().scale.pooled, lib.state().scale.pooled)


@pytest.mark.parametrize("compress", [False, True])
def test_an_entry_holding_less_than_its_header_declares_is_rejected_before_reading(good, compress):
    """The 'means' entry declares 100 float64 (800 bytes) but holds 100 random bytes (incompressible)."""
    import io

    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, "shape": (100,)})
    data = buf.getvalue() + np.random.default_rng(0).bytes(100)
    p = _entries_of(good, compress=compress, overrides={"means.npy": data})
    with pytest.raises(ValueError, match=re.escape("entry 'means' declares (100,) float64 (800 bytes) but the file "
                                                   "holds")):
        SkillLibrary.load(p)


def test_an_entry_declaring_an_overflowing_shape_is_rejected(good):
    """(2^33, 2^33) float64: 2^69 bytes, which a 64-bit product would wrap to 0."""
    import io

    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, "shape": (2 ** 33, 2 ** 33)})
    p = _entries_of(good, overrides={"means.npy": buf.getvalue()})
    with pytest.raises(ValueError, match=re.escape(f"entry 'means' declares ({2 ** 33}, {2 ** 33}) float64 "
                                                   f"({2 ** 69} bytes) but the file holds")):
        SkillLibrary.load(p)


def test_a_dense_file_warns_with_the_whole_message_naming_the_file(tmp_path, caplog):
    """The user sees the full warning: which file, why the scale is estimated, what is missing."""
    rng = np.random.default_rng(6)
    p = _dense(tmp_path / "old.npz", [(0, 1, 2.0, 1.0, rng.standard_normal(15), _spd(rng, 15, 0.1))], n_seen=2)
    with caplog.at_level("WARNING", logger="drake_skills.library.storage"):
        SkillLibrary.load(p)
    assert caplog.messages == [
        f"library file '{p}' has schema version < 3 (fixed Sigma_init scale): its shared scale is estimated from "
        "the stored components, and phase estimates need new demonstrations (no path lengths stored)"]


def test_a_dense_file_counts_its_demonstrations_as_stored_and_an_inconsistent_count_names_the_file(tmp_path):
    """The scale counts ``n_seen`` demonstrations (one demonstration is a valid library); a file whose count
    disagrees with its components (none seen, one component) is an error naming the file and the counts."""
    rng = np.random.default_rng(7)
    comp = (0, 1, 1.0, 1.0, rng.standard_normal(15), _spd(rng, 15, 0.1))
    st = storage.load_state(_dense(tmp_path / "one.npz", [comp], n_seen=1))
    assert st.n_seen == 1 and st.scale.n == 1 and len(st.components) == 1
    p = _dense(tmp_path / "none_seen.npz", [comp], n_seen=0)
    with pytest.raises(ValueError, match="^" + re.escape(
            f"library file '{p}' is inconsistent: the shared scale counted 1 demonstrations, the library has seen 0")):
        storage.load_state(p)
