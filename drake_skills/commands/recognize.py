"""``drake-skills recognize LIB DEMO``: which skill is this motion, and what should the robot do."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def register(sub) -> None:
    p = sub.add_parser(
        "recognize", help="recognize the skill of a human motion and predict the robot's response",
        description="Load a library and a demonstration file; print the recognized component (or 'unknown') "
                    "with the responsibilities and, for a library with a robot part, write the conditioned "
                    "robot trajectory (Eq. 13) to OUT/prediction.npz.")
    p.add_argument("library", type=Path, metavar="LIB", help="library file (.npz) from 'drake-skills learn'")
    p.add_argument("demo", type=Path, metavar="DEMO", help="demonstration file (.npz or .csv); only the human part is used")
    p.add_argument("--fraction", type=float, default=1.0,
                   help="observe only this fraction of the motion's path (default 1.0)")
    p.add_argument("--calibration", type=Path, default=None,
                   help="calibration.npz of the subject (default: the one beside DEMO, if any)")
    from drake_skills.commands import add_common

    add_common(p, "recognize")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from drake_skills import SkillLibrary
    from drake_skills.data.demos import load_calibration, load_demo
    from drake_skills.data.workspace import Workspace

    lib = SkillLibrary.load(args.library)
    demo = load_demo(args.demo)
    cal = args.calibration or (args.demo.parent / "calibration.npz")
    ws = None
    if cal.exists():
        motions = load_calibration(cal)
        ws = Workspace.from_calibration(list(motions.values()) if isinstance(motions, dict) else motions,
                                        z_factor=0.9)
    human = demo.human
    if args.fraction < 1:
        # keep the samples up to the given fraction of the path length
        step = np.linalg.norm(np.diff(human, axis=0), axis=1)
        cut = int(np.searchsorted(np.cumsum(step), args.fraction * step.sum())) + 1
        human = human[: max(cut, 2) + 1]
    rec = lib.recognize(human, observed_fraction=args.fraction, workspace=ws)
    label = "unknown (ask for a demonstration)" if rec.component is None else f"component {rec.component}"
    print(f"{args.demo}: {label}" + (f"  [true task: {demo.task}]" if demo.task else ""))
    for k, r, d2 in sorted(zip(rec.ids, rec.responsibilities, rec.mahalanobis_sq), key=lambda x: -x[1]):
        print(f"  component {k:3d}: responsibility {r:.3f}  Mahalanobis^2 {d2:9.1f} (dof {rec.dof})")
    out = {"demo": str(args.demo), "component": rec.component, "ids": list(rec.ids),
           "responsibilities": rec.responsibilities.tolist(), "mahalanobis_sq": rec.mahalanobis_sq.tolist()}
    args.out.mkdir(parents=True, exist_ok=True)
    if rec.component is not None and lib.has_robot:
        mean, cov = lib.predict_robot(human, args.fraction, workspace=ws, component=rec.component)
        duration = lib.component(rec.component).duration
        np.savez(args.out / "prediction.npz", t=np.linspace(0, duration, mean.shape[0]), robot_mean=mean, robot_cov=cov)
        print(f"  robot: {mean.shape[0]} samples over {duration:.2f} s, final q = {np.round(mean[-1], 3).tolist()}")
        if demo.robot is not None:
            err = np.abs(mean[-1] - demo.robot[-1]).max()
            out["final_joint_error_rad"] = float(err)
            print(f"  max final joint error vs the demonstration: {err:.4f} rad")
        print(f"  wrote {args.out / 'prediction.npz'}")
    (args.out / "recognition.json").write_text(json.dumps(out, indent=2))
    return 0
