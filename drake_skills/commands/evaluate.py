"""``drake-skills eval letters|salad|sensitivity|interaction|scale``: the experiments, written as tables and plots."""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path


def register(sub) -> None:
    from drake_skills.commands import add_common, add_config, add_subjects_model
    from drake_skills.evaluation.common import available_workers

    p = sub.add_parser("eval", help="run the experiments (letters, salad, sensitivity, interaction, scale) and write "
                                    "tables and plots",
                       description="Reproduce the experiments of Sec. 4: `eval letters` (Sec. 4.1, Figs. 3-4) and "
                                   "`eval salad` (Sec. 4.2, Tables 1-3, Figs. 7c and 9, and the robot response "
                                   "error vs the observed fraction); `eval sensitivity` (the defaults against "
                                   "alternative settings on both data sets), `eval interaction` (real human-robot "
                                   "interactions on the source's test split) and `eval scale` (many skills in one "
                                   "library). Writes .md and .csv tables, .png plots and summary.json under --out.")
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
        add_config(q)  # the library settings of every library the experiment learns

    q = esub.add_parser("letters", help="Sec. 4.1: incremental library vs batch EM vs labeled ML on LASA letters")
    common(q, "letters", 100)
    q.set_defaults(func=run_letters)

    q = esub.add_parser("salad", help="Sec. 4.2: personalized libraries, transfer, robot response error")
    common(q, "salad", 100)
    add_subjects_model(q)
    q.add_argument("--subjects", type=int, default=None, help="number of simulated subjects (default 10)")
    q.add_argument("--demos", type=int, default=None, help="demonstrations per task and subject (default 15)")
    q.add_argument("--data-seed", type=int, default=0, help="seed of the simulated data set (default 0)")
    q.set_defaults(func=run_salad)

    q = esub.add_parser("sensitivity", help="how much room the defaults have: the learned scale's prior, the "
                                            "test quantiles and the raw arc length, on letters and salad at once")
    common(q, "sensitivity", 100)
    add_subjects_model(q)
    q.add_argument("--splits", type=int, default=None, help="salad train/test splits per subject (default 10)")
    q.set_defaults(func=run_sensitivity)

    from drake_skills.data.interaction import SHARED_ENV, shared_data_path

    q = esub.add_parser("interaction", help="real human-robot interactions (buetepage_hr.npz): recognition, "
                                            "components, robot response and anticipation on the source's split",
                        description="Learn the training interactions of --data in random orders with the library "
                                    "settings (default LibraryConfig(); workspace = the bounding box of the "
                                    "training wrists) and report, on the source's test split: recognition "
                                    "(correct / wrong / undecided / unknown), components found, the robot "
                                    "response error of predict_robot beside a task-mean baseline, "
                                    "recognition of path prefixes with the phase estimated (anticipation), and "
                                    "the commits of the Drake controller's decision logic replayed on each test "
                                    "interaction (first commit, path share at it, skill executed); and "
                                    "ipromps' leave-one-out protocol over every interaction (table loo: "
                                    "beginnings cut at a share of the samples, the forced choice beside the "
                                    "library's own answers).")
    add_common(q, "eval/interaction")
    q.add_argument("--data", type=Path, default=shared_data_path("buetepage_hr.npz"),
                   help=f"interactions file (default: ../shared/data/buetepage_hr.npz beside the repository, "
                        f"or under ${SHARED_ENV}/data)")
    q.add_argument("--columns", default="hand", metavar="SEL",
                   help="human columns: the hand/wrist (6:9 of the buetepage_hr layout, default), the whole arm "
                        "(arm: shoulder, elbow, hand, 0:9), elbow, shoulder, or START:STOP (e.g. 0:3); 'hand' of a file "
                        "whose human array holds 3 columns, a wrist only, is those 3")
    q.add_argument("--orders", type=int, default=None,
                   help="random orders of the training interactions (default 20, --quick: 2)")
    q.add_argument("--teaching", choices=("random", "row"), default="random",
                   help="how each order teaches: interleaved (random, default) or task by task (row: every "
                        "interaction of one task, then the next, as a person shows a robot one skill at a time)")
    q.add_argument("--robot-units", default="rad",
                   help="units of the file's robot columns, for the response tables (default rad: joint angles; "
                        "e.g. m for a second person's arm)")
    q.add_argument("--rate", type=float, default=100.0,
                   help="sampling rate of the file in Hz (not stated by the source; default 100)")
    q.add_argument("--max-gap", type=float, default=0.5, metavar="S",
                   help="fill runs of missing samples (NaN/inf: a tracker that lost the joint) of up to S seconds "
                        "(lost samples / --rate) by linear interpolation, with a warning; longer ones are an error "
                        "(default 0.5; 0: refuse any)")
    q.add_argument("--loo-orders", type=int, default=None,
                   help="orders per held-out interaction of the leave-one-out table (ipromps' protocol over every "
                        "interaction of the file, cut at a share of its samples; default 3, --quick: 1; 0 skips it)")
    q.add_argument("--untaught-orders", type=int, default=None,
                   help="orders per left-out task of the table untaught (each task in turn kept out of the "
                        "training split and its interactions shown as a new task; default 5, --quick: 1; 0 skips it)")
    q.add_argument("--quick", action="store_true",
                   help="reduced run: 2 orders (unless --orders), fractions 0.1, 0.5, 1.0, 1 leave-one-out order, "
                        "1 order per untaught task")
    q.add_argument("--workers", type=int, default=available_workers(),
                   help="processes for the orders (default: available cores); results do not depend on it")
    q.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_config(q)
    q.set_defaults(func=run_interaction)

    q = esub.add_parser("scale", help="many skills in one library: LASA-30, and synthetic skills from 10 to 1000",
                        description="LASA-30 in one library (4 demonstrations per shape taught in random order, "
                                    "the other 3 recognized) and synthetic skills at K = 10 ... 1000 (interleaved "
                                    "and in a row): components found, correct / wrong / undecided / unknown, ms per "
                                    "update and per recognition. Runs in one process (the timings compare).")
    add_common(q, "eval/scale")
    q.add_argument("--quick", action="store_true", help="reduced run (what the tests use)")
    q.add_argument("--orders", type=int, default=None, help="random orders of LASA-30 (default 3, --quick: 1; 0 skips LASA)")
    q.add_argument("--sizes", type=int, nargs="+", default=None, metavar="K",
                   help="numbers of synthetic skills (default 10 30 100 300 1000, --quick: 10 30)")
    q.add_argument("--shapes", default=None, metavar="SET",
                   help="LASA shapes in the library: 'all' (default), 'half-a' or 'half-b' (every other shape "
                        "of the LASA list, from the first or the second: the defaults were chosen on half A), "
                        "or comma-separated names")
    q.add_argument("--no-progress", action="store_true", help="no progress bars")
    add_config(q)
    q.set_defaults(func=run_scale)


def run_interaction(args: argparse.Namespace) -> int:
    from drake_skills.evaluation.common import use_agg
    from drake_skills.evaluation.interaction import InteractionSettings, evaluate_interaction

    use_agg()
    t0 = time.time()
    if not Path(args.data).is_file():
        raise FileNotFoundError(f"interactions file '{args.data}' does not exist (give --data PATH)")
    orders = args.orders if args.orders is not None else (2 if args.quick else 20)
    kw = dict(data=str(args.data), columns=args.columns, orders=orders, rate_hz=args.rate, max_gap_s=args.max_gap,
              seed=args.seed,
              library=_library(args), robot_units=args.robot_units, teaching=args.teaching)
    if args.quick:
        kw.update(fractions=(0.1, 0.5, 1.0))
    kw["loo_orders"] = args.loo_orders if args.loo_orders is not None else (1 if args.quick else 3)
    kw["untaught_orders"] = args.untaught_orders if args.untaught_orders is not None else (1 if args.quick else 5)
    rep = evaluate_interaction(InteractionSettings(**kw), workers=args.workers, progress=not args.no_progress)
    rep.summary["command"] = " ".join(["drake-skills", "eval", "interaction"] + sys.argv[3:])
    return _finish(rep, args.out, t0)


def _finish(rep, out: Path, t0: float) -> int:
    paths = rep.write(out)
    for key, t in rep.tables.items():
        print(f"\n## {key}\n")
        print(t.to_markdown())
    print(f"wrote {len(paths)} files under {out} in {time.time() - t0:.1f} s", file=sys.stderr)
    return 0


def _library(args: argparse.Namespace):
    """The LibraryConfig of ``--config`` (the defaults without it)."""
    from drake_skills.sim.config import load_library_config

    return load_library_config(args.config)


def run_letters(args: argparse.Namespace) -> int:
    from drake_skills.evaluation.common import use_agg
    from drake_skills.evaluation.letters import LettersSettings, evaluate_letters

    use_agg()
    t0 = time.time()
    kw = dict(seed=args.seed, library=_library(args))
    if args.quick:
        kw.update(trials=4, kl_samples=500, em_n_init=2)
    if args.trials is not None:
        kw["trials"] = args.trials
    rep = evaluate_letters(LettersSettings(**kw), workers=args.workers, progress=not args.no_progress)
    rep.summary["command"] = " ".join(["drake-skills", "eval", "letters"] + sys.argv[3:])
    return _finish(rep, args.out, t0)


def run_salad(args: argparse.Namespace) -> int:
    from drake_skills.evaluation.common import use_agg
    from drake_skills.evaluation.salad import evaluate_salad
    from drake_skills.evaluation.salad_data import SaladSettings

    use_agg()
    t0 = time.time()
    base = SaladSettings.quick(seed=args.seed) if args.quick else SaladSettings(seed=args.seed)
    overrides = {"trials": args.trials, "n_subjects": args.subjects, "n_demos": args.demos}
    s = replace(base, data_seed=args.data_seed, library=_library(args), subject_model=args.subjects_model,
                **{k: v for k, v in overrides.items() if v is not None})  # validated again
    rep = evaluate_salad(s, workers=args.workers, progress=not args.no_progress, cache_dir=args.out / "cache")
    rep.summary["command"] = " ".join(["drake-skills", "eval", "salad"] + sys.argv[3:])
    return _finish(rep, args.out, t0)


def _lasa_shapes(spec: str | None):
    """``--shapes``: None (the settings' default), a half of :data:`~drake_skills.data.lasa.LASA_SHAPES`, or names."""
    from drake_skills.data.lasa import LASA_SHAPES

    if spec is None:
        return None
    if spec == "all":
        return tuple(LASA_SHAPES)
    if spec in ("half-a", "half-b"):
        return tuple(LASA_SHAPES[0 if spec == "half-a" else 1::2])
    names = tuple(dict.fromkeys(n.strip() for n in spec.split(",") if n.strip()))
    unknown = [n for n in names if n not in LASA_SHAPES]
    if unknown or not names:
        raise ValueError(f"--shapes: unknown LASA shapes {unknown or [spec]}; use all, half-a, half-b or names "
                         f"from {', '.join(LASA_SHAPES)}")
    return names


def run_scale(args: argparse.Namespace) -> int:
    from drake_skills.evaluation.common import use_agg
    from drake_skills.evaluation.scale import ScaleSettings, evaluate_scale

    use_agg()
    t0 = time.time()
    base = ScaleSettings.quick(seed=args.seed) if args.quick else ScaleSettings(seed=args.seed)
    overrides = {"lasa_orders": args.orders, "sizes": tuple(args.sizes) if args.sizes else None,
                 "lasa_shapes": _lasa_shapes(args.shapes)}
    s = replace(base, library=_library(args), **{k: v for k, v in overrides.items() if v is not None})
    rep = evaluate_scale(s, progress=not args.no_progress)
    rep.summary["command"] = " ".join(["drake-skills", "eval", "scale"] + sys.argv[3:])
    return _finish(rep, args.out, t0)


def run_sensitivity(args: argparse.Namespace) -> int:
    from drake_skills.evaluation.sensitivity import SensitivitySettings, evaluate_sensitivity

    t0 = time.time()
    base = SensitivitySettings.quick(seed=args.seed) if args.quick else SensitivitySettings(seed=args.seed)
    overrides = {"letter_orders": args.trials, "salad_splits": args.splits}
    s = replace(base, library=_library(args), subject_model=args.subjects_model,
                **{k: v for k, v in overrides.items() if v is not None})
    rep = evaluate_sensitivity(s, workers=args.workers, progress=not args.no_progress,
                               cache_dir=args.out / "cache")
    rep.summary["command"] = " ".join(["drake-skills", "eval", "sensitivity"] + sys.argv[3:])
    return _finish(rep, args.out, t0)
