"""``drake-skills control``: the controller alone, over LCM, for a real robot (or a station elsewhere)."""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import asdict, replace

from drake_skills.commands import add_common, add_config, add_subjects_model

#: LCM's default URL (what drake-iiwa-driver uses without --lcm_url): multicast that stays on this host.
DEFAULT_URL = "udpm://239.255.76.67:7667?ttl=0"


def register(sub) -> None:
    p = sub.add_parser(
        "control", help="run the skill-library controller over LCM (a real KUKA iiwa and a wrist tracker)",
        description="Run the controller Diagram alone: it subscribes to lcmt_iiwa_status (IIWA_STATUS) and to the "
                    "wrist (lcmt_drake_signal on DRAKE_SKILLS_WRIST, metres) and publishes position-only "
                    "lcmt_iiwa_command (IIWA_COMMAND) every 5 ms, trial after trial: observe the wrist, decide, "
                    "execute the conditioned motion or hold, start over. A stale status (none for 100 ms) freezes "
                    "the command. The library is not taught here. Writes OUT/control.json (one record per "
                    "trial). See README, 'On a real robot'.")
    p.add_argument("--library", type=_existing, required=True, metavar="LIB",
                   help="library file (.npz) from 'drake-skills learn' or 'drake-skills demo'")
    p.add_argument("--lcm-url", default=DEFAULT_URL, metavar="URL",
                   help=f"LCM bus (default {DEFAULT_URL}, LCM's default and the iiwa driver's, which stays on this "
                        f"host; ttl=1 reaches the robot's network; memq:// only this process)")
    who = p.add_mutually_exclusive_group(required=True)
    who.add_argument("--calibration", type=_existing, metavar="NPZ",
                     help="the person's calibration motions (calibration.npz, as 'generate salad' writes): "
                          "their workspace normalizes the wrist (Eq. 14)")
    who.add_argument("--subject", type=int, metavar="N",
                     help="use the workspace of simulated salad subject N (for a simulated station)")
    add_subjects_model(p, from_config=True)
    p.add_argument("--trials", type=int, default=None, help="stop after this many trials (default: run until Ctrl-C)")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="stop after this many seconds of controller time (default: run until Ctrl-C)")
    p.add_argument("--wait", type=float, default=None, metavar="S",
                   help="seconds to wait for the first status and wrist messages (default: the config's "
                        "lcm.wait_for_messages, 10)")
    p.add_argument("--realtime-rate", type=float, default=1.0,
                   help="pace the controller's clock to this multiple of the wall clock (default 1.0; a robot "
                        "needs 1.0)")
    add_config(p)
    add_common(p, "control", seed=None, seed_help="seed of --subject's simulated data (default: the config's, 0)")
    p.set_defaults(func=run)


def _existing(text: str):
    from pathlib import Path

    path = Path(text)
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"'{text}' is not a file")
    return path


def run(args: argparse.Namespace) -> int:
    from drake_skills import SkillLibrary
    from drake_skills.data.demos import load_calibration
    from drake_skills.data.workspace import Workspace
    from drake_skills.sim.config import load_config
    from drake_skills.sim.lcm_controller import ControllerRunner, build_lcm_controller

    cfg = load_config(args.config)
    cfg = replace(cfg, seed=cfg.seed if args.seed is None else args.seed,
                  subject_model=cfg.subject_model if args.subjects_model is None else args.subjects_model,
                  lcm=replace(cfg.lcm, url=args.lcm_url,
                              **({} if args.wait is None else {"wait_for_messages": args.wait})))
    if args.trials is not None and args.trials < 1 or args.duration is not None and not args.duration > 0:
        raise ValueError("--trials must be >= 1 and --duration positive")
    if not args.realtime_rate >= 0:
        raise ValueError("--realtime-rate must be >= 0")
    library = SkillLibrary.load(args.library)
    if args.calibration is not None:
        workspace = Workspace.from_calibration(list(load_calibration(args.calibration).values()),
                                               z_factor=cfg.z_factor)
        who = f"calibration {args.calibration}"
    else:
        from drake_skills.scenario.salad import generate_subject

        workspace = generate_subject(args.subject, n_demos=1, seed=cfg.seed,
                                     model=cfg.subject_model).workspace(z_factor=cfg.z_factor)
        who = f"simulated subject {args.subject} ({cfg.subject_model})"
    if library.n_components == 0:
        print(f"warning: {args.library} has no components: every motion will be answered 'unknown'")
    diagram, handles = build_lcm_controller(cfg, library=library, workspace=workspace)
    runner = ControllerRunner(diagram, handles, cfg, realtime_rate=args.realtime_rate)
    c = cfg.lcm
    print(f"controller: {library.n_components} skills from {args.library}, workspace of {who}")
    print(f"LCM {c.url}: status '{c.status_channel}', wrist '{c.wrist_channel}' in; commands '{c.command_channel}' "
          f"every {1000 * c.command_period:g} ms; waiting up to {c.wait_for_messages:g} s for the robot and tracker")
    args.out.mkdir(parents=True, exist_ok=True)
    stopped = f"{args.trials} trials done"
    t_wall = time.perf_counter()
    try:
        try:
            runner.start()
        except TimeoutError as exc:
            print(f"drake-skills control: error: {exc}", file=sys.stderr)
            return 1
        t_stop = runner.time + (args.duration if args.duration is not None else math.inf)
        print(f"{'trial':>5s}  {'decision':12s}  {'decided at s':>12s}  {'ended at s':>10s}  held (stale status)")
        while args.trials is None or len(runner.trials) < args.trials:
            if runner.time >= t_stop - 1e-9:
                stopped = "duration reached"
                break
            for trial in runner.advance_to(min(runner.time + 1.0, t_stop)):
                decided = "" if math.isnan(trial.decision_time) else f"{trial.decision_time:.2f}"
                print(f"{trial.trial + 1:5d}  {trial.decision:12s}  {decided:>12s}  {trial.end_time:10.2f}  "
                      f"{'yes' if trial.held_for_stale_status else 'no'}", flush=True)
    except KeyboardInterrupt:
        stopped = "stopped by Ctrl-C"
    except (RuntimeError, SystemExit) as exc:  # e.g. Drake's status receiver on a message of another robot
        what = " ".join(str(exc).split()) or type(exc).__name__
        stopped = f"error: {what}"
        hint = (f" (a status on '{c.status_channel}' whose num_joints is not 7)" if "num_joints" in what else "")
        print(f"drake-skills control: error: the controller stopped, no more commands are sent: {what}{hint}",
              file=sys.stderr)
    records = [_jsonable(asdict(t)) for t in runner.trials[:args.trials]]
    if not stopped.endswith("done"):
        unfinished = runner.stop()
        if unfinished is not None:
            records.append({**_jsonable(asdict(unfinished)), "unfinished": True})
    (args.out / "control.json").write_text(json.dumps(
        {"library": str(args.library), "workspace": who, "lcm": asdict(c), "stopped": stopped,
         "wall_seconds": round(time.perf_counter() - t_wall, 3), "trials": records}, indent=2))
    print(f"{stopped}: {sum(1 for r in records if not r.get('unfinished'))} trials; wrote {args.out / 'control.json'}")
    if stopped.startswith("error:"):
        return 1
    return 0


def _jsonable(x):
    """NaN -> None, dict keys -> str (a JSON record)."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x
