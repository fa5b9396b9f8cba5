"""``drake-skills tune DEMOS``: choose the library settings by cross-validation on labeled demonstrations (Ray)."""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path


def register(sub) -> None:
    from drake_skills.commands import add_common, add_config
    from drake_skills.evaluation.common import available_workers

    p = sub.add_parser(
        "tune", help="choose the library settings by cross-validation on your labeled demonstrations (Ray)",
        description="Random search over the library settings that remain (drake_skills.tuning.SEARCH_SPACE), "
                    "scored by task-stratified cross-validation on labeled demonstrations: "
                    "score = (correct - 10 wrong) / held_out - 0.02 x components beyond the number of tasks "
                    "(unknown and undecided count 0; trial 0 is the base config). Runs on a local Ray "
                    "(loopback only, no dashboard) or on a cluster (--address). Writes OUT/config.yaml (LibraryConfig "
                    "fields, for --config of learn, demo and eval), OUT/trials.md/.csv and OUT/summary.json.")
    p.add_argument("demos", type=Path, metavar="DEMOS",
                   help="a directory of labeled demonstration files (.npz/.csv with a task), or an interactions "
                        "file in the layout of buetepage_hr.npz (its train split when it has one)")
    p.add_argument("--columns", default="hand", metavar="SEL",
                   help="for an interactions file: the human columns, a name (hand: 6:9 of the buetepage_hr "
                        "layout, default; arm, elbow, shoulder) or START:STOP")
    p.add_argument("--max-gap", type=float, default=0.5, metavar="S",
                   help="for an interactions file: fill runs of missing samples (NaN/inf) of up to S seconds "
                        "(lost samples / 100 Hz: tune reads the file at 100 Hz) by linear interpolation, with a "
                        "warning (default 0.5; 0: refuse any)")
    p.add_argument("--trials", type=int, default=64, help="settings tried (default 64; trial 0 = the base config)")
    p.add_argument("--folds", type=int, default=4, help="cross-validation folds (default 4)")
    p.add_argument("--orders", type=int, default=2, help="presentation orders per fold (default 2)")
    p.add_argument("--address", default=None,
                   help="a running Ray cluster (e.g. ray://head:10001 or auto); default: a local Ray")
    p.add_argument("--workers", type=int, default=available_workers(),
                   help="CPUs of the local Ray (default: available cores)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_common(p, "tune")
    add_config(p)  # the base config: trial 0 and the settings outside the search space
    p.set_defaults(func=run)


def _load(args) -> list:
    from drake_skills.data.demos import load_dir
    from drake_skills.data.interaction import column_selection, load_interactions

    if args.demos.is_dir():
        demos = load_dir(args.demos)
        if not demos:
            raise ValueError(f"no demonstrations (.npz or .csv) found under '{args.demos}'")
        return demos
    if not args.demos.is_file():
        raise FileNotFoundError(f"'{args.demos}' is neither a directory of demonstrations nor a file")
    demos = load_interactions(args.demos, columns=column_selection(args.columns, "--columns"), max_gap_s=args.max_gap)
    return demos.train if any(s is not None for s in demos.split) else list(demos)


def run(args: argparse.Namespace) -> int:
    from drake_skills.sim.config import load_library_config
    from drake_skills.tuning import OBJECTIVE, tune

    t0 = time.time()
    demos = _load(args)
    base = load_library_config(args.config)
    print(f"tune: {len(demos)} demonstrations, {args.trials} trials, {args.folds} folds x {args.orders} orders, "
          f"Ray {'at ' + args.address if args.address else 'local'}", file=sys.stderr)
    res = tune(demos, n_trials=args.trials, seed=args.seed, address=args.address, n_folds=args.folds,
               n_orders=args.orders, base=base, num_cpus=None if args.address else args.workers,
               progress=not args.no_progress)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = res.write_yaml(out / "config.yaml")
    (out / "trials.md").write_text("## trials\n\n" + res.trials.to_markdown())
    res.trials.write_csv(out / "trials.csv")
    row = res.trials.rows[res.best]
    cols = res.trials.columns
    summary = {"command": " ".join(["drake-skills", "tune"] + sys.argv[2:]), "objective": OBJECTIVE,
               "best_trial": res.best, "n_demos": len(demos), "n_trials": args.trials,
               "best": dict(zip(cols, row)), "base": dict(zip(cols, res.trials.rows[0])),
               "config": res.config.dict(), "seconds": round(time.time() - t0, 1)}
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float) + "\n")
    print(res.trials.to_markdown())
    best = dict(zip(cols, row))
    print(f"best: trial {res.best}, score {best['score']:.3f} (base config {res.trials.rows[0][cols.index('score')]:.3f}); "
          f"wrote {path} (use it with --config) in {summary['seconds']} s")
    return 0
