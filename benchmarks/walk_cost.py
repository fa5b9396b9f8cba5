"""What the path walk costs on a noisy motion, with its vertices at the samples or at their means (``average_holds``).

A helix of 700 samples with white noise of half a tolerance (so the walk adapts and smooths),
``vertex_path(..., adapt_to_noise=True)`` timed both ways, alternating, best of 5 x 50 calls, 3
rounds; and a clean helix of 150 samples (the walk that every clean motion takes, which
``average_holds`` does not change). Prints microseconds per call and the ratio::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/walk_cost.py
"""
import timeit

import numpy as np

from drake_skills.promp.preprocessing import vertex_path


def _helix(n: int) -> np.ndarray:
    u = np.linspace(0, 2 * np.pi, n)
    return np.stack([3 * np.cos(u), 3 * np.sin(u), 0.5 * u], 1)


def _best(f) -> float:
    return min(timeit.repeat(f, number=50, repeat=5)) / 50


def main() -> None:
    noisy = _helix(700) + np.random.default_rng(0).normal(0, 0.05, (700, 3))
    clean = _helix(150)
    print("| round | noisy 700 samples: vertices at samples / at means (us) | ratio | clean 150 samples (us) |")
    print("|---|---|---|---|")
    for r in range(3):
        a = _best(lambda: vertex_path(noisy, 0.1, adapt_to_noise=True, average_holds=False))
        b = _best(lambda: vertex_path(noisy, 0.1, adapt_to_noise=True, average_holds=True))
        c = _best(lambda: vertex_path(clean, 0.1, adapt_to_noise=True))
        print(f"| {r + 1} | {a * 1e6:.0f} / {b * 1e6:.0f} | {b / a:.2f} | {c * 1e6:.0f} |", flush=True)


if __name__ == "__main__":
    main()
