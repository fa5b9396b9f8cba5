"""One library file, many writers: no demonstration is lost, and a writer killed mid-save never corrupts it."""
import multiprocessing as mp
import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills._lock import FileLock, LockTimeout, lock_path
from drake_skills.library import storage
from drake_skills.library.storage import LibraryChangedError

import writers
from synthetic import synthetic_demo

#: Kills of the kill test (>= 50; DRAKE_SKILLS_KILLS raises it for a longer run).
KILLS = max(50, int(os.environ.get("DRAKE_SKILLS_KILLS", "50")))


@pytest.fixture(scope="module")
def ctx():
    """Forkserver: writers are forked from a clean server that has the library imported already.

    The server ignores the parent's sys.path (Python 3.11), so it gets the test directory
    through PYTHONPATH to import ``writers`` once, not in every writer (~1 s each); the learn
    command's modules (pydrake's yaml among them) are preloaded for the same reason.
    """
    c = mp.get_context("forkserver")
    c.set_forkserver_preload(["writers", "drake_skills.cli", "drake_skills.commands.learn", "drake_skills.sim.config",
                            "drake_skills.data.demos"])
    tests = str(Path(writers.__file__).parent)
    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = tests + (os.pathsep + old if old else "")
    try:
        from multiprocessing import forkserver

        forkserver.ensure_running()
    finally:
        if old is None:
            del os.environ["PYTHONPATH"]
        else:
            os.environ["PYTHONPATH"] = old
    return c


def _demos(n, seed, noise=1.0):
    rng = np.random.default_rng(seed)
    return [synthetic_demo(i % 4, rng, noise=noise) for i in range(n)]


def test_save_refuses_a_file_another_writer_saved_since_it_was_loaded(tmp_path):
    p = tmp_path / "shared.npz"
    demos = _demos(3, 0)
    SkillLibrary().save(p)
    a, b = SkillLibrary.load(p), SkillLibrary.load(p)
    assert a.generation == b.generation == 1
    a.partial_fit(demos[0])
    a.save(p)
    saved = p.read_bytes()
    b.partial_fit(demos[1])
    with pytest.raises(LibraryChangedError) as e:
        b.save(p)
    msg = str(e.value)
    assert "shared.npz" in msg and "generation 1" in msg and "generation 2" in msg and "update_file" in msg, msg
    assert p.read_bytes() == saved  # nothing written
    assert SkillLibrary.load(p).n_seen == 1
    # the writer that saved keeps saving (its generation follows the file) ...
    a.partial_fit(demos[2])
    a.save(p)
    assert SkillLibrary.load(p).n_seen == 2 and storage.file_generation(p) == 3
    # ... and an explicit expected_generation=None overwrites, as asked
    b.save(p, expected_generation=None)
    assert SkillLibrary.load(p).n_seen == 1 and storage.file_generation(p) == 4


def test_save_refuses_when_the_loaded_file_was_removed_and_accepts_a_new_path(tmp_path):
    p = tmp_path / "lib.npz"
    SkillLibrary().save(p)
    lib = SkillLibrary.load(p)
    p.unlink()
    with pytest.raises(LibraryChangedError, match="was removed"):
        lib.save(p)
    assert lib.save(tmp_path / "other.npz") == tmp_path / "other.npz"  # another file: no check


def test_files_without_a_generation_count_as_generation_zero(tmp_path):
    import json

    p = tmp_path / "old.npz"
    SkillLibrary().save(p)
    with np.load(p, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["metadata"]))
    del meta["generation"]
    arrays["metadata"] = np.array(json.dumps(meta))
    np.savez(p, **arrays)
    lib = SkillLibrary.load(p)
    assert lib.generation == 0
    lib.save(p)
    assert storage.file_generation(p) == 1


def test_update_file_leaves_the_file_as_it_was_when_a_demonstration_is_bad(tmp_path):
    p = tmp_path / "lib.npz"
    SkillLibrary.update_file(p, _demos(2, 1))
    before = p.read_bytes()
    good, bad = _demos(2, 2)
    from drake_skills import Demonstration

    still = Demonstration(t=bad.t, human=np.repeat(bad.human[:1], len(bad.t), axis=0), robot=bad.robot)
    with pytest.raises(ValueError, match="does not move"):
        SkillLibrary.update_file(p, [good, still])
    assert p.read_bytes() == before


def test_an_unlocked_reader_sees_one_version_whole_while_a_save_replaces_the_file(tmp_path, monkeypatch):
    """``learn --library`` reads the file before it takes the lock: a save landing between the reader's headers and
    its arrays must not mix two versions (the reader keeps the version it opened)."""
    p = tmp_path / "lib.npz"
    demos = _demos(6, 4, noise=5.0)
    SkillLibrary(LibraryConfig(**writers.ONE_COMPONENT_PER_DEMO)).fit(demos[:2]).save(p)
    newer = SkillLibrary.load(p)
    newer.partial_fit(demos[2])
    newer.save(tmp_path / "newer.npz")
    real_load = np.load

    def replaced_meanwhile(*args, **kw):  # another writer's save lands after the reader's first look
        os.replace(tmp_path / "newer.npz", p) if (tmp_path / "newer.npz").exists() else None
        return real_load(*args, **kw)

    monkeypatch.setattr(np, "load", replaced_meanwhile)
    lib = SkillLibrary.load(p)
    assert not (tmp_path / "newer.npz").exists()  # the replace happened during the load
    assert lib.n_seen == 2 and lib.n_components == 2  # the version it opened, whole
    assert SkillLibrary.load(p).n_seen == 3


def test_the_lock_times_out_naming_the_holder_and_is_reentrant(tmp_path, ctx):
    p = tmp_path / "lib.npz"
    ready, release = ctx.Event(), ctx.Event()
    holder = ctx.Process(target=_hold_lock, args=(str(p), ready, release))
    holder.start()
    try:
        assert ready.wait(30)
        t0 = time.monotonic()
        with pytest.raises(LockTimeout, match=f"locked by process {holder.pid}"):
            with FileLock(p, timeout=0.2):
                pass
        assert time.monotonic() - t0 >= 0.2
    finally:
        release.set()
        holder.join(30)
    with FileLock(p, timeout=5), FileLock(p, timeout=0):  # reentrant in one process
        assert lock_path(p).exists()


def _hold_lock(path, ready, release):
    with FileLock(path):
        ready.set()
        release.wait(30)


def _run_writers(ctx, target, path, chunks):
    barrier = ctx.Barrier(len(chunks))
    procs = [ctx.Process(target=target, args=(str(path), chunk, barrier)) for chunk in chunks]
    for pr in procs:
        pr.start()
    for pr in procs:
        pr.join(120)
    assert all(pr.exitcode == 0 for pr in procs), [pr.exitcode for pr in procs]


def test_four_concurrent_writers_lose_no_demonstration(tmp_path, ctx):
    """4 processes each fold in 6 demonstrations of their own, one load-extend-save at a time, all at once."""
    demos = _demos(24, 3, noise=5.0)  # goals scattered over the workspace: 24 different motions
    chunks = [demos[i::4] for i in range(4)]
    p = tmp_path / "shared.npz"
    _run_writers(ctx, writers.extend_one_at_a_time, p, chunks)
    lib = SkillLibrary.load(p)
    assert lib.n_seen == 24 and lib.generation == 24  # 24 saves, none replaced another's
    created = [e for e in lib.history if e["event"] == "created"]
    assert sorted(e["demo"] for e in created) == list(range(24))
    # every demonstration is in the result: its weights are the mean of a component of its own
    means = np.stack([c.mean for c in lib.components])
    for d in demos:
        dist = np.abs(means - lib.encode(d)).max(axis=1)
        assert dist.min() < 1e-9 * (1 + np.abs(means).max()), d.name
    # and the shared totals counted each exactly once (order-free: the mean of all 24)
    W = np.stack([lib.encode(d) for d in demos])
    np.testing.assert_allclose(lib.state().scale.total_mean, W.mean(axis=0), rtol=1e-9, atol=1e-9)


def test_the_check_above_finds_the_demonstrations_unlocked_writers_lose(tmp_path):
    """Control: two writers interleaved without the lock and the generation check lose work (as issue 16 found).

    The interleaving is forced (both load, then both save), so the loss is certain, not a race.
    """
    demos = _demos(4, 3)
    p = tmp_path / "shared.npz"
    SkillLibrary().fit(demos[:2]).save(p)
    a, b = SkillLibrary.load(p), SkillLibrary.load(p)
    a.partial_fit(demos[2])
    b.partial_fit(demos[3])
    a.save(p, expected_generation=None)
    b.save(p, expected_generation=None)  # last writer wins
    assert SkillLibrary.load(p).n_seen == 3  # one of the 4 demonstrations is gone


def test_a_writer_killed_at_random_moments_never_leaves_a_corrupt_file(tmp_path, ctx):
    """SIGKILL a process saving a growing library >= 50 times: the file always loads and equals a saved version."""
    p = tmp_path / "lib.npz"
    rng = np.random.default_rng(7)
    reference = [SkillLibrary().state()]  # reference[k]: the library after k demonstrations of the stream
    ref_lib = SkillLibrary()
    loads = interrupted = 0
    seen = set()
    for kill in range(KILLS):
        started = ctx.Event()
        pr = ctx.Process(target=writers.grow_forever, args=(str(p), 100_000, started))
        pr.start()
        assert started.wait(30)
        time.sleep(float(rng.uniform(0.0, 0.05)))  # after its first save: during one of the next few (~10 ms each)
        os.kill(pr.pid, signal.SIGKILL)
        pr.join(30)
        assert pr.exitcode == -signal.SIGKILL, pr.exitcode
        interrupted += any(tmp_path.glob(".lib.npz.*.tmp"))  # killed mid-save (the next save removes it)
        if not p.exists():
            continue
        lib = SkillLibrary.load(p)  # never raises: the file is whole
        loads += 1
        k = lib.n_seen
        while len(reference) <= k:
            ref_lib.partial_fit(writers.stream_demo(len(reference) - 1))
            reference.append(ref_lib.state())
        got, want = lib.state(), reference[k]
        assert [c.id for c in got.components] == [c.id for c in want.components]
        for a, b in zip(got.components, want.components):
            np.testing.assert_array_equal(a.mean, b.mean)
            np.testing.assert_array_equal(a.cluster.scatter, b.cluster.scatter)
            assert a.age == b.age and a.support == b.support
        np.testing.assert_array_equal(got.scale.pooled, want.scale.pooled)
        assert got.history == want.history
        seen.add(k)
    print(f"{KILLS} kills: {loads} loads, every one a saved version ({len(seen)} distinct, up to "
          f"{max(seen, default=0)} demonstrations); {interrupted} kills landed mid-save")
    assert loads >= KILLS - 5 and len(seen) >= 10


def _demo_folder(folder: Path, demos) -> Path:
    from drake_skills.data.demos import save_npz

    folder.mkdir(parents=True)
    for i, d in enumerate(demos):
        save_npz(d, folder / f"demo_{i:02d}.npz")
    return folder


def test_four_concurrent_learn_commands_extending_one_library_lose_no_demonstration(tmp_path, ctx):
    """Four `drake-skills learn DIR --library shared/library.npz --out shared` at once: 2 + 4 x 5 demonstrations."""
    cfg = tmp_path / "one_per_demo.yaml"
    cfg.write_text("".join(f"{k}: {v}\n" for k, v in writers.ONE_COMPONENT_PER_DEMO.items()))
    demos = _demos(22, 11, noise=5.0)
    shared = tmp_path / "shared"
    from drake_skills.cli import main

    assert main(["learn", str(_demo_folder(tmp_path / "first", demos[:2])), "--out", str(shared),
                 "--config", str(cfg)]) == 0
    lib_file = shared / "library.npz"
    argvs = [["learn", str(_demo_folder(tmp_path / f"w{i}", demos[2 + 5 * i:7 + 5 * i])), "--library",
              str(lib_file), "--out", str(shared), "--in-order"] for i in range(4)]
    barrier = ctx.Barrier(4)
    procs = [ctx.Process(target=writers.learn_cli, args=(argv, barrier)) for argv in argvs]
    for pr in procs:
        pr.start()
    for pr in procs:
        pr.join(120)
    assert [pr.exitcode for pr in procs] == [0, 0, 0, 0]
    lib = SkillLibrary.load(lib_file)
    assert lib.n_seen == 22 and lib.generation == 5 and lib.state().scale.n == 22
    means = np.stack([c.mean for c in lib.components])
    for d in demos:  # each demonstration is the mean of a component of its own
        assert np.abs(means - lib.encode(d)).max(axis=1).min() < 1e-9 * (1 + np.abs(means).max())


def test_learn_refuses_to_replace_a_file_that_is_not_the_library_it_extends_unless_forced(tmp_path, capsys):
    from drake_skills.cli import main

    folder = _demo_folder(tmp_path / "demos", _demos(4, 12))
    out = tmp_path / "out"
    assert main(["learn", str(folder), "--out", str(out)]) == 0
    before = (out / "library.npz").read_bytes()
    capsys.readouterr()
    assert main(["learn", str(folder), "--out", str(out)]) == 1  # a second learn from scratch: refused
    err = capsys.readouterr().err
    assert "library.npz' exists and is not the --library being extended" in err and "--force" in err, err
    assert (out / "library.npz").read_bytes() == before
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "library.npz").write_bytes(b"not a library")  # a corrupt or foreign file is not replaced either
    assert main(["learn", str(folder), "--out", str(foreign)]) == 1
    assert (foreign / "library.npz").read_bytes() == b"not a library"
    # extending it in place, and --force, are what the message offers
    assert main(["learn", str(folder), "--library", str(out / "library.npz"), "--out", str(out)]) == 0
    assert SkillLibrary.load(out / "library.npz").n_seen == 8
    assert main(["learn", str(folder), "--out", str(foreign), "--force"]) == 0
    assert SkillLibrary.load(foreign / "library.npz").n_seen == 4
