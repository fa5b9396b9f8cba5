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
