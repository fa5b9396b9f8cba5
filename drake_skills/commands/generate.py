"""``drake-skills generate salad``: write the simulated salad scenario to files."""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

SCENARIOS = ("salad",)


def register(sub) -> None:
    from drake_skills.commands import add_common

    p = sub.add_parser(
        "generate", help="generate simulated demonstrations (the salad scenario)",
        description="Generate the simulated salad scenario of the paper (Sec. 4.2): per subject, the calibration "
                    "half circles and demonstrations of the five tasks (human wrist + IIWA7 joints from Drake "
                    "inverse kinematics). Writes OUT/<subject>/<task>_<nn>.npz, OUT/<subject>/calibration.npz, "
                    "OUT/manifest.json and OUT/README.txt.")
    p.add_argument("scenario", choices=SCENARIOS, help="what to generate")
    p.add_argument("--subjects", type=int, default=10, help="number of subjects (default 10)")
    p.add_argument("--demos", type=int, default=15, help="demonstrations per task and subject (default 15)")
    p.add_argument("--tasks", nargs="+", default=None, metavar="TASK",
                   help="subset of the tasks board tomato bowl dressing standup (default all)")
    p.add_argument("--csv", action="store_true", help="also write each demonstration as CSV")
    add_common(p, "generate")
    p.set_defaults(func=run)


def _remove_previous(out: Path) -> None:
    """Delete what an earlier ``generate`` listed in ``out/manifest.json`` (its files and calibrations), nothing else.

    A run with fewer subjects or demonstrations would otherwise leave the earlier run's
    extra files beside its own, and ``learn`` would read them.
    """
    manifest = out / "manifest.json"
    if not manifest.is_file():
        return
    try:
        old = json.loads(manifest.read_text())
        if "scenario" not in old:
            raise KeyError("scenario")
        paths = [out / f["path"] for f in old["files"]]
        paths += [out / s["name"] / "calibration.npz" for s in old["subjects"]]
    except (ValueError, KeyError, TypeError):
        raise ValueError(f"'{manifest}' is not the manifest of `drake-skills generate`: choose another --out") from None
    for p in paths:
        for f in (p, p.with_suffix(".csv")):
            if f.resolve().is_relative_to(out.resolve()) and f.is_file():
                f.unlink()


def run(args: argparse.Namespace) -> int:
    from drake_skills.data.demos import save_calibration, save_csv, save_npz
    from drake_skills.scenario.salad import SLOPPY_SUBJECTS, TASKS, generate_subject

    tasks = tuple(args.tasks) if args.tasks else TASKS
    unknown = [t for t in tasks if t not in TASKS]
    if unknown:
        raise ValueError(f"unknown task(s) {unknown}; tasks are {list(TASKS)}")
    if args.subjects < 1 or args.demos < 1:
        raise ValueError("--subjects and --demos must be at least 1")
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    _remove_previous(out)
    manifest = {"scenario": args.scenario, "seed": args.seed, "subjects": [], "tasks": list(tasks),
                "demos_per_task": args.demos, "rate_hz": 150.0, "files": []}
    start = time.perf_counter()
    for i in range(1, args.subjects + 1):
        data = generate_subject(i, args.demos, args.seed, tasks)
        sdir = out / data.subject.name
        save_calibration(sdir / "calibration.npz", {"xy": data.calibration[0], "zy": data.calibration[1]})
        for demo in data.demos:
            rel = Path(demo.name + ".npz")
            save_npz(demo, out / rel)
            if args.csv:
                save_csv(demo, out / rel.with_suffix(".csv"))
            manifest["files"].append({"path": str(rel), "subject": demo.subject, "task": demo.task,
                                      "samples": demo.n_samples, "duration": round(demo.duration, 4)})
        s = data.subject
        manifest["subjects"].append({"name": s.name, "arm_length": round(s.arm_length, 4), "sloppy": s.sloppy,
                                     "workspace": data.workspace(z_factor=0.9).dict()})
        print(f"[{i}/{args.subjects}] {s.name}: {len(data.demos)} demonstrations"
              f"{' (sloppy)' if s.sloppy else ''}, {time.perf_counter() - start:.1f} s", flush=True)
    (out / "manifest.json").write_text(json.dumps(manifest, indent=1))
    (out / "README.txt").write_text(
        "Simulated salad scenario (drake-skills generate salad, seed %d).\n\n"
        "<subject>/<task>_<nn>.npz  one demonstration: t (T,) s at 150 Hz, human (T, 3) right wrist in m\n"
        "                           (world frame of models/salad/scene.yaml), robot (T, 7) IIWA7 joints in rad,\n"
        "                           task and subject labels. Load with drake_skills.data.demos.load_npz.\n"
        "<subject>/calibration.npz  the calibration half circles xy and zy (T_i, 3) of Sec. 4.2.2.\n"
        "manifest.json              subjects (arm length, sloppy, workspace), tasks and files.\n\n"
        "Tasks: %s. Sloppy subjects: %s.\n" % (args.seed, ", ".join(tasks),
                                               ", ".join(f"subject{k}" for k in SLOPPY_SUBJECTS)))
    n = len(manifest["files"])
    print(f"wrote {n} demonstrations of {args.subjects} subject(s) to {out} in {time.perf_counter() - start:.1f} s")
    return 0
