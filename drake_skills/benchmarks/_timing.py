"""Timing helper shared by the benchmark suites."""
from __future__ import annotations

import time

import numpy as np


def median_ms(fn, repeats: int, *, warmup: bool = True) -> float:
    """Median wall time of ``fn()`` over ``repeats`` calls, in milliseconds.

    ``warmup`` makes one untimed call first (caches, lazy imports); turn it off
    when ``fn`` consumes a finite stream of inputs.
    """
    if warmup:
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def fastest_cpu_ms(fn, items, batches: int) -> float:
    """CPU time of ``fn(item)`` per item, in milliseconds: the fastest of ``batches`` passes over ``items``.

    On a machine shared with other work the wall clock's median moves by 1.5x between runs of the same
    code; the process's CPU time of a whole pass, at its fastest, moves by a few percent. One warm-up pass.
    The process's CPU time counts every thread: run it with one BLAS thread (``OPENBLAS_NUM_THREADS=1``).
    """
    items = list(items)
    if not items:
        raise ValueError("fastest_cpu_ms needs at least one item to time")
    if batches < 1:
        raise ValueError(f"fastest_cpu_ms needs batches >= 1, got {batches}")
    for x in items:
        fn(x)
    best = np.inf
    for _ in range(int(batches)):
        c0 = time.process_time()
        for x in items:
            fn(x)
        best = min(best, time.process_time() - c0)
    return 1e3 * float(best) / len(items)
