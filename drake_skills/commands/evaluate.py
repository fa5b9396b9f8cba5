"""``drake-skills eval letters|salad``: the paper's experiments (Sec. 4), written as tables and plots."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def register(sub) -> None:
    from drake_skills.commands import add_common
    from drake_skills.evaluation.common import available_workers

    p = sub.add_parser("eval", help="run the paper's experiments (letters, salad) and write tables and plots",
                       description="Reproduce the experiments of Sec. 4: `eval letters` (Sec. 4.1, Figs. 3-4) and "
                                   "`eval salad` (Sec. 4.2, Tables 1-3, Figs. 7c and 9, and the robot response "
                                   "error vs the observed fraction), and `eval sensitivity` (the defaults against alternative "
                                   "settings on both data sets). Writes .md and .csv tables, .png plots and "
                                   "summary.json under --out.")
    esub = p.add_subparsers(dest="experiment", metavar="EXPERIMENT")
    esub.required = True

    def common(q, name, trials):
        add_common(q, f"eval/{name}")
        q.add_argument("--quick", action="store_true", help="reduced run (what the tests use)")
        q.add_argument("--trials", type=int, default=None,
                       help=f"random orders / splits per experiment (default {trials}, --quick: fewer)")
        q.add_argument("--workers", type=int, default=available_workers(),
                       help="processes for the trials (default: available cores); results do not depend on it")
        q.add_argument("--no-progress", action="store_true", help="no progress bars")

    q = esub.add_parser("letters", help="Sec. 4.1: incremental library vs batch EM vs labeled ML on LASA letters")
    common(q, "letters", 100)
    q.set_defaults(func=run_letters)

    q = esub.add_parser("salad", help="Sec. 4.2: personalized libraries, transfer, robot response error")
    common(q, "salad", 100)
    q.add_argument("--subjects", type=int, default=None, help="number of simulated subjects (default 10)")
    q.add_argument("--demos", type=int, default=None, help="demonstrations per task and subject (default 15)")
    q.add_argument("--data-seed", type=int, default=0, help="seed of the simulated data set (default 0)")
    q.set_defaults(func=run_salad)

    q = esub.add_parser("sensitivity", help="how much room the defaults have: arc-length tolerance and gating "
                                            "floor on letters and salad at once")
    common(q, "sensitivity", 100)
    q.add_argument("--splits", type=int, default=None, help="salad train/test splits per subject (default 10)")
    q.set_defaults(func=run_sensitivity)


def _finish(rep, out: Path, t0: float) -> int:
    paths = rep.write(out)
    for key, t in rep.tables.items():
        print(f"\n## {key}\n")
        print(t.to_markdown())
    print(f"wrote {len(paths)} files under {out} in {time.time() - t0:.1f} s", file=sys.stderr)
    return 0


def run_letters(args: argparse.Namespace) -> int:
    from drake_skills.evaluation.common import use_agg
    from drake_skills.evaluation.letters import LettersSettings, evaluate_letters

    use_agg()
    t0 = time.time()
    s = LettersSettings(seed=args.seed)
    if args.quick:
        s.trials, s.kl_samples, s.em_n_init = 4, 500, 2
    if args.trials is not None:
        s.trials = args.trials
    rep = evaluate_letters(s, workers=args.workers, progress=not args.no_progress)
    rep.summary["command"] = " ".join(["drake-skills", "eval", "letters"] + sys.argv[3:])
    return _finish(rep, args.out, t0)


def run_salad(args: argparse.Namespace) -> int:
    from drake_skills.evaluation.common import use_agg
    from drake_skills.evaluation.salad import SaladSettings, evaluate_salad

    use_agg()
    t0 = time.time()
    s = SaladSettings.quick(seed=args.seed) if args.quick else SaladSettings(seed=args.seed)
    if args.trials is not None:
        s.trials = args.trials
    if args.subjects is not None:
        s.n_subjects = args.subjects
    if args.demos is not None:
        s.n_demos = args.demos
    s.data_seed = args.data_seed
    rep = evaluate_salad(s, workers=args.workers, progress=not args.no_progress, cache_dir=args.out / "cache")
    rep.summary["command"] = " ".join(["drake-skills", "eval", "salad"] + sys.argv[3:])
    return _finish(rep, args.out, t0)


def run_sensitivity(args: argparse.Namespace) -> int:
    from drake_skills.evaluation.sensitivity import SensitivitySettings, evaluate_sensitivity

    t0 = time.time()
    s = SensitivitySettings.quick(seed=args.seed) if args.quick else SensitivitySettings(seed=args.seed)
    if args.trials is not None:
        s.letter_orders = args.trials
    if args.splits is not None:
        s.salad_splits = args.splits
    if s.letter_orders < 1 or s.salad_splits < 1:
        raise SystemExit("drake-skills eval sensitivity: --trials and --splits must be >= 1")
    rep = evaluate_sensitivity(s, workers=args.workers, progress=not args.no_progress,
                               cache_dir=args.out / "cache")
    rep.summary["command"] = " ".join(["drake-skills", "eval", "sensitivity"] + sys.argv[3:])
    return _finish(rep, args.out, t0)
