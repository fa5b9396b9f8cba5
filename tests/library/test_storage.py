"""Library files: round trip, atomic writes, clear errors for bad files, no pickle."""
import json

import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.library import storage

from synthetic import synthetic_demo


@pytest.fixture(scope="module")
def lib():
    rng = np.random.default_rng(0)
    lib = SkillLibrary(LibraryConfig(delete_min_age=5))
    lib.partial_fit(synthetic_demo(3, rng))  # an outlier that gets deleted
    for i in range(18):
        lib.partial_fit(synthetic_demo(i % 3, rng))
    return lib


def test_round_trip_gives_identical_predictions(lib, tmp_path):
    p = tmp_path / "lib.npz"
    lib.save(p)
    lib2 = SkillLibrary.load(p)
    rng = np.random.default_rng(1)
    for task in range(3):
        h = synthetic_demo(task, rng).human
        r1, r2 = lib.recognize(h), lib2.recognize(h)
        assert r1.component == r2.component
        np.testing.assert_array_equal(r1.responsibilities, r2.responsibilities)
        np.testing.assert_array_equal(lib.predict_robot(h)[0], lib2.predict_robot(h)[0])
    assert lib2.history == lib.history
    assert any(e["event"] == "deleted" for e in lib2.history)
    assert lib2.config == lib.config
    # the loaded library keeps learning the same way
    d = synthetic_demo(0, rng)
    assert lib.__class__.load(p).partial_fit(d) == lib2.partial_fit(d)


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


def _rewrite(src, dst, **changes):
    with np.load(src, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["metadata"]))
    for k, v in changes.pop("meta", {}).items():
        meta[k] = v
    arrays["metadata"] = np.array(json.dumps(meta))
    arrays.update(changes)
    np.savez(dst, **arrays)


def test_bad_files_give_clear_errors(lib, tmp_path):
    good = tmp_path / "good.npz"
    lib.save(good)
    data = good.read_bytes()
    cases = {}
    (tmp_path / "truncated.npz").write_bytes(data[: len(data) // 2])
    cases["truncated.npz"] = "truncated"
    (tmp_path / "text.npz").write_text("hello")
    cases["text.npz"] = "truncated or not an .npz"
    np.savez(tmp_path / "foreign.npz", x=np.arange(3))
    cases["foreign.npz"] = "not a drake-skills library"
    _rewrite(good, tmp_path / "newer.npz", meta={"schema_version": storage.SCHEMA_VERSION + 1})
    cases["newer.npz"] = "newer"
    with np.load(good) as z:
        covs = z["covs"].copy()
        means = z["means"].copy()
    covs[0, 0, 1] += 1.0
    _rewrite(good, tmp_path / "asym.npz", covs=covs)
    cases["asym.npz"] = "not symmetric"
    means[1, 2] = np.nan
    _rewrite(good, tmp_path / "nan.npz", means=means)
    cases["nan.npz"] = "NaN"
    _rewrite(good, tmp_path / "shape.npz", means=means[:, :-1])
    cases["shape.npz"] = "shapes"
    _rewrite(good, tmp_path / "format.npz", meta={"format": "something else"})
    cases["format.npz"] = "not a drake-skills library"
    np.savez(tmp_path / "pickled.npz", metadata=np.array([{"a": 1}], dtype=object), means=means, covs=covs)
    cases["pickled.npz"] = "without pickle"
    for name, msg in cases.items():
        with pytest.raises(ValueError, match=msg) as e:
            SkillLibrary.load(tmp_path / name)
        assert name in str(e.value)
    with pytest.raises(FileNotFoundError):
        SkillLibrary.load(tmp_path / "missing.npz")


def test_empty_library_round_trips(tmp_path):
    p = tmp_path / "empty.npz"
    SkillLibrary().save(p)
    assert SkillLibrary.load(p).n_components == 0


def test_version_1_file_keeps_its_raw_arc_length(lib, tmp_path):
    """Schema 1 had no resample_tolerance: such a file loads with 0 (its behaviour); a schema 2 file keeps its value."""
    good = tmp_path / "good.npz"
    lib.save(good)
    with np.load(good, allow_pickle=False) as z:
        meta = json.loads(str(z["metadata"]))
    cfg = {k: v for k, v in meta["config"].items() if k != "resample_tolerance"}
    _rewrite(good, tmp_path / "v1.npz", meta={"schema_version": 1, "config": cfg})
    old = SkillLibrary.load(tmp_path / "v1.npz")
    assert old.config.resample_tolerance == 0.0
    tolerant = SkillLibrary(LibraryConfig(resample_tolerance=0.1))
    rng = np.random.default_rng(2)
    for i in range(3):
        tolerant.partial_fit(synthetic_demo(i, rng))
    tolerant.save(tmp_path / "v2.npz")
    assert SkillLibrary.load(tmp_path / "v2.npz").config.resample_tolerance == 0.1
