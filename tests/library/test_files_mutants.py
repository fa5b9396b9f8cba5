"""``SkillLibrary.update_file`` in this process: the behaviours `make mutate` found untested (issue 20).

The concurrency tests run ``update_file`` in other processes, which mutmut cannot see;
these check, in-process, what it passes on: each demonstration's workspace, the config
of a new file, the refusal of a different config for an existing one, the lock's
time-out, and the arguments of ``on_update``.
"""
import fcntl
import os
import re
import threading

import numpy as np
import pytest

from drake_skills import Demonstration, LibraryConfig, SkillLibrary
from drake_skills._lock import LockTimeout, lock_path
from drake_skills.promp.preprocessing import Workspace

from synthetic import synthetic_demo

SMALL = dict(n_samples=30, n_basis_human=5, n_basis_robot=5)
LO, HI = np.array([-1.0, 2.0, 0.5]), np.array([3.0, 4.0, 1.5])


def _demos(n, seed=0):
    rng = np.random.default_rng(seed)
    return [synthetic_demo(i % 2, rng, T=30) for i in range(n)]


def _raw(demo, ws):
    """``demo`` in the raw units that ``ws`` normalizes back to it."""
    return Demonstration(t=demo.t, human=ws.lower + demo.human * (ws.upper - ws.lower) / ws.scale, robot=demo.robot,
                         task=demo.task, name=demo.name)


def _means(lib):
    return [c.mean for c in lib.components]


def test_update_file_normalizes_each_demonstration_with_its_own_workspace(tmp_path):
    demos = _demos(3)
    ws = [Workspace(LO, HI), Workspace(LO - 1.0, HI + 2.0), Workspace(LO, HI + 5.0)]
    ref = SkillLibrary(LibraryConfig(**SMALL))
    for d in demos:
        ref.partial_fit(d)
    lib, _ = SkillLibrary.update_file(tmp_path / "lib", [_raw(d, w) for d, w in zip(demos, ws)], workspace=ws,
                                      config=LibraryConfig(**SMALL))
    assert len(lib.components) == len(ref.components)
    for a, b in zip(_means(lib), _means(ref)):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)
    # one workspace for all
    one = Workspace(LO, HI)
    lib1, _ = SkillLibrary.update_file(tmp_path / "one", [_raw(d, one) for d in demos], workspace=one,
                                       config=LibraryConfig(**SMALL))
    for a, b in zip(_means(lib1), _means(ref)):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)
    # and without it the raw units are learned as they are: different moments (the check above can fail)
    raw, _ = SkillLibrary.update_file(tmp_path / "raw", [_raw(d, one) for d in demos], config=LibraryConfig(**SMALL))
    assert not np.allclose(_means(raw)[0][:15], _means(ref)[0][:15], atol=0.1)


def test_update_file_refuses_a_workspace_list_of_the_wrong_length_and_writes_nothing(tmp_path):
    p = tmp_path / "lib.npz"
    with pytest.raises(ValueError, match=r"^2 workspaces for 3 demonstrations$"):
        SkillLibrary.update_file(p, _demos(3), workspace=(Workspace(LO, HI), None))
    assert not p.exists()


def test_update_file_starts_a_new_file_with_the_given_config_and_refuses_another_for_an_existing_one(tmp_path):
    p = tmp_path / "lib.npz"
    config = LibraryConfig(**SMALL)
    lib, _ = SkillLibrary.update_file(p, _demos(1), config=config)
    assert lib.config.dict() == config.dict() != LibraryConfig().dict()
    assert SkillLibrary.load(p).config.dict() == config.dict()
    # the same config again, or none, extends the file
    lib, _ = SkillLibrary.update_file(p, _demos(1, seed=1), config=LibraryConfig(**SMALL))
    lib, _ = SkillLibrary.update_file(p, _demos(1, seed=2))
    assert lib.n_seen == 3 and SkillLibrary.load(p).n_seen == 3
    before = p.read_bytes()
    msg = rf"^library file '{re.escape(str(p))}' exists with its own config; a config applies to a new library only$"
    with pytest.raises(ValueError, match=msg):
        SkillLibrary.update_file(p, _demos(1, seed=3), config=LibraryConfig())
    assert p.read_bytes() == before


def test_update_file_calls_on_update_with_index_demonstration_update_and_library(tmp_path):
    demos = _demos(3)
    calls = []
    lib, updates = SkillLibrary.update_file(tmp_path / "lib", demos, config=LibraryConfig(**SMALL),
                                            on_update=lambda *a: calls.append((a, a[3].n_seen)))
    assert [c[0][0] for c in calls] == [0, 1, 2]
    assert all(c[0][1] is d for c, d in zip(calls, demos))
    assert all(c[0][2] is u for c, u in zip(calls, updates))  # each call gets that demonstration's update
    assert all(c[0][3] is lib for c in calls)
    assert [c[1] for c in calls] == [1, 2, 3]  # called after each demonstration, not at the end


def test_update_file_gives_up_on_a_lock_held_elsewhere_after_its_timeout_and_writes_nothing(tmp_path):
    p = tmp_path / "lib.npz"
    SkillLibrary.update_file(p, _demos(1), config=LibraryConfig(**SMALL))
    before = p.read_bytes()
    fd = os.open(lock_path(p), os.O_RDWR)  # another open file description: flock conflicts as another process's
    fcntl.flock(fd, fcntl.LOCK_EX)
    os.pwrite(fd, b"4242\n", 0)
    release = threading.Timer(3.0, fcntl.flock, (fd, fcntl.LOCK_UN))  # so that a timeout ignored cannot hang
    release.start()
    lock = re.escape(str(lock_path(p)))
    msg = rf"^'{re.escape(str(p))}' is locked by process 4242 for more than 0.1 s \(lock file '{lock}'\)$"
    try:
        with pytest.raises(LockTimeout, match=msg):
            SkillLibrary.update_file(p, _demos(1, seed=1), timeout=0.1)
    finally:
        release.cancel()
        release.join()
        fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)
    assert p.read_bytes() == before
