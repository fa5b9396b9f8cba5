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

from drake_skills.commands import add_config, add_out

#: Width of the table printed on the console (the Markdown table in bench.md is not wrapped).
WIDTH = 100


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
    add_out(parser, "bench", "bench.json and bench.md")  # no --seed: every suite fixes its own
    parser.set_defaults(func=main)


def _columns(rows: list[dict]) -> list[str]:
    cols = ["suite"] if any("suite" in r for r in rows) else []
    for r in rows:
        cols += [k for k in r if k not in cols]
    return cols


def format_tables(rows: list[dict], width: int = WIDTH) -> str:
    """One text table per suite (each suite has its own columns), each at most ``width`` wide."""
    suites = list(dict.fromkeys(r["suite"] for r in rows))
    parts = []
    for s in suites:
        sub = [{k: v for k, v in r.items() if k != "suite"} for r in rows if r["suite"] == s]
        parts.append(f"suite {s}\n" + format_table(sub, width=width))
    return "\n\n".join(parts)


def format_table(rows: list[dict], *, markdown: bool = False, width: int = WIDTH) -> str:
    """Rows as an aligned text table at most ``width`` characters wide (or a Markdown table).

    Missing cells are blank. In the text table the ``notes`` column (and any column that
    would not fit) is printed under its row, indented and wrapped to ``width``.
    """
    import textwrap

    cols = _columns(rows)
    if markdown:
        cells = [[str(r.get(c, "")) for c in cols] for r in rows]
        lines = ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
        lines += ["| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" for row in cells]
        return "\n".join(lines)
    inline = [c for c in cols if c != "notes"]
    below = [c for c in cols if c == "notes"]

    def widths_of(names):
        return [max(len(c), *(len(str(r.get(c, ""))) for r in rows)) for c in names]

    while sum(widths_of(inline)) + 2 * (len(inline) - 1) > width and len(inline) > 2:
        below.insert(0, inline.pop())  # the last columns move under the row until the rest fit
    widths = widths_of(inline)
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    lines = [fmt.format(*inline).rstrip(), fmt.format(*("-" * w for w in widths))]
    for r in rows:
        lines += textwrap.wrap(fmt.format(*(str(r.get(c, "")) for c in inline)).rstrip(), width,
                               subsequent_indent="    ")
        for c in below:
            if str(r.get(c, "")):
                text = str(r[c]) if c == "notes" else f"{c}: {r[c]}"
                lines += textwrap.wrap(text, width, initial_indent="    ", subsequent_indent="    ")
    return "\n".join(lines)


def main(args: argparse.Namespace) -> int:
    suites = _suites()
    names = args.suite or sorted(suites)
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
    print(format_tables(rows))
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
