"""Shared pieces of the paper's experiments: tables, reproducible parallel trials, figures.

Evaluation functions return an :class:`EvalReport` (tables, figures, a summary
dict) and never print or write; the ``drake-skills eval`` command writes it
with :meth:`EvalReport.write`.

Reproducibility: trial ``i`` of an experiment seeded with ``seed`` draws all
its randomness from ``np.random.default_rng(SeedSequence([seed, stream, i]))``
(:func:`trial_rng`), so its result does not depend on which process runs it or
on how many workers there are; :func:`run_trials` returns results in trial order.
"""
from __future__ import annotations

import csv
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np


def available_workers() -> int:
    """Cores this process may use (the default of ``--workers``)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def trial_rng(seed: int, index: int, stream: int = 0) -> np.random.Generator:
    """The random generator of one trial, a function of ``(seed, stream, index)`` only.

    Parameters
    ----------
    seed : int
        The experiment's ``--seed``.
    index : int
        The trial index (0-based).
    stream : int
        Separates independent experiments that share a seed.
    """
    return stream_rng(seed, stream, index)


def stream_rng(seed: int, stream: int, *ids: int) -> np.random.Generator:
    """The generator of one trial named by several ids: ``SeedSequence([seed, stream, *ids])``."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(stream), *map(int, ids)]))


def nested_streams(tasks: Sequence[str], perm: np.ndarray, n_max: int) -> list[list[int]]:
    """For k = 1..n_max: the indices of ``perm`` among the first k of their task, in ``perm`` order.

    Parameters
    ----------
    tasks : sequence of str
        The task of each item.
    perm : array, shape (n,)
        A permutation of the items (the presentation order).
    n_max : int

    Returns
    -------
    list of list of int
        Nested streams: stream k holds k items of every task (fewer if a task has fewer).
    """
    rank, counts = {}, {}
    for j in perm:
        t = tasks[j]
        rank[j] = counts.get(t, 0)
        counts[t] = rank[j] + 1
    return [[int(j) for j in perm if rank[j] < k] for k in range(1, n_max + 1)]


# The context of the trials running in this process (set by the pool initializer).
_CONTEXT: Any = None


def _init_worker(context) -> None:
    global _CONTEXT
    _CONTEXT = context
    # one BLAS thread per worker: the workers already fill the cores
    _single_thread()


def _single_thread():
    """One BLAS thread, as in the workers (so serial and parallel runs do the same arithmetic)."""
    try:
        from threadpoolctl import threadpool_limits

        return threadpool_limits(1)
    except Exception:  # noqa: BLE001 - optional  # pragma: no cover
        import contextlib

        return contextlib.nullcontext()


def _call(args):
    fn, item = args
    return fn(_CONTEXT, item)


def run_trials(fn: Callable[[Any, Any], Any], items: Sequence, context: Any = None, *, workers: int = 1,
               desc: str = "trials", progress: bool = True) -> list:
    """``[fn(context, item) for item in items]``, over ``workers`` processes, in order.

    Parameters
    ----------
    fn : callable
        A module-level function (it is pickled) ``fn(context, item) -> result``.
        Any randomness must come from the item (e.g. a trial index fed to
        :func:`trial_rng`), never from global state.
    items : sequence
        One per trial.
    context : object
        Shared, read-only data (sent once to each worker).
    workers : int
        Number of processes; 1 runs in this process.
    desc : str
        Label of the progress bar.
    progress : bool
        Show a tqdm progress bar on stderr.

    Returns
    -------
    results : list
        In the order of ``items``, identical whatever ``workers`` is.
    """
    from tqdm import tqdm

    items = list(items)
    if isinstance(workers, bool) or int(workers) != workers or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    bar = tqdm(total=len(items), desc=desc, disable=not progress, leave=False, dynamic_ncols=True)
    try:
        if workers == 1 or len(items) <= 1:
            out = []
            with _single_thread():
                for item in items:
                    out.append(fn(context, item))
                    bar.update()
            return out
        n = min(int(workers), len(items))
        with ProcessPoolExecutor(max_workers=n, initializer=_init_worker, initargs=(context,)) as pool:
            out = []
            for r in pool.map(_call, [(fn, it) for it in items], chunksize=1):
                out.append(r)
                bar.update()
            return out
    finally:
        bar.close()


# ------------------------------------------------------------------- tables
@dataclass
class Table:
    """A small table: named columns, rows of values, a caption.

    Attributes
    ----------
    columns : list of str
    rows : list of list
        Each row as long as ``columns``; floats are formatted with ``fmt``.
    caption : str
        One or two sentences: what the numbers are and how they were made.
    fmt : str
        Format of float cells in markdown (CSV keeps full precision).
    """

    columns: list[str]
    rows: list[list]
    caption: str = ""
    fmt: str = "{:.3g}"

    def __post_init__(self):
        for i, r in enumerate(self.rows):
            if len(r) != len(self.columns):
                raise ValueError(f"row {i} has {len(r)} cells for {len(self.columns)} columns")

    def _cell(self, v) -> str:
        if isinstance(v, (float, np.floating)):
            return "nan" if not np.isfinite(v) else self.fmt.format(float(v))
        return str(v)

    def to_markdown(self) -> str:
        lines = []
        if self.caption:
            lines += [self.caption, ""]
        lines.append("| " + " | ".join(self.columns) + " |")
        lines.append("|" + "|".join("---" for _ in self.columns) + "|")
        for r in self.rows:
            lines.append("| " + " | ".join(self._cell(v) for v in r) + " |")
        return "\n".join(lines) + "\n"

    def write_csv(self, path: Path) -> None:
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(self.columns)
            for r in self.rows:
                w.writerow([repr(float(v)) if isinstance(v, (float, np.floating)) else v for v in r])

    def column(self, name: str) -> list:
        j = self.columns.index(name)
        return [r[j] for r in self.rows]


@dataclass
class EvalReport:
    """What an experiment produced: tables, figures and a summary (numbers for RESULTS.md).

    Attributes
    ----------
    name : str
    tables : dict of str to Table
        Written as ``<key>.md`` and ``<key>.csv``.
    figures : dict of str to matplotlib Figure
        Written as ``<key>.png``.
    summary : dict
        Headline numbers and the settings used (written as ``summary.json``).
    """

    name: str
    tables: dict[str, Table] = field(default_factory=dict)
    figures: dict[str, Any] = field(default_factory=dict)
    summary: dict = field(default_factory=dict)

    def write(self, out: Path) -> list[Path]:
        """Write every table (.md, .csv), figure (.png), ``summary.json`` and ``README.md``.

        Returns the written paths. Figures are closed after writing.
        """
        import json

        import matplotlib.pyplot as plt

        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        paths = []
        index = [f"# {self.name}\n"]
        for key, t in self.tables.items():
            p = out / f"{key}.md"
            p.write_text(f"## {key}\n\n" + t.to_markdown())
            t.write_csv(out / f"{key}.csv")
            paths += [p, out / f"{key}.csv"]
            index.append(f"## {key}\n\n{t.to_markdown()}")
        for key, fig in self.figures.items():
            p = out / f"{key}.png"
            fig.savefig(p, dpi=110, bbox_inches="tight")
            plt.close(fig)
            paths.append(p)
            index.append(f"![{key}]({key}.png)\n")
        p = out / "summary.json"
        p.write_text(json.dumps(self.summary, indent=2, default=_json_default) + "\n")
        paths.append(p)
        p = out / "README.md"
        p.write_text("\n".join(index))
        paths.append(p)
        return paths


def _json_default(o):
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


def count_distribution(counts: Sequence[int], bins: Sequence) -> list[float]:
    """Fraction of ``counts`` falling in each bin; a bin is an int or ``(lo, None)`` for ``>= lo``."""
    c = np.asarray(counts)
    n = max(len(c), 1)
    out = []
    for b in bins:
        if isinstance(b, tuple):
            lo, hi = b
            m = (c >= lo) if hi is None else ((c >= lo) & (c <= hi))
        else:
            m = c == b
        out.append(float(m.sum()) / n)
    return out


def use_agg() -> None:
    """Select the non-interactive Agg backend (figures are only written to files)."""
    import matplotlib

    matplotlib.use("Agg", force=True)


def fig_kl_vs_samples(ks, inc, em, *, xlabel: str, title: str, std_bars: bool = False):
    """KL(labeled ML || model) against samples per class: mean and 10-90 % band per model.

    ``inc`` and ``em`` are (trials, len(ks)) arrays; ``std_bars`` adds +-1 std error bars.
    """
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    for name, a, c in (("incremental (ours)", inc, "tab:green"), ("batch EM (true K)", em, "tab:blue")):
        mean = a.mean(axis=0)
        lo, hi = np.percentile(a, 10, axis=0), np.percentile(a, 90, axis=0)
        ax.plot(ks, mean, "o-", color=c, label=f"{name}: mean")
        ax.fill_between(ks, lo, hi, color=c, alpha=0.2, label=f"{name}: 10-90 %")
        if std_bars:
            ax.errorbar(ks, mean, yerr=a.std(axis=0), color=c, fmt="none", capsize=3)
    ax.set_yscale("symlog", linthresh=1.0)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("KL(labeled ML || model), nats")
    ax.set_title(title)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig
