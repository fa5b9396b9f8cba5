"""Library files that are well-formed but wrong: inconsistent dimensions and sums, huge declared arrays, short entries.

Every one is refused by ``SkillLibrary.load`` with the file and the reason in the message,
before anything large is allocated (issue 16).
"""
import json

import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary

from synthetic import synthetic_demo


@pytest.fixture(scope="module")
def lib():
    rng = np.random.default_rng(0)
    lib = SkillLibrary(LibraryConfig(delete_min_age=5))
    for i in range(18):
        lib.partial_fit(synthetic_demo(i % 3, rng))
    assert any(c.subclusters[1] is not None for c in lib.state().components)
    return lib


def _rewrite(src, dst, **changes):
    """Copy the library file ``src`` to ``dst`` with some arrays or metadata keys (``meta={...}``) replaced."""
    with np.load(src, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["metadata"]))
    meta.update(changes.pop("meta", {}))
    arrays["metadata"] = np.array(json.dumps(meta))
    arrays.update(changes)
    np.savez(dst, **arrays)


def test_inconsistent_dimensions_and_sums_are_rejected_naming_the_file_and_the_reason(lib, tmp_path):
    """Crafted files whose arrays have the declared shapes but disagree with each other or with the metadata."""
    good = tmp_path / "good.npz"
    lib.save(good)
    with np.load(good) as z:
        pooled, sub_means = z["pooled"].copy(), z["sub_means"].copy()
        meta = json.loads(str(z["metadata"]))
    scale = dict(meta["scale"])
    cases = {}
    _rewrite(good, tmp_path / "pooled.npz", pooled=pooled + 1e-3 * np.trace(pooled) * np.eye(len(pooled)))
    cases["pooled.npz"] = "pooled scatter differs from the sum of the components' scatters"
    _rewrite(good, tmp_path / "dof.npz", meta={"scale": {**scale, "dof": scale["dof"] + 2.0}})
    cases["dof.npz"] = "degrees of freedom"
    _rewrite(good, tmp_path / "count.npz", meta={"scale": {**scale, "n": scale["n"] + 1}})
    cases["count.npz"] = "counted .* demonstrations, the library has seen"
    two = [i for i, c in enumerate(meta["components"]) if c["subclusters"][1] is not None][0]
    sub_means[two, 1] += 1.0
    _rewrite(good, tmp_path / "sub.npz", sub_means=sub_means)
    cases["sub.npz"] = "sub-clusters' mean differs"
    config = dict(meta["config"], workspace={"lower": [0.0, 0.0], "upper": [1.0, 1.0], "scale": 10.0})
    _rewrite(good, tmp_path / "workspace.npz", meta={"config": config})
    cases["workspace.npz"] = "workspace is 2-D but dim_human is 3"
    _rewrite(good, tmp_path / "dims.npz", meta={"dim_robot": meta["dim_robot"] - 1})
    cases["dims.npz"] = "'means' has shape .*, the metadata says"
    for name, msg in cases.items():
        with pytest.raises(ValueError, match=msg) as e:
            SkillLibrary.load(tmp_path / name)
        assert name in str(e.value), str(e.value)
    SkillLibrary.load(good)  # the untouched file is consistent


def test_a_file_declaring_huge_arrays_is_refused_before_anything_is_allocated(lib, tmp_path, monkeypatch):
    """A few-MB file whose metadata declares over 1 GiB of arrays: refused from the metadata, no array read."""
    good = tmp_path / "good.npz"
    lib.save(good)
    with np.load(good) as z:
        meta = json.loads(str(z["metadata"]))
    comp = meta["components"][0]
    K, d = 100, 3 * 200 + 7 * 200        # every scatter factor of full rank d: 100 x 32 MB
    many = [dict(comp, id=i, rank=d, subclusters=[dict(comp["subclusters"][0]), None]) for i in range(K)]
    config = dict(meta["config"], n_basis_human=200, n_basis_robot=200)   # the largest a config accepts
    _rewrite(good, tmp_path / "huge.npz", meta={"components": many, "next_id": K, "config": config,
                                               "dim_human": 3, "dim_robot": 7, "n_seen": K,
                                               "gain": None})  # (a gain of the old basis would be refused first)
    assert (tmp_path / "huge.npz").stat().st_size < 10 * 2 ** 20
    read = []
    real_load = np.load
    monkeypatch.setattr(np, "load", lambda *a, **k: read.append(a) or real_load(*a, **k))
    with pytest.raises(ValueError, match="huge.npz.*MiB of arrays, more than") as e:
        SkillLibrary.load(tmp_path / "huge.npz")
    assert len(read) == 1, read  # only the metadata entry was read
    assert "MAX_ARRAY_BYTES" in str(e.value)


def test_an_entry_shorter_than_its_header_says_is_refused_before_it_is_read(lib, tmp_path):
    import zipfile

    good = tmp_path / "good.npz"
    lib.save(good)
    bad = tmp_path / "short.npz"
    with zipfile.ZipFile(good) as zin, zipfile.ZipFile(bad, "w") as zout:
        for info in zin.infolist():
            data = zin.read(info)
            if info.filename == "pooled.npy":
                data = data[: len(data) // 3]  # the header still declares (d, d)
            zout.writestr(info.filename, data)
    with pytest.raises(ValueError, match=r"short.npz.: entry 'pooled' declares") as e:
        SkillLibrary.load(bad)
    assert "but the file holds" in str(e.value)
