"""Cost against the number of skills (issue 19): time(K) / time(5) at K = 5, 100 and 1000, measured in one run.

Libraries of K synthetic skills (:mod:`drake_skills.data.synthetic`: 3-D wrist paths
at least 1.5 apart, scatter 0.03, 7-joint robots; 3 demonstrations per skill, in a
row) are built first with the default ``LibraryConfig`` (or ``--config``). Then each
call is timed with the sizes interleaved (one call at each K in turn, repeated), so
that every K sees the same machine load, and each row gives the median and its ratio
to K = 5:

* ``partial_fit`` of a new demonstration of a taught skill;
* ``recognize(human, observed_fraction=1.0)``: a whole motion;
* ``recognize(beginning)``: 30-90 % of a motion, the phase estimated per component.

Also the largest library's file: save and load times and its size.

Each call is timed by the wall clock (``value``, ``ratio``) and by the CPU time of the
process (``cpu ms``, ``cpu ratio``): on a machine shared with other work, a call of a
few milliseconds is often preempted for a scheduler slice of several, which inflates
the wall-clock medians of the longer calls more than their cost; the CPU time is the
cost.
"""
from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np

from drake_skills.data.synthetic import skill_bank
from drake_skills.library.incremental import LibraryConfig, SkillLibrary

SIZES = (5, 100, 1000)
QUICK_SIZES = (5, 20, 50)
#: The goals of issue 19 on the ratio time(K) / time(5).
GOALS = {100: 1.5, 1000: 2.0}


def _library(K: int, rng, config: LibraryConfig):
    bank = skill_bank(K, rng)
    lib = SkillLibrary(config)
    for k in range(K):
        for _ in range(3):
            lib.partial_fit(bank.demo(k, rng))
    return lib, bank


def _probe(bank, rng):
    """A new demonstration of a taught skill and a beginning (30-90 %) of another one."""
    demo = bank.demo(int(rng.integers(bank.n_skills)), rng)
    human = bank.demo(int(rng.integers(bank.n_skills)), rng).human
    return demo, human[: max(5, int(rng.uniform(0.3, 0.9) * len(human)))]


def run(quick: bool = False, config=None) -> list[dict]:
    """``config``: a SimConfig whose ``library`` is measured (default ``LibraryConfig()``)."""
    lib_config = config.library if config is not None else LibraryConfig()
    sizes = QUICK_SIZES if quick else SIZES
    repeats = 20 if quick else 150
    rng = np.random.default_rng(0)
    libs = {K: _library(K, rng, lib_config) for K in sizes}
    found = {K: libs[K][0].n_components for K in sizes}  # as built (the timed updates add demonstrations)
    calls = {
        "partial_fit": lambda lib, demo, part: lib.partial_fit(demo),
        "recognize (whole motion)": lambda lib, demo, part: lib.recognize(demo.human, observed_fraction=1.0),
        "recognize (beginning, phase estimated)": lambda lib, demo, part: lib.recognize(part),
    }
    wall = {(name, K): [] for name in calls for K in sizes}
    cpu = {(name, K): [] for name in calls for K in sizes}
    for _ in range(repeats):
        for K in sizes:
            lib, bank = libs[K]
            demo, part = _probe(bank, rng)
            for name, call in calls.items():
                c0, t0 = time.process_time(), time.perf_counter()
                call(lib, demo, part)
                wall[name, K].append(time.perf_counter() - t0)
                cpu[name, K].append(time.process_time() - c0)
    rows = []
    base = sizes[0]
    for name in calls:
        ms0, cpu0 = (1e3 * float(np.median(t[name, base])) for t in (wall, cpu))
        for K in sizes:
            ms, cms = (1e3 * float(np.median(t[name, K])) for t in (wall, cpu))
            goal = GOALS.get(K) if not quick else None
            rows.append({"name": f"{name}, K={K} (found {found[K]})", "value": round(ms, 3),
                         "unit": "ms", "ratio": round(ms / ms0, 2) if K != base else "",
                         "cpu ms": round(cms, 3), "cpu ratio": round(cms / cpu0, 2) if K != base else "",
                         "goal": f"ratio <= {goal}" if goal else "",
                         "notes": f"median of {repeats}, sizes interleaved; ratio = time(K) / time(K={base})"})
    K = sizes[-1]
    lib = libs[K][0]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "library.npz"
        save, load = [], []
        for _ in range(3):
            t0 = time.perf_counter()
            lib.save(path)
            t1 = time.perf_counter()
            SkillLibrary.load(path)
            save.append(t1 - t0)
            load.append(time.perf_counter() - t1)
        size = os.path.getsize(path)
    note = f"{lib.n_components} components, {lib.n_seen} demonstrations, {lib.state().n_weights} weights each"
    rows.append({"name": f"save, K={K}", "value": round(1e3 * float(np.median(save)), 1), "unit": "ms",
                 "notes": note + " (fsync included)"})
    rows.append({"name": f"load, K={K}", "value": round(1e3 * float(np.median(load)), 1), "unit": "ms",
                 "notes": note + " (every array checked before it is read)"})
    rows.append({"name": f"file size, K={K}", "value": round(size / 2 ** 20, 2), "unit": "MiB", "notes": note})
    return rows
