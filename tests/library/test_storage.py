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
    # the library and its lock file (kept: deleting a lock file lets two writers lock two files)
    assert sorted(x.name for x in tmp_path.iterdir()) == [".lib.npz.lock", "lib.npz"]


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
    assert sorted(x.name for x in tmp_path.iterdir()) == [".lib.npz.lock", "lib.npz"]


def _rewrite(src, dst, **changes):
    with np.load(src, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["metadata"]))
    for k, v in changes.pop("meta", {}).items():
        meta[k] = v
    arrays["metadata"] = np.array(json.dumps(meta))
    arrays.update(changes)
    np.savez(dst, **arrays)


@pytest.mark.parametrize("key, now, before", [
    ("adapt_to_noise", True, False),        # learned with the plain walk
    ("average_holds", True, False),         # its noisy motions walked with a vertex per noisy sample
    ("single_demo_quantile", 0.9, 1.0),     # learned with no single-demonstration rule
    ("split_within_share", 0.2, 1.0),       # learned splitting on the halves' distance alone
    ("keep_single_demos_apart", True, False),  # learned merging two components seen once within the quantile
    ("skip_false_starts", True, False),     # read every motion whole
    ("new_skill_weight", 1.0, 0.0),         # answered a beginning whenever a skill explained it
])
def test_a_file_written_before_an_optional_key_loads_as_it_was_learned_and_a_new_one_keeps_it(lib, tmp_path, key,
                                                                                              now, before):
    """The keys newer than schema 3 are optional: a file without one loads with the behaviour it was learned
    with (and keeps its components); a file written now keeps today's value."""
    assert getattr(lib.config, key) == now
    new = tmp_path / "new.npz"
    lib.save(new)
    assert getattr(SkillLibrary.load(new).config, key) == now
    with np.load(new, allow_pickle=False) as z:
        meta = json.loads(str(z["metadata"]))
    del meta["config"][key]
    _rewrite(new, tmp_path / "before.npz", meta={"config": meta["config"]})
    old = SkillLibrary.load(tmp_path / "before.npz")
    assert getattr(old.config, key) == before and type(getattr(old.config, key)) is type(now)
    assert [c.id for c in old.components] == [c.id for c in lib.components]


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
        pooled = z["pooled"].copy()
        means = z["means"].copy()
        factors = z["factors"].copy()
    pooled[0, 1] += 1.0
    _rewrite(good, tmp_path / "asym.npz", pooled=pooled)
    cases["asym.npz"] = "not symmetric"
    means[1, 2] = np.nan
    _rewrite(good, tmp_path / "nan.npz", means=means)
    cases["nan.npz"] = "NaN"
    _rewrite(good, tmp_path / "shape.npz", means=means[:, :-1])
    cases["shape.npz"] = "has shape"
    _rewrite(good, tmp_path / "rank.npz", factors=factors[:, :-1])
    cases["rank.npz"] = "'factors' has shape"
    _rewrite(good, tmp_path / "format.npz", meta={"format": "something else"})
    cases["format.npz"] = "not a drake-skills library"
    np.savez(tmp_path / "pickled.npz", metadata=np.array([{"a": 1}], dtype=object), means=means)
    cases["pickled.npz"] = "Python objects"
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


def _dense_file(lib, path, version):
    """``lib`` written in the dense layout of schema 1-2 (means and covariances, the fixed-scale settings)."""
    st = lib.state()
    cfg = lib.config.dict()
    cfg.update(sigma_init_human=0.5, sigma_init_robot=0.1, gating_floor=1.0, fast_forgetting=True)
    cfg.pop("adapt_to_noise")  # newer than schema 3
    cfg.pop("average_holds")
    if version < 2:
        cfg.pop("resample_tolerance")
    comps = lib.components
    meta = {"format": storage.FORMAT, "schema_version": version, "config": cfg, "dim_human": st.dim_human,
            "dim_robot": st.dim_robot, "next_id": st.next_id, "n_seen": st.n_seen, "history": list(st.history),
            "components": [{"id": c.id, "age": c.age, "support": c.support, "duration": c.duration} for c in comps]}
    np.savez(path, metadata=np.array(json.dumps(meta)), means=np.stack([c.mean for c in comps]),
             covs=np.stack([c.cov for c in comps]))


def test_schema_1_and_2_files_load_with_their_representation_and_the_same_answers(lib, tmp_path):
    """Older files (dense covariances, the fixed Sigma_init scale) load: their arc length and basis settings are
    kept (version 1 had no tolerance: 0), the retired settings dropped, the components and answers the same."""
    for version in (1, 2):
        p = tmp_path / f"v{version}.npz"
        _dense_file(lib, p, version)
        old = SkillLibrary.load(p)
        assert old.config.resample_tolerance == (0.0 if version == 1 else lib.config.resample_tolerance)
        assert old.config.adapt_to_noise is False and old.config.average_holds is False
        assert [c.id for c in old.components] == [c.id for c in lib.components]
        for a, b in zip(old.components, lib.components):
            np.testing.assert_allclose(a.mean, b.mean)
            assert a.age == b.age and a.support == b.support
        rng = np.random.default_rng(2)
        for task in range(3):
            h = synthetic_demo(task, rng).human
            assert old.recognize(h, observed_fraction=1.0).status in ("skill", "undecided")
    bad = tmp_path / "bad.npz"
    _dense_file(lib, bad, 2)
    with np.load(bad) as z:
        covs = z["covs"].copy()
        meta = str(z["metadata"])
    covs[0] = -np.eye(covs.shape[1])
    np.savez(bad, metadata=np.array(meta), means=np.stack([c.mean for c in lib.components]), covs=covs)
    with pytest.raises(ValueError, match="not positive definite") as e:
        SkillLibrary.load(bad)
    assert "bad.npz" in str(e.value)


def _npy_header_only(shape, dtype) -> bytes:
    """An .npy entry that declares ``shape`` and ``dtype`` and holds no data."""
    import io

    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": np.lib.format.dtype_to_descr(np.dtype(dtype)),
                                               "fortran_order": False, "shape": tuple(shape)})
    return buf.getvalue()


def _peak_bytes_while(fn):
    import tracemalloc

    tracemalloc.start()
    try:
        fn()
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak


def test_a_file_declaring_huge_metadata_is_rejected_without_allocating_it(tmp_path):
    """A metadata entry whose header claims 200 MB of text (under the 64 M character cap) but holds none."""
    import zipfile

    p = tmp_path / "huge_meta.npz"
    with zipfile.ZipFile(p, "w") as z:
        z.writestr("metadata.npy", _npy_header_only((), "<U50000000"))
    with pytest.raises(ValueError, match="declares") as e:
        peak = _peak_bytes_while(lambda: SkillLibrary.load(p))
    assert "huge_meta.npz" in str(e.value)
    peak = _peak_bytes_while(lambda: pytest.raises(ValueError, SkillLibrary.load, p))
    assert peak < 10 * 2 ** 20  # 200 MB declared, under 10 MB used
    with zipfile.ZipFile(p, "w") as z:  # above the cap: rejected by size alone
        z.writestr("metadata.npy", _npy_header_only((), f"<U{storage.MAX_METADATA_CHARS + 1}"))
    with pytest.raises(ValueError, match="metadata"):
        SkillLibrary.load(p)


def test_a_file_declaring_huge_arrays_that_agree_with_its_metadata_is_rejected_without_allocating(lib, tmp_path):
    """Metadata of 50 components of 9,800 weights (a 770 MB pooled scatter) and array headers to match, no data."""
    import zipfile

    good = tmp_path / "good.npz"
    lib.save(good)
    with np.load(good) as z:
        meta = json.loads(str(z["metadata"]))
    cfg = dict(meta["config"])
    meta.update(dim_human=1400, dim_robot=0, config=cfg)
    d = 1400 * cfg["n_basis_human"]
    assert d <= storage.MAX_WEIGHTS
    comp = dict(meta["components"][0], rank=0, subclusters=[dict(meta["components"][0]["subclusters"][0], rank=0),
                                                            None])
    meta["components"] = [dict(comp, id=i) for i in range(50)]
    meta["next_id"] = 50
    shapes = {"means": (50, d), "factors": (d, 0), "sub_means": (50, 2, d), "sub_factors": (d, 0),
              "total_mean": (d,), "total_m2": (d,), "pooled": (d, d)}
    p = tmp_path / "huge_arrays.npz"
    with zipfile.ZipFile(p, "w") as z:
        z.writestr("metadata.npy", _npy_bytes(np.array(json.dumps(meta))))
        for name, shape in shapes.items():
            z.writestr(f"{name}.npy", _npy_header_only(shape, "<f8"))
    with pytest.raises(ValueError, match=r"declares .* bytes\) but the file holds") as e:
        SkillLibrary.load(p)
    assert "huge_arrays.npz" in str(e.value)
    peak = _peak_bytes_while(lambda: pytest.raises(ValueError, SkillLibrary.load, p))
    assert peak < 20 * 2 ** 20  # 770 MB declared, under 20 MB used


def _npy_bytes(a) -> bytes:
    import io

    buf = io.BytesIO()
    np.lib.format.write_array(buf, a, allow_pickle=False)
    return buf.getvalue()
