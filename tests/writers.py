"""Processes that write one library file, for the concurrency and kill tests (importable as `writers`).

They run in ``multiprocessing``'s forkserver context: a clean single-threaded server
forks each writer (fast, and unaffected by the threads of the test process: meshcat,
BLAS), so the functions live in a module the server can import.
"""
import os

import numpy as np

from drake_skills import LibraryConfig, SkillLibrary

from synthetic import synthetic_demo

#: Every demonstration is novel and nothing merges or is deleted: each writer's
#: demonstrations become components of their own, so each can be found in the result.
ONE_COMPONENT_PER_DEMO = dict(novelty_quantile=1e-9, merge_quantile=1e-9, split_quantile=0.5,
                              delete_min_age=10_000)


def stream_demo(k: int):
    """The k-th demonstration of the kill test's stream (deterministic in k)."""
    return synthetic_demo(k % 4, np.random.default_rng(1000 + k))


def extend_one_at_a_time(path: str, demos: list, barrier) -> int:
    """Fold ``demos`` into the file one ``update_file`` at a time (a load-extend-save each), after ``barrier``."""
    barrier.wait()
    config = LibraryConfig(**ONE_COMPONENT_PER_DEMO)
    for d in demos:
        SkillLibrary.update_file(path, [d], config=config)
    return os.getpid()


def grow_forever(path: str, n_max: int, started) -> None:
    """Resume the stream from the file, then save after every demonstration until ``n_max`` (killed before).

    Sets the event ``started`` once its first save is done, so the killer times its kill
    from then and every writer adds at least one version, however slow the disk.
    """
    lib = SkillLibrary.load(path) if os.path.exists(path) else SkillLibrary()
    for k in range(lib.n_seen, n_max):
        lib.partial_fit(stream_demo(k))
        lib.save(path)
        started.set()


def learn_cli(argv: list, barrier) -> None:
    """``drake-skills learn ARGV`` in this process, after ``barrier``; its exit code is the process's."""
    import sys

    from drake_skills.cli import main

    barrier.wait()
    sys.exit(main(argv))
