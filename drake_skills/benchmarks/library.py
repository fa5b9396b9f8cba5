"""Benchmarks of the incremental library (issue 3).

(a) ``partial_fit`` time with K = 5, 20, 100 components (gating 3 x 15,
    stacked 10 x 15 weights);
(b) ``recognize`` + ``predict_robot`` at K = 5;
(c) keeping a library current after each new demonstration: refitting a
    batch EM mixture on all N demonstrations so far versus one
    ``partial_fit``, at N = 50, 200 and 1000.
"""
from __future__ import annotations

import time

from dataclasses import replace

import numpy as np

from drake_skills.benchmarks._timing import median_ms
from drake_skills.data.demonstration import Demonstration
from drake_skills.library.incremental import LibraryConfig, SkillLibrary

#: The benchmark's representation without --config: 3-D wrist and 7 joints, 15 basis functions each.
CONFIG = dict(n_basis_human=15, n_basis_robot=15)
T = 150


def _skill_bank(n_skills: int, rng):
    """Random smooth skills far apart in normalized units: (human end points, bends, robot goals).

    End points are drawn with rejection so that every pair is at least 6 units
    apart (about 2 RMS units in weight space), so the library should find
    ``n_skills`` components and the timings are taken at the stated K.
    """
    half = 10.0 * max(1.0, (n_skills / 5.0) ** (1 / 3))
    goals = []
    while len(goals) < n_skills:
        g = rng.uniform(-half, half, 3)
        if all(np.linalg.norm(g - o) >= 6.0 for o in goals):
            goals.append(g)
    goals = np.array(goals)
    bends = rng.uniform(-4, 4, (n_skills, 3))
    q_goals = rng.uniform(-1.5, 1.5, (n_skills, 7))
    return goals, bends, q_goals


def _demo(bank, k: int, rng) -> Demonstration:
    goals, bends, q_goals = bank
    t = np.arange(T) / 150.0
    z = t / t[-1]
    s = 10 * z ** 3 - 15 * z ** 4 + 6 * z ** 5
    human = np.outer(s, goals[k] + rng.normal(0, 0.2, 3)) + np.outer(np.sin(np.pi * z), bends[k])
    robot = np.outer(s, q_goals[k] + rng.normal(0, 0.02, 7))
    return Demonstration(t=t, human=human + rng.normal(0, 0.01, (T, 3)), robot=robot)


def _library_with(K: int, rng, config: LibraryConfig):
    bank = _skill_bank(K, rng)
    lib = SkillLibrary(config)
    for k in range(K):  # three demos per skill in a row: support 3 survives the deletion rule
        for rep in range(3):
            lib.partial_fit(_demo(bank, k, rng))
    return lib, bank


def run(quick: bool = False, config=None) -> list[dict]:
    """``config``: a SimConfig whose ``library`` is measured (default ``LibraryConfig(**CONFIG)``)."""
    lib_config = config.library if config is not None else LibraryConfig(**CONFIG)
    rng = np.random.default_rng(0)
    rows = []
    repeats = 20 if quick else 200
    lib5 = None
    for K in (5, 20) if quick else (5, 20, 100):
        lib, bank = _library_with(K, rng, lib_config)
        demos = [_demo(bank, int(rng.integers(K)), rng) for _ in range(repeats)]
        it = iter(demos)
        ms = median_ms(lambda: lib.partial_fit(next(it)), repeats, warmup=False)
        rows.append({"name": f"partial_fit, K={K} (found {lib.n_components})", "value": round(ms, 3), "unit": "ms",
                     "goal": "< 2 ms at K=5" if K == 5 else "", "notes": "gating 3x15, stacked 10x15, T=150"})
        if K == 5:
            lib5, bank5 = lib, bank
    # the same K = 5 stream without the learned conditioning gain (its fit costs one Eq. (13) per update)
    if lib_config.conditioning_gain:
        state = np.random.default_rng(0)
        lib, bank = _library_with(5, state, replace(lib_config, conditioning_gain=False))
        demos = [_demo(bank, int(state.integers(5)), state) for _ in range(repeats)]
        it = iter(demos)
        ms = median_ms(lambda: lib.partial_fit(next(it)), repeats, warmup=False)
        rows.append({"name": f"partial_fit, K=5, conditioning_gain off (found {lib.n_components})",
                     "value": round(ms, 3), "unit": "ms", "goal": "",
                     "notes": "the paper's Eq. (13): no gain fit in the update"})
    probe = [_demo(bank5, int(rng.integers(5)), rng).human for _ in range(repeats)]
    # whole motions (issue 3's goal), then the same motions without the fraction: recognition then
    # estimates each component's phase (the path a live caller takes; issue 12's prefix figures are
    # in the anticipation suite)
    for fraction, name, goal, notes in (
            (1.0, "recognize + predict_robot, whole motion, K=5", "< 1 ms",
             "observed_fraction=1: condition on 100 resampled wrist samples, 100-step robot mean+cov"),
            (None, "recognize + predict_robot, fraction estimated, K=5", "",
             "no observed_fraction: each component's phase estimated first (prefix recognition)")):
        it = iter(probe)
        ms = median_ms(lambda: lib5.predict_robot(next(it), fraction), repeats, warmup=False)  # Eqs. 12-13
        rows.append({"name": name, "value": round(ms, 3), "unit": "ms", "goal": goal, "notes": notes})

    # (c) batch EM refit after every new demonstration versus one partial_fit
    from drake_skills.library.batch import batch_em

    K = 5
    bank = _skill_bank(K, rng)
    sizes = (50, 200) if quick else (50, 200, 1000)
    lib = SkillLibrary(lib_config)
    W = []
    stream = [_demo(bank, i % K, rng) for i in range(max(sizes) + 21)]
    pf_times = {}
    for n, d in enumerate(stream, 1):
        t0 = time.perf_counter()
        lib.partial_fit(d)
        dt = time.perf_counter() - t0
        W.append(lib.encode(d))  # the weights a batch learner would have to keep
        for N in sizes:
            if N < n <= N + 20:
                pf_times.setdefault(N, []).append(dt)
    W = np.asarray(W)
    for N in sizes:
        em_ms = median_ms(lambda: batch_em(W[:N], K, random_state=0), 1 if N >= 1000 else 3, warmup=False)
        pf_ms = 1e3 * float(np.median(pf_times[N]))
        rows.append({"name": f"batch EM refit vs partial_fit, N={N}", "value": round(em_ms / pf_ms, 1), "unit": "x",
                     "goal": ">= 100x at N=1000" if N == 1000 else "",
                     "notes": f"EM {em_ms:.1f} ms (K={K}, full cov, {W.shape[1]}-D) vs partial_fit {pf_ms:.3f} ms"})
    return rows
