#!/usr/bin/env python3
"""Print the mutation score of the last ``mutmut run`` (``make mutate``), per module.

Reads ``mutmut results --all true`` (run from the project root, where ``mutants/`` is).
A mutant is *detected* when a test failed (killed) or the tests ran past their time
limit (timeout: the mutant made them loop or crawl). The score is detected / tested;
every survivor is listed, with its diff when ``--diff`` is given (``mutmut show NAME``
prints one).

    .ci/mutation_report.py [--diff] [--mutmut PATH]
"""
from __future__ import annotations

import argparse
import collections
import re
import subprocess
import sys

#: mutmut 3 names mutants ``package.module.x_function__mutmut_N`` or ``package.module.xǁClassǁmethod__mutmut_N``.
NAME = re.compile(r"^(?P<module>[\w.]+?)\.x(?:_|ǁ)(?P<function>.+)__mutmut_(?P<n>\d+)$")
DETECTED = {"killed", "timeout"}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--diff", action="store_true", help="print each survivor's diff")
    ap.add_argument("--mutmut", default="mutmut", help="mutmut executable (default: the one on PATH)")
    args = ap.parse_args(argv)
    out = subprocess.run([args.mutmut, "results", "--all", "true"], capture_output=True, text=True)
    if out.returncode != 0:
        print(out.stdout + out.stderr, file=sys.stderr)
        return out.returncode
    by_module: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    survivors: list[tuple[str, str]] = []
    for line in out.stdout.splitlines():
        name, sep, status = line.strip().rpartition(": ")
        m = NAME.match(name)
        if not sep or not m:
            continue
        by_module[m["module"]][status] += 1
        if status not in DETECTED and status != "not checked":
            survivors.append((name, status))
    if not by_module:
        print("no mutation results: run `make mutate` first", file=sys.stderr)
        return 1
    total = collections.Counter()
    print(f"{'module':40s} {'detected':>9s} {'tested':>7s} {'score':>7s}   killed timeout survived no-tests")
    for module in sorted(by_module):
        c = by_module[module]
        total.update(c)
        if sum(c.values()) > c["not checked"]:  # modules outside MUTANTS are left out
            _row(module, c)
    _row("all", total)
    if total["not checked"]:
        print(f"\n{total['not checked']} mutant(s) not checked: outside MUTANTS, or the run was interrupted")
    print(f"\n{len(survivors)} surviving mutant(s)" + (":" if survivors else ""))
    for name, status in survivors:
        print(f"  {name}  [{status}]")
        if args.diff:
            show = subprocess.run([args.mutmut, "show", name], capture_output=True, text=True).stdout
            print("".join(f"      {l}\n" for l in show.splitlines() if l[:1] in "+-" and l[:3] not in ("+++", "---")))
    return 0


def _row(module: str, c: collections.Counter) -> None:
    tested = sum(v for k, v in c.items() if k != "not checked")
    detected = sum(c[k] for k in DETECTED)
    score = f"{100 * detected / tested:6.1f}%" if tested else "     -"
    print(f"{module:40s} {detected:9d} {tested:7d} {score:>7s}   {c['killed']:6d} {c['timeout']:7d} "
          f"{c['survived']:8d} {c['no tests']:8d}")


if __name__ == "__main__":
    sys.exit(main())
