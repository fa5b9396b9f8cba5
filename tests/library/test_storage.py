"""Library files: round trip, atomic writes, clear errors for bad files, no pickle."""
import json
import re

import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.library import storage

import library_files as lf
from synthetic import synthetic_demo


@pytest.fixture(scope="module")
def lib():
    rng = np.random.default_rng(0)
    lib = SkillLibrary(LibraryConfig(delete_min_age=5))
    lib.partial_fit(synthetic_demo(3, rng))  # an outlier that gets deleted
    for i in range(18):
        lib.partial_fit(synthetic_demo(i % 3, rng))
    return lib


def test_round_trip_restores_the_saved_library(lib, tmp_path):
    """Everything the saved library holds comes back: compared with the library before saving."""
    p = lib.save(tmp_path / "lib")
    assert p == tmp_path / "lib.npz"
    back = SkillLibrary.load(p)
    assert back.n_seen == lib.n_seen == 19
    assert back.config == lib.config
    assert back.history == lib.history
    assert any(e["event"] == "deleted" for e in back.history)
    assert (back.dim_human_, back.dim_robot_) == (3, 7)
    assert len(back.components) == len(lib.components) == 3
    for a, b in zip(lib.components, back.components):
        assert (b.id, b.age, b.support, b.duration, b.weight) == (a.id, a.age, a.support, a.duration, a.weight)
        np.testing.assert_array_equal(b.mean, a.mean)
        np.testing.assert_array_equal(b.cov, a.cov)
    # the next id is restored too: a novel motion gets the id the saved library would give it
    rng = np.random.default_rng(5)
    novel = synthetic_demo(3, rng)
    assert back.partial_fit(novel).created == (4,)


def test_round_trip_gives_identical_predictions_and_learning(lib, tmp_path):
    p = tmp_path / "lib.npz"
    lib.save(p)
    lib2 = SkillLibrary.load(p)
    rng = np.random.default_rng(1)
    for task in range(3):
        h = synthetic_demo(task, rng).human
        r1, r2 = lib.recognize(h), lib2.recognize(h)
        assert r1.component == r2.component
        np.testing.assert_array_equal(r1.responsibilities, r2.responsibilities)
        np.testing.assert_array_equal(r1.log_likelihoods, r2.log_likelihoods)
        np.testing.assert_array_equal(lib.predict_robot(h)[0], lib2.predict_robot(h)[0])
    # the loaded library keeps learning the same way as the one that was saved (on a copy of it)
    d = synthetic_demo(0, rng)
    assert SkillLibrary.load(p).partial_fit(d) == lib2.partial_fit(d)


def test_loaded_library_is_independent_of_the_file(lib, tmp_path):
    p = tmp_path / "lib.npz"
    lib.save(p)
    back = SkillLibrary.load(p)
    p.unlink()
    assert back.recognize(synthetic_demo(0, np.random.default_rng(2)).human).component is not None


def test_save_is_atomic_and_leaves_no_temp_files(lib, tmp_path):
    p = tmp_path / "lib.npz"
    lib.save(p)
    lib.save(p)
    assert sorted(x.name for x in tmp_path.iterdir()) == ["lib.npz"]


def test_save_gives_the_usual_file_mode_and_a_failed_save_keeps_the_old_file(lib, tmp_path, monkeypatch):
    import os

    p = tmp_path / "lib.npz"
    lib.save(p)
    mask = os.umask(0o022)
    os.umask(mask)
    assert (p.stat().st_mode & 0o777) == (0o666 & ~mask)  # not mkstemp's owner-only 0600
    before = p.read_bytes()

    def broken_savez(f, **arrays):
        f.write(b"partial")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", broken_savez)
    with pytest.raises(OSError, match="disk full"):
        lib.save(p)
    assert p.read_bytes() == before
    assert sorted(x.name for x in tmp_path.iterdir()) == ["lib.npz"]


def test_save_rejects_what_is_not_a_library(tmp_path):
    with pytest.raises(ValueError, match="save_library takes a SkillLibrary, got dict"):
        storage.save_library({}, tmp_path / "x.npz")


def test_empty_library_round_trips(tmp_path):
    p = tmp_path / "empty.npz"
    SkillLibrary(LibraryConfig(n_basis_human=7)).save(p)
    back = SkillLibrary.load(p)
    assert back.n_components == 0 and back.n_seen == 0 and back.history == ()
    assert back.config == LibraryConfig(n_basis_human=7)
    assert back.dim_human_ is None and back.dim_robot_ is None


def test_library_whose_components_were_all_deleted_keeps_its_counters(tmp_path):
    """No components left, but dimensions, the next id, n_seen and the history are kept."""
    cfg = LibraryConfig()
    meta = lf.metadata(cfg, [], dim_human=3, dim_robot=7, next_id=4, n_seen=9,
                       history=[{"event": "created", "id": 3, "demo": 0}])
    p = lf.write(tmp_path / "gone.npz", meta, np.zeros((0, 100)), np.zeros((0, 100, 100)))
    back = SkillLibrary.load(p)
    assert back.n_components == 0 and back.n_seen == 9
    assert back.history == ({"event": "created", "id": 3, "demo": 0},)
    assert back.n_human == 30 and back.has_robot
    assert back.partial_fit(synthetic_demo(0, np.random.default_rng(0))).created == (4,)


def test_version_1_file_keeps_its_raw_arc_length(lib, tmp_path):
    """Schema 1 had no resample_tolerance: such a file loads with 0 (its behaviour); a schema 2 file keeps its value."""
    good = tmp_path / "good.npz"
    lib.save(good)
    with np.load(good, allow_pickle=False) as z:
        meta = json.loads(str(z["metadata"]))
        means, covs = z["means"], z["covs"]
    meta.update(schema_version=1, config={k: v for k, v in meta["config"].items() if k != "resample_tolerance"})
    old = SkillLibrary.load(lf.write(tmp_path / "v1.npz", meta, means, covs))
    assert old.config.resample_tolerance == 0.0
    tolerant = SkillLibrary(LibraryConfig(resample_tolerance=0.1))
    rng = np.random.default_rng(2)
    for i in range(3):
        tolerant.partial_fit(synthetic_demo(i, rng))
    tolerant.save(tmp_path / "v2.npz")
    assert SkillLibrary.load(tmp_path / "v2.npz").config.resample_tolerance == 0.1


# ----------------------------------------------------------------------------- bad files
H, R = 3 * 10, 7 * 20  # weights of the default config with a 3-D human and 7 joints


def _good_parts(rng=None):
    """Two valid components (ids 0 and 2) of the default config, and their metadata."""
    rng = rng or np.random.default_rng(7)
    d = H + R
    A = rng.standard_normal((d, d))
    cov = A @ A.T / d + 0.1 * np.eye(d)
    comps = [lf.component(0, rng.standard_normal(d), cov, support=3.0, age=6, duration=1.2),
             lf.component(2, rng.standard_normal(d), 0.5 * cov, support=1.5, age=2, duration=0.8)]
    meta = lf.metadata(LibraryConfig(), comps, dim_human=3, dim_robot=7, next_id=3)
    means = np.stack([c["mean"] for c in comps])
    covs = np.stack([c["cov"] for c in comps])
    return meta, means, covs


def test_hand_written_valid_file_loads(tmp_path):
    """The baseline of the error tests below: the unmodified parts make a good library."""
    meta, means, covs = _good_parts()
    lib = SkillLibrary.load(lf.write(tmp_path / "ok.npz", meta, means, covs))
    assert [(c.id, c.age, c.support, c.duration) for c in lib.components] == [(0, 6, 3.0, 1.2), (2, 2, 1.5, 0.8)]
    np.testing.assert_array_equal(lib.components[1].cov, covs[1])


def _meta_with(**changes):
    meta, means, covs = _good_parts()
    meta.update(changes)
    return meta, means, covs


def _component_with(i, **changes):
    meta, means, covs = _good_parts()
    meta["components"][i].update(changes)
    return meta, means, covs


def _covs_with(fn):
    meta, means, covs = _good_parts()
    covs = covs.copy()
    fn(covs)
    return meta, means, covs


def _means_with(fn):
    meta, means, covs = _good_parts()
    means = means.copy()
    fn(means)
    return meta, means, covs


def _not_pd(covs):
    covs[1][:H, :H] -= 5.0 * np.eye(H)  # human block indefinite, beyond what the gating floor (1.0) hides


def _robot_block_not_pd(covs):
    covs[1][H:, H:] -= 5.0 * np.eye(R)  # only the robot block: the gating (human) factor still exists


def _human_block_hidden_by_floor(covs):
    """One eigenvalue -0.5 in the human block: the floored gating factor (floor 1.0) exists, the covariance is not PD."""
    S = covs[0][:H, :H]
    w, V = np.linalg.eigh(S)
    w[0] = -0.5
    covs[0][:H, :H] = 0.5 * ((V * w) @ V.T + ((V * w) @ V.T).T)
    covs[0][:H, H:] = 0.0
    covs[0][H:, :H] = 0.0


def _small_asymmetric_entry(covs):
    """An entry of 1e-3 made asymmetric by 1e-10: beyond rtol 1e-9 and atol 1e-12, within numpy's defaults."""
    covs[1][0, 5] = covs[1][5, 0] = 1e-3
    covs[1][0, 5] += 1e-10


def _set_min_eigenvalue(covs, k, relative):
    """Make the smallest eigenvalue of covs[k] equal to relative * trace / d (the tolerance is 1e-12)."""
    S = covs[k]
    w, V = np.linalg.eigh(S)
    w[0] = relative * np.sum(w) / len(w)
    S = (V * w) @ V.T
    covs[k] = 0.5 * (S + S.T)


def _shorter(which):
    meta, means, covs = _good_parts()
    if which == "means":
        return meta, means[:, :-1], covs
    return meta, means, covs[:, :-1]


def _metadata_array(value):
    meta, means, covs = _good_parts()
    return value, means, covs


METADATA_CASES = {
    "no_format": (lambda: _meta_with(format=None), "is not a drake-skills library (format tag None)"),
    "other_format": (lambda: _meta_with(format="something else"),
                     "is not a drake-skills library (format tag 'something else')"),
    "schema_missing": (lambda: _meta_with(schema_version=None), "schema_version missing or not an integer"),
    "schema_text": (lambda: _meta_with(schema_version="2"), "schema_version missing or not an integer"),
    "newer": (lambda: _meta_with(schema_version=storage.SCHEMA_VERSION + 1),
              f"has schema version {storage.SCHEMA_VERSION + 1}, newer than this drake-skills supports "
              f"({storage.SCHEMA_VERSION}): upgrade drake-skills"),
    "config_missing": (lambda: _meta_with(config=None), "bad metadata (TypeError"),
    "config_unknown_field": (lambda: _meta_with(config={**LibraryConfig().dict(), "magic": 1}),
                             "bad metadata (ValueError: unknown LibraryConfig fields: ['magic'])"),
    "config_bad_value": (lambda: _meta_with(config={**LibraryConfig().dict(), "gating_floor": -1.0}),
                         "bad metadata (ValueError: LibraryConfig.gating_floor must be positive"),
    "next_id_missing": (lambda: _meta_with(next_id=None), "bad metadata (TypeError"),
    "n_seen_text": (lambda: _meta_with(n_seen="many"), "bad metadata (ValueError"),
    "history_number": (lambda: _meta_with(history=3), "bad metadata (TypeError"),
    "components_missing": (lambda: _meta_with(components=None),
                           "bad metadata (TypeError: components must be a list, got NoneType)"),
    "components_number": (lambda: _meta_with(components=3), "bad metadata (TypeError: components must be a list, got int)"),
    "no_dimensions": (lambda: _meta_with(dim_human=None), "components but no dimensions"),
    "no_robot_dimension": (lambda: _meta_with(dim_robot=None), "components but no dimensions"),
    "wrong_dimension": (lambda: _meta_with(dim_human=2),
                        "arrays have shapes (2, 170), (2, 170, 170); metadata says 2 components of dimension 160"),
    "fewer_components": (lambda: _meta_with(components=_good_parts()[0]["components"][:1]),
                         "metadata says 1 components of dimension 170"),
    "component_no_age": (lambda: _component_with(1, age=None), "component 1 metadata is bad"),
    "component_no_support": (lambda: _component_with(0, support="lots"), "component 0 metadata is bad"),
    "duplicate_id": (lambda: _component_with(1, id=0), "component id 0 is duplicated or out of range"),
    "id_at_next_id": (lambda: _component_with(1, id=3), "component id 3 is duplicated or out of range"),
    "negative_id": (lambda: _component_with(0, id=-1), "component id -1 is duplicated or out of range"),
    "zero_support": (lambda: _component_with(1, support=0.0), "component 2 has support 0.0, age 2, duration 0.8"),
    "negative_support": (lambda: _component_with(0, support=-1.0),
                         "component 0 has support -1.0, age 6, duration 1.2"),
    "negative_age": (lambda: _component_with(1, age=-1), "component 2 has support 1.5, age -1, duration 0.8"),
    "asymmetric_1e-7": (lambda: _covs_with(lambda c: c.__setitem__((1, 0, 1), c[1, 0, 1] * (1 + 1e-7))),
                        "covariance of component 2 is not symmetric"),
    "asymmetric_small_entry": (lambda: _covs_with(_small_asymmetric_entry), "covariance of component 2 is not symmetric"),
    "negative_eigenvalue_1e-10": (lambda: _covs_with(lambda c: _set_min_eigenvalue(c, 1, -1e-10)),
                                  "covariance of component 2 is not positive definite"),
    "nan_duration": (lambda: _component_with(1, duration=float("nan")),
                     "component 2 has support 1.5, age 2, duration nan"),
    "inf_duration": (lambda: _component_with(0, duration=float("inf")),
                     "component 0 has support 3.0, age 6, duration inf"),
    "means_short": (lambda: _shorter("means"), "arrays have shapes (2, 169), (2, 170, 170)"),
    "covs_short": (lambda: _shorter("covs"), "arrays have shapes (2, 170), (2, 169, 170)"),
    "nan_mean": (lambda: _means_with(lambda m: m.__setitem__((1, 2), np.nan)),
                 "means or covariances contain NaN or inf"),
    "inf_cov": (lambda: _covs_with(lambda c: c.__setitem__((0, 3, 3), np.inf)),
                "means or covariances contain NaN or inf"),
    "asymmetric": (lambda: _covs_with(lambda c: c.__setitem__((1, 0, 1), c[1, 0, 1] + 1e-3)),
                   "covariance of component 2 is not symmetric"),
    "not_pd": (lambda: _covs_with(_not_pd), "covariance of component 2 is not positive definite"),
    "robot_block_not_pd": (lambda: _covs_with(_robot_block_not_pd),
                           "covariance of component 2 is not positive definite"),
    "negative_eigenvalue_under_floor": (lambda: _covs_with(_human_block_hidden_by_floor),
                                        "covariance of component 0 is not positive definite"),
    "metadata_number": (lambda: _metadata_array(np.array(3.0)), "metadata entry is not a JSON string"),
    "metadata_list": (lambda: _metadata_array(np.array(["{}", "{}"])), "metadata entry is not a JSON string"),
    "metadata_not_json": (lambda: _metadata_array(np.array("{not json")), "metadata is not valid JSON"),
    "metadata_json_list": (lambda: _metadata_array(np.array("[1, 2]")),
                           "is not a drake-skills library (format tag None)"),
}


@pytest.mark.parametrize("case", sorted(METADATA_CASES))
def test_inconsistent_file_is_rejected_with_a_message_naming_it(tmp_path, case):
    make, message = METADATA_CASES[case]
    meta, means, covs = make()
    p = lf.write(tmp_path / f"{case}.npz", meta, means, covs)
    with pytest.raises(ValueError, match=re.escape(message)) as e:
        SkillLibrary.load(p)
    assert str(e.value).startswith(f"library file '{p}'")


def test_smallest_eigenvalue_within_rounding_is_accepted(tmp_path):
    """An eigenvalue of -1e-13 trace/d (rounding of a PSD matrix) passes the check, at scale 1 and 100."""
    for scale in (1.0, 100.0):
        meta, means, covs = _good_parts()
        covs = covs * scale
        _set_min_eigenvalue(covs, 0, -1e-13)
        assert SkillLibrary.load(lf.write(tmp_path / f"psd{scale}.npz", meta, means, covs)).n_components == 2


def test_age_zero_and_integer_arrays_load(tmp_path):
    """Ages are counts (0 is valid); integer arrays in a hand-written file are read as floats."""
    meta, means, covs = _good_parts()
    meta["components"][0]["age"] = 0
    d = means.shape[1]
    lib = SkillLibrary.load(lf.write(tmp_path / "ints.npz", meta, np.zeros((2, d), dtype=int),
                                     np.stack([np.eye(d, dtype=int)] * 2)))
    assert lib.components[0].age == 0
    assert lib.components[0].mean.dtype == float and lib.components[1].cov.dtype == float


def test_one_component_library_round_trips_and_an_empty_one_stores_no_rows(tmp_path):
    rng = np.random.default_rng(3)
    one = SkillLibrary(LibraryConfig())
    one.partial_fit(synthetic_demo(0, rng))
    back = SkillLibrary.load(one.save(tmp_path / "one.npz"))
    np.testing.assert_array_equal(back.components[0].cov, one.components[0].cov)
    SkillLibrary().save(tmp_path / "empty.npz")
    with np.load(tmp_path / "empty.npz", allow_pickle=False) as z:
        assert z["means"].shape[0] == 0 and z["covs"].shape[0] == 0


def test_save_syncs_the_file_to_disk_before_renaming_it(lib, tmp_path, monkeypatch):
    import os

    calls = []
    real_fsync, real_replace = os.fsync, os.replace
    monkeypatch.setattr(os, "fsync", lambda fd: (calls.append("fsync"), real_fsync(fd))[1])
    monkeypatch.setattr(os, "replace", lambda a, b: (calls.append("replace"), real_replace(a, b))[1])
    lib.save(tmp_path / "lib.npz")
    assert calls == ["fsync", "replace"]


def test_symmetric_within_rounding_is_accepted(tmp_path):
    """Asymmetry at the level of float rounding (1e-15 relative) is not an error."""
    meta, means, covs = _covs_with(lambda c: c.__setitem__((1, 0, 1), c[1, 0, 1] * (1 + 1e-15)))
    assert SkillLibrary.load(lf.write(tmp_path / "ok.npz", meta, means, covs)).n_components == 2


def test_unreadable_files_give_clear_errors(lib, tmp_path):
    good = tmp_path / "good.npz"
    lib.save(good)
    data = good.read_bytes()
    meta, means, covs = _good_parts()
    cases = {}
    (tmp_path / "truncated.npz").write_bytes(data[: len(data) // 2])
    cases["truncated.npz"] = "is truncated or not an .npz file"
    (tmp_path / "text.npz").write_text("hello")
    cases["text.npz"] = "is truncated or not an .npz file"
    np.savez(tmp_path / "foreign.npz", x=np.arange(3))
    cases["foreign.npz"] = "is not a drake-skills library (missing ['covs', 'means', 'metadata'])"
    np.savez(tmp_path / "nocovs.npz", metadata=np.array(json.dumps(meta)), means=means)
    cases["nocovs.npz"] = "is not a drake-skills library (missing ['covs'])"
    np.savez(tmp_path / "pickled.npz", metadata=np.array([{"a": 1}], dtype=object), means=means, covs=covs)
    cases["pickled.npz"] = "cannot be read as .npz without pickle"
    for name, msg in cases.items():
        with pytest.raises(ValueError, match=re.escape(msg)) as e:
            SkillLibrary.load(tmp_path / name)
        assert str(e.value).startswith(f"library file '{tmp_path / name}' {msg}"), e.value
    with pytest.raises(FileNotFoundError, match=re.escape(f"library file '{tmp_path / 'missing.npz'}' does not exist")):
        SkillLibrary.load(tmp_path / "missing.npz")


def test_corrupt_member_of_a_zip_is_a_clear_error(lib, tmp_path):
    """A library file whose zip directory is intact but whose data is damaged (CRC mismatch) is reported
    as truncated or corrupt, naming the error, not as a zipfile traceback."""
    p = tmp_path / "damaged.npz"
    lib.save(p)
    data = bytearray(p.read_bytes())
    start = data.index(b"covs.npy") + 200  # inside the stored (uncompressed) covariance data
    data[start:start + 16] = bytes(16)
    p.write_bytes(bytes(data))
    with pytest.raises(ValueError) as e:
        SkillLibrary.load(p)
    assert str(e.value).startswith(f"library file '{p}' is truncated or not an .npz file (BadZipFile: "), e.value
