"""``drake-skills demo``: the open-ended collaboration of the paper's Fig. 2, simulated with Drake."""
from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import replace

from drake_skills.commands import add_common, add_config, add_subjects_model


def register(sub) -> None:
    p = sub.add_parser(
        "demo", help="simulate the robot learning and answering collaborative skills (IIWA7, salad scene)",
        description="Generate one simulated subject of the salad scenario, then run a stream of trials of the "
                    "five tasks in random order against an initially EMPTY skill library: the controller "
                    "recognizes the skill from the person's wrist and the simulated IIWA7 executes the "
                    "conditioned response, or it answers 'unknown', holds still, and the trial's "
                    "demonstration is folded into the library. Writes OUT/summary.json, OUT/library.npz and "
                    "OUT/demo.html (a self-contained meshcat recording of the whole run).")
    p.add_argument("--trials", type=int, default=None,
                   help="number of trials (default: the config's, 20; 8 with --quick)")
    p.add_argument("--subject", type=int, default=None,
                   help="1-based index of the simulated subject (default: the config's, 1)")
    add_subjects_model(p, from_config=True)
    add_config(p)
    p.add_argument("--quick", action="store_true", help="a short run: 8 trials from 4 demonstrations per task")
    p.add_argument("--meshcat", action="store_true",
                   help="serve the recording live on localhost instead of writing demo.html "
                        "(prints the URL, serves until Ctrl-C)")
    add_common(p, "demo", seed=None, seed_help="random seed (default: the config's seed, 0)")
    p.set_defaults(func=run)


def _row(r) -> str:
    flange = "" if not math.isfinite(r.flange_error_cm) else f"{r.flange_error_cm:.1f}"
    rms = "" if not math.isfinite(r.tracking_rms_rad) else f"{r.tracking_rms_rad:.4f}"
    what = r.decision + (f" ({r.recognized_task})" if r.recognized_task else "") + (" -> taught" if r.taught else "")
    return (f"{r.trial + 1:5d}  {r.task:9s}  {what:30s}  {'yes' if r.correct else 'NO':7s}  {flange:>9s}  "
            f"{rms:>9s}")


def run(args: argparse.Namespace) -> int:
    from drake_skills.scenario.salad import generate_subject
    from drake_skills.sim.config import load_config
    from drake_skills.sim.demo import run_collaboration
    from drake_skills.sim.diagram import make_meshcat

    cfg = load_config(args.config)
    overrides = {"seed": args.seed, "subject": args.subject, "subject_model": args.subjects_model}
    if args.quick:
        overrides.update(trials=8, demos_per_task=4)
    if args.trials is not None:
        overrides["trials"] = args.trials
    cfg = replace(cfg, **{k: v for k, v in overrides.items() if v is not None})  # validated again
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    data = generate_subject(cfg.subject, n_demos=cfg.demos_per_task, seed=cfg.seed, model=cfg.subject_model)
    workspace = data.workspace(z_factor=cfg.z_factor)
    t_gen = time.perf_counter() - t0
    print(f"subject {cfg.subject} ({cfg.subject_model}): {len(data.demos)} demonstrations generated in {t_gen:.1f} s; "
          f"{cfg.trials} trials against an empty library")
    meshcat = make_meshcat()
    print(f"{'trial':>5s}  {'task':9s}  {'decision':30s}  {'correct':7s}  {'flange cm':>9s}  {'rms rad':>9s}")
    summary, library = run_collaboration(cfg, data.demos, workspace, meshcat=meshcat,
                                         on_trial=lambda r: print(_row(r), flush=True))
    summary.wall_seconds = time.perf_counter() - t0
    acc = summary.accuracy_after_teaching
    print(f"accuracy after teaching: {'n/a' if not math.isfinite(acc) else f'{100 * acc:.0f}%'} "
          f"({summary.known_trials} trials of taught tasks); unknown -> taught: {summary.unknown}; "
          f"wrong skill executed: {summary.wrong}; components: {summary.components}")
    print(f"flange error at handover (right skill): mean {summary.mean_flange_error_cm:.1f} cm, "
          f"max {summary.max_flange_error_cm:.1f} cm; joint tracking RMS {summary.mean_tracking_rms_rad:.4f} rad; "
          f"joint limits {'held' if summary.within_limits else 'VIOLATED'}")
    print(f"simulated {summary.simulated_seconds:.1f} s in {summary.wall_seconds:.1f} s wall time")
    library.save(args.out / "library.npz")
    (args.out / "summary.json").write_text(json.dumps(
        {"subject": cfg.subject, "subject_model": cfg.subject_model, "seed": cfg.seed, **summary.dict()}, indent=2))
    if args.meshcat:
        print(f"meshcat: open {meshcat.web_url()} to replay the run; Ctrl-C to stop")
        try:
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            print("stopped")
        return 0
    html = args.out / "demo.html"
    html.write_text(meshcat.StaticHtml())
    print(f"wrote {args.out / 'summary.json'}, {args.out / 'library.npz'}, {html}")
    return 0
