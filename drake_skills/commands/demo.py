"""``drake-skills demo``: the open-ended collaboration of the paper's Fig. 2, simulated with Drake."""
from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import asdict, replace

from drake_skills.commands import add_common, add_config, add_subjects_model


def register(sub) -> None:
    p = sub.add_parser(
        "demo", help="simulate the robot learning and answering collaborative skills (IIWA7, salad scene)",
        description="Generate one simulated subject of the salad scenario, then run a stream of trials of the "
                    "five tasks in random order against an initially EMPTY skill library: the controller "
                    "recognizes the skill from the person's wrist and the simulated IIWA7 executes the "
                    "conditioned response, or it answers 'unknown' (stopping a response it may have started on "
                    "the motion's beginning) and the trial's demonstration is folded into the library. Writes OUT/summary.json, OUT/library.npz, "
                    "OUT/trials/trial_NN.png (per trial: component probabilities and estimated phase against "
                    "time, commit and final answer marked) and OUT/demo.html (a self-contained meshcat "
                    "recording of the whole run).")
    p.add_argument("--trials", type=int, default=None,
                   help="number of trials (default: the config's, 20; 8 with --quick)")
    p.add_argument("--subject", type=int, default=None,
                   help="1-based index of the simulated subject (default: the config's, 1)")
    add_subjects_model(p, from_config=True)
    add_config(p)
    p.add_argument("--quick", action="store_true", help="a short run: 8 trials from 4 demonstrations per task")
    p.add_argument("--transport", choices=("direct", "lcm"), default="direct",
                   help="direct: controller and plant wired in one Diagram (default); lcm: the controller Diagram "
                        "and a simulated station talk only over LCM (iiwa driver messages and a wrist message)")
    p.add_argument("--lcm-url", default=None, metavar="URL",
                   help="LCM bus of --transport lcm (default: the config's lcm.url, memq://, an in-process queue); "
                        "e.g. udpm://239.255.76.67:7667?ttl=0 for a real bus that stays on this host")
    p.add_argument("--lcm-latency", type=float, default=None, metavar="S",
                   help="--transport lcm: seconds of latency added to every message by the simulated bus")
    p.add_argument("--lcm-wrist-drop", type=float, default=None, metavar="F",
                   help="--transport lcm: fraction of wrist messages the simulated bus drops (seeded)")
    p.add_argument("--faults", default=None, metavar="KINDS",
                   help="a misbehaving wrist tracker: comma-separated dropout, stale, nan, outlier, latency, start (or "
                        "all), at the rates of drake_skills.systems.wrist_faults.PRESETS; the same trials are "
                        "also run with a perfect tracker and the decisions printed side by side (OUT/faults.json)")
    p.add_argument("--meshcat", action="store_true",
                   help="serve the recording live on localhost instead of writing demo.html "
                        "(prints the URL, serves until Ctrl-C)")
    add_common(p, "demo", seed=None, seed_help="random seed (default: the config's seed, 0)")
    p.set_defaults(func=run)


def _row(r) -> str:
    flange = "" if not math.isfinite(r.flange_error_cm) else f"{r.flange_error_cm:.1f}"
    frac = "" if not math.isfinite(r.decision_fraction) else f"{100 * r.decision_fraction:.0f}%"
    lead = "" if not math.isfinite(r.lead_s) else f"{r.lead_s:+.1f}"
    what = r.decision + (f" ({r.recognized_task})" if r.recognized_task else "") + (" -> taught" if r.taught else "")
    if r.revisions:
        what += f", revised {r.revisions}x"
    return (f"{r.trial:5d}  {r.task:9s}  {what:34s}  {r.outcome:6s}  {frac:>6s}  {lead:>6s}  {flange:>9s}")


def _compare_without_faults(cfg, demos, workspace, faulty, make_sim, out) -> None:
    """Run the same trials with a perfect tracker; print and write both runs' decisions side by side."""
    from drake_skills.sim.demo import run_collaboration
    from drake_skills.systems.wrist_faults import TrackerFaults

    print("the same trials with a perfect tracker:", flush=True)
    clean, _ = run_collaboration(replace(cfg, faults=TrackerFaults()), demos, workspace, meshcat=None,
                                 make_sim=make_sim)
    print(f"{'trial':>5s}  {'task':9s}  {'perfect tracker':24s}  {'faulty tracker':24s}  same")
    rows = []
    for a, b in zip(clean.results, faulty.results):  # TrialResult dicts
        same = (a["decision"], a["outcome"]) == (b["decision"], b["outcome"])
        rows.append({"trial": a["trial"], "task": a["task"], "perfect": f"{a['decision']} {a['outcome']}",
                     "faulty": f"{b['decision']} {b['outcome']}", "same": same})
        print(f"{a['trial']:5d}  {a['task']:9s}  {rows[-1]['perfect']:24s}  {rows[-1]['faulty']:24s}  "
              f"{'yes' if same else 'NO'}")
    counts = {name: {"right": s.right, "wrong": s.wrong, "asked": s.asked, "within_limits": s.within_limits}
              for name, s in (("perfect", clean), ("faulty", faulty))}
    print(f"perfect: right {clean.right}, wrong {clean.wrong}, asked {clean.asked}; faulty: right {faulty.right}, "
          f"wrong {faulty.wrong}, asked {faulty.asked}; same decision in {sum(r['same'] for r in rows)} of "
          f"{len(rows)} trials; joint limits {'held' if faulty.within_limits else 'VIOLATED'} with faults")
    (out / "faults.json").write_text(json.dumps({"faults": asdict(cfg.faults), "trials": rows, **counts},
                                                indent=2) + "\n")


def _result(d: dict):
    from drake_skills.sim.demo import TrialResult

    return TrialResult(**d)


def run(args: argparse.Namespace) -> int:
    from drake_skills.scenario.salad import generate_subject
    from drake_skills.sim.config import load_config
    from drake_skills.sim.demo import run_collaboration
    from drake_skills.sim.diagram import make_meshcat
    from drake_skills.commands.demo_plots import legend_html, plot_trial

    cfg = load_config(args.config)
    overrides = {"seed": args.seed, "subject": args.subject, "subject_model": args.subjects_model}
    if args.quick:
        overrides.update(trials=8, demos_per_task=4)
    if args.trials is not None:
        overrides["trials"] = args.trials
    cfg = replace(cfg, **{k: v for k, v in overrides.items() if v is not None})  # validated again
    lcm_overrides = {"url": args.lcm_url, "latency": args.lcm_latency, "wrist_drop": args.lcm_wrist_drop}
    if args.transport != "lcm" and any(v is not None for v in lcm_overrides.values()):
        raise ValueError("--lcm-url, --lcm-latency and --lcm-wrist-drop need --transport lcm")
    cfg = replace(cfg, lcm=replace(cfg.lcm, **{k: v for k, v in lcm_overrides.items() if v is not None}))
    if args.faults is not None:
        from drake_skills.systems.wrist_faults import faults_from_spec

        cfg = replace(cfg, faults=faults_from_spec(args.faults))
    make_sim = None
    if args.transport == "lcm":
        from drake_skills.sim.lcm_demo import LcmCollaborationSim

        make_sim = LcmCollaborationSim
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    data = generate_subject(cfg.subject, n_demos=cfg.demos_per_task, seed=cfg.seed, model=cfg.subject_model)
    workspace = data.workspace(z_factor=cfg.z_factor)
    t_gen = time.perf_counter() - t0
    print(f"subject {cfg.subject} ({cfg.subject_model}): {len(data.demos)} demonstrations generated in {t_gen:.1f} s; "
          f"{cfg.trials} trials against an empty library"
          + (f"; controller and station over LCM ({cfg.lcm.url})" if make_sim is not None else ""))
    meshcat = make_meshcat()
    print(f"{'trial':>5s}  {'task':9s}  {'decision':34s}  {'result':6s}  {'commit':>6s}  {'lead s':>6s}  "
          f"{'flange cm':>9s}")
    plots = args.out / "trials"
    plots.mkdir(exist_ok=True)
    for old in plots.glob("trial_*.png"):
        old.unlink()

    def on_trial(result, outcome):
        print(_row(result), flush=True)
        plot_trial(result, outcome, plots / f"trial_{result.trial:02d}.png")

    summary, library = run_collaboration(cfg, data.demos, workspace, meshcat=meshcat, on_trial=on_trial,
                                         make_sim=make_sim)
    summary.wall_seconds = time.perf_counter() - t0
    if args.faults is not None:
        _compare_without_faults(cfg, data.demos, workspace, summary, make_sim, args.out)
    acc = summary.accuracy_after_teaching
    print(f"{summary.trials} trials: right {summary.right}, WRONG skill executed {summary.wrong}, asked "
          f"{summary.asked} (unknown {summary.unknown}, undecided at rest {summary.undecided_at_rest}); "
          f"components: {summary.components}")
    print(f"taught tasks: {'n/a' if not math.isfinite(acc) else f'{100 * acc:.0f}%'} right of "
          f"{summary.known_trials} trials; wrong commits revised in time: {summary.wrong_commits - summary.wrong}")
    untaught = summary.trials - summary.known_trials
    if untaught:
        print(f"tasks not yet taught: {untaught} trials; in {summary.untaught_started} of them the robot started "
              f"another task's response on the motion's beginning (largest joint displacement "
              f"{summary.untaught_max_displacement_rad:.2f} rad)")
    if math.isfinite(summary.mean_decision_fraction):
        print(f"the robot committed at {100 * summary.mean_decision_fraction:.0f}% of the person's path on average, "
              f"{summary.mean_lead_s:+.2f} s before the person stopped (over the trials that executed a skill)")
    print(f"flange error at handover (right skill): mean {summary.mean_flange_error_cm:.1f} cm, "
          f"max {summary.max_flange_error_cm:.1f} cm; joint tracking RMS {summary.mean_tracking_rms_rad:.4f} rad; "
          f"joint limits {'held' if summary.within_limits else 'VIOLATED'}")
    print(f"simulated {summary.simulated_seconds:.1f} s in {summary.wall_seconds:.1f} s wall time")
    library.save(args.out / "library.npz")
    (args.out / "summary.json").write_text(json.dumps(
        {"subject": cfg.subject, "subject_model": cfg.subject_model, "seed": cfg.seed, "transport": args.transport,
         **({"lcm": asdict(cfg.lcm)} if make_sim is not None else {}), **summary.dict()}, indent=2))
    if args.meshcat:
        print(f"meshcat: open {meshcat.web_url()} to replay the run; Ctrl-C to stop")
        try:
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            print("stopped")
        return 0
    html = args.out / "demo.html"
    page = meshcat.StaticHtml()
    legend = legend_html([_result(r) for r in summary.results])
    page = page.replace("</body>", legend + "</body>", 1) if "</body>" in page else page + legend
    html.write_text(page)
    print(f"wrote {args.out / 'summary.json'}, {args.out / 'library.npz'}, {plots}/trial_*.png, {html}")
    return 0
