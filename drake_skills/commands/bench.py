"""``drake-skills bench``: run the speed benchmarks and write a table.

Suites are the modules of ``drake_skills.benchmarks`` with a ``run(quick)``
function (``promp``, ``library``, ...). Writes ``OUT/bench.json`` and
``OUT/bench.md``.
"""
from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np

from drake_skills.commands import add_common, add_config


def _suites():
    from drake_skills.benchmarks import discover_suites

    return discover_suites()


def register(subparsers) -> None:
    suites = sorted(_suites())
    parser = subparsers.add_parser("bench", help="measure speed (ProMP core, library, ...)",
                                   description="Run the speed benchmarks; print a table and write "
                                               "OUT/bench.json and OUT/bench.md.")
    parser.add_argument("--quick", action="store_true", help="fewer repeats and smaller sizes")
    parser.add_argument("--suite", choices=suites, action="append",
                        help="suite to run (repeatable; default: all of " + ", ".join(suites) + ")")
    add_config(parser)  # libraries of the library and sim suites (default: each suite's own settings)
    add_common(parser, "bench")
    parser.set_defaults(func=main)


def _columns(rows: list[dict]) -> list[str]:
    cols = ["suite"]
    for r in rows:
        cols += [k for k in r if k not in cols]
    return cols


def format_table(rows: list[dict], *, markdown: bool = False) -> str:
    """Rows as an aligned text table (or a Markdown table); missing cells are blank."""
    cols = _columns(rows)
    cells = [[str(r.get(c, "")) for c in cols] for r in rows]
    if markdown:
        lines = ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
        lines += ["| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" for row in cells]
        return "\n".join(lines)
    widths = [max(len(c), *(len(row[i]) for row in cells)) for i, c in enumerate(cols)]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    lines = [fmt.format(*cols), fmt.format(*("-" * w for w in widths))] + [fmt.format(*r) for r in cells]
    return "\n".join(line.rstrip() for line in lines)


def main(args: argparse.Namespace) -> int:
    suites = _suites()
    names = args.suite or sorted(suites)
    np.random.seed(args.seed)  # legacy global RNG, used by sklearn inside some suites
    config = None
    if args.config is not None:
        from drake_skills.sim.config import load_config

        config = load_config(args.config)
    rows = []
    for name in names:
        t0 = time.perf_counter()
        for row in suites[name](quick=args.quick, config=config):
            rows.append({"suite": name, **row})
        print(f"suite {name}: {time.perf_counter() - t0:.1f} s", flush=True)
    print(format_table(rows))
    machine = {"python": platform.python_version(), "numpy": np.__version__, "machine": platform.machine(),
               "processor": platform.processor() or platform.machine(), "cpus": _cpus(), "quick": args.quick}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "bench.json").write_text(json.dumps({"machine": machine, "rows": rows}, indent=2))
    md = (f"Machine: {machine['cpus']} CPU cores, Python {machine['python']}, numpy {machine['numpy']}"
          f"{' (quick)' if args.quick else ''}\n\n" + format_table(rows, markdown=True) + "\n")
    (args.out / "bench.md").write_text(md)
    print(f"wrote {args.out / 'bench.json'} and {args.out / 'bench.md'}")
    return 0


def _cpus() -> int:
    import os

    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1
