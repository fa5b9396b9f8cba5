"""Choose a setting on development data: `eval interaction`'s tables on the buetepage TRAINING split.

For each value of one ``LibraryConfig`` field, the tables of ``drake-skills eval interaction``
(recognition, response, anticipation, commits) by internal validation on the training
interactions alone (:func:`~drake_skills.evaluation.interaction.development_splits`: per task 6
taught, the rest held out, 3 draws x ``--orders`` random orders), averaged over the draws. The
source's test split is never touched, so a value chosen here can then be reported on it with
``drake-skills eval interaction --config``.

Not a speed benchmark: the tool behind RESULTS.md's "Conditioning against the mean" (about 1 min
per value at 4 orders on the shared 2-core machine)::

    .venv/bin/python benchmarks/dev_split.py expert_prior 1,4,16,100 --tables response
"""
from __future__ import annotations

import argparse
import dataclasses
import numbers
import sys

import numpy as np

from drake_skills import LibraryConfig
from drake_skills.data.interaction import load_interactions
from drake_skills.evaluation.interaction import (InteractionContext, InteractionSettings, default_data_path,
                                                 development_splits, evaluate_interaction)

#: The tables it can print (`untaught`: each task left out in turn, 2 orders per task, only when asked for).
TABLES = ("recognition", "response", "anticipation", "commits", "untaught")
DEFAULT_TABLES = ("recognition", "response", "anticipation", "commits")


def _mean_table(tables) -> list[list]:
    """Cell-wise mean over draws of the numeric cells (NaN where a draw has none); text cells as in the first."""
    rows = []
    for i, row in enumerate(tables[0].rows):
        cells = []
        for j, v in enumerate(row):
            if isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_)):
                vals = np.array([float(t.rows[i][j]) for t in tables])
                cells.append(f"{np.nanmean(vals):.3g}" if np.isfinite(vals).any() else "-")
            else:
                cells.append(str(v))
        rows.append(cells)
    return rows


def sweep(field: str, values, *, orders: int = 4, tables=DEFAULT_TABLES, data=None, out=sys.stdout, teaching="random",
          fixed=None) -> None:
    """Print the mean ``tables`` on the development splits for ``LibraryConfig(**fixed, **{field: v})``, each v,
    taught in ``teaching`` order ("random" or "row": task by task)."""
    names = {f.name for f in dataclasses.fields(LibraryConfig)}
    if field not in names:
        raise SystemExit(f"dev_split: LibraryConfig has no field {field!r}")
    unknown = [t for t in tables if t not in TABLES]
    if unknown:
        raise SystemExit(f"dev_split: unknown tables {unknown}; choose from {', '.join(TABLES)}")
    path = data or default_data_path()
    train = load_interactions(path).train
    splits = development_splits(train)
    default = getattr(LibraryConfig(), field)
    for v in values:
        settings = InteractionSettings(data=path, orders=orders, library=LibraryConfig(**{**(fixed or {}), field: v}),
                                       loo_orders=0, teaching=teaching,
                                       untaught_orders=2 if "untaught" in tables else 0)
        reps = [evaluate_interaction(settings, progress=False, figures=False,
                                     context=InteractionContext.from_splits(taught, held, settings))
                for taught, held in splits]
        is_default = v == default and isinstance(v, bool) == isinstance(default, bool)
        print(f"\n## {field} = {v!r}{' (default)' if is_default else ''}"
              + "".join(f", {k} = {x!r}" for k, x in (fixed or {}).items()) + f", taught {teaching}", file=out)
        comps = [r.summary["components_mean"] for r in reps]
        print(f"\ncomponents (mean over orders, per draw): {', '.join(f'{c:.2f}' for c in comps)}; "
              f"mean {np.mean(comps):.2f}", file=out)
        for name in tables:
            t = reps[0].tables[name]
            print(f"\n{name}\n\n| " + " | ".join(t.columns) + " |\n|" + "---|" * len(t.columns), file=out)
            for row in _mean_table([r.tables[name] for r in reps]):
                print("| " + " | ".join(row) + " |", file=out)
        out.flush()


def _value(text: str):
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return {"true": True, "false": False}.get(text.lower(), text)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("field", help="a LibraryConfig field, e.g. expert_prior")
    ap.add_argument("values", help="comma-separated values, e.g. 1,4,16")
    ap.add_argument("--orders", type=int, default=4, help="random orders per draw (default: %(default)s)")
    ap.add_argument("--tables", default=",".join(DEFAULT_TABLES), help="comma-separated tables (default: %(default)s)")
    ap.add_argument("--data", default=None, help="buetepage_hr.npz (default: the shared data folder)")
    ap.add_argument("--teaching", choices=("random", "row"), default="random",
                    help="order of the taught interactions: random, or task by task (default: %(default)s)")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="another LibraryConfig field held at a value for every run (repeatable)")
    args = ap.parse_args(argv)
    fixed = {}
    for item in args.set:
        k, sep, v = item.partition("=")
        if not sep:
            raise SystemExit(f"dev_split: --set takes FIELD=VALUE, got {item!r}")
        fixed[k.strip()] = _value(v.strip())
    sweep(args.field, [_value(v) for v in args.values.split(",")], orders=args.orders,
          tables=tuple(args.tables.split(",")), data=args.data, teaching=args.teaching, fixed=fixed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
