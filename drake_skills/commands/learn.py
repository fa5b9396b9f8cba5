"""``drake-skills learn DEMOS_DIR --out DIR``: fold demonstrations into a library, one at a time."""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from drake_skills.commands import add_config, add_out, add_seed, add_workspace

LIBRARY_FILE = "library.npz"


def register(sub) -> None:
    p = sub.add_parser(
        "learn", help="learn (or extend) a skill library from a folder of demonstrations",
        description="Fold the demonstrations in DEMOS_DIR (.npz or .csv files, searched recursively; an npz and "
                    "a CSV of the same name are one demonstration) into a skill library one at a time, as the "
                    "robot would during deployment. Each file's workspace (Eq. 14) is the nearest workspace.json "
                    "or calibration.npz in its folder or above it (up to DEMOS_DIR), or --workspace. The first "
                    "demonstration (or --library) declares the dimensions; a file with other columns is an "
                    "error and nothing is written. Writes OUT/library.npz, OUT/library.tasks.json (the task "
                    "labels of the components, for `recognize`) and OUT/learn.json (what happened).")
    p.add_argument("demos_dir", type=Path, metavar="DEMOS_DIR", help="folder of demonstrations")
    add_out(p, "learn", "library.npz, library.tasks.json and learn.json")
    p.add_argument("--library", type=Path, default=None, metavar="LIB",
                   help="existing library file to extend (default: start empty); it is not modified")
    add_workspace(p)
    add_config(p)  # for a new library only; an extended one keeps its own
    add_seed(p, 0, "seed of the presentation order (default 0)")
    p.add_argument("--in-order", action="store_true", help="present the demonstrations in file order, not shuffled")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from drake_skills import SkillLibrary
    from drake_skills.commands import WorkspaceFinder, scan_paths, short_name, tasks_file
    from drake_skills.data.demos import check_layout
    from drake_skills.library.labels import TaskVotes
    from drake_skills.sim.config import load_library_config

    if not args.demos_dir.is_dir():
        raise FileNotFoundError(f"demonstration directory '{args.demos_dir}' does not exist")
    found, notes = scan_paths([args.demos_dir])
    for note in notes:
        print(f"note: {note}")
    demos = [d for d, _ in found]
    if not demos:
        raise ValueError(f"no demonstrations (.npz or .csv) found under '{args.demos_dir}'")
    votes = TaskVotes()
    if args.library is not None:
        if args.config is not None:
            raise ValueError("--config applies to a new library only; the existing library keeps its own")
        lib = SkillLibrary.load(args.library)
        if tasks_file(args.library).is_file():
            votes = TaskVotes.from_dict(json.loads(tasks_file(args.library).read_text()))
    else:
        lib = SkillLibrary(load_library_config(args.config))
    # every file is checked before anything is learned: a bad one leaves nothing half done
    if lib.dim_human_ is not None:
        dims, declared = (lib.dim_human_, lib.dim_robot_), f"the library '{args.library}'"
    else:
        dims, declared = (demos[0].dim_human, demos[0].dim_robot), f"its first demonstration '{demos[0].name}'"
    for d in demos:
        check_layout(d, *dims, declared)
    find = WorkspaceFinder(args.workspace, args.demos_dir)
    workspaces = [find(d.name) for d in demos]
    sources = sorted({str(f) for _, f in workspaces if f is not None})
    raw = sum(ws is None for ws, _ in workspaces)
    print(f"learning from {len(demos)} demonstrations in {args.demos_dir}; library starts with "
          f"{lib.n_components} component(s); workspace from {', '.join(sources) if sources else 'nowhere'}")
    if raw:
        print(f"note: {raw} demonstration(s) have no workspace.json or calibration.npz in their folder or above "
              f"(nor --workspace): their human positions are taken as already normalized")
    order = np.arange(len(demos)) if args.in_order else np.random.default_rng(args.seed).permutation(len(demos))
    t0 = time.perf_counter()
    counts = {"created": 0, "merged": 0, "deleted": 0}
    for n, i in enumerate(order, 1):
        d = demos[i]
        u = lib.partial_fit(d, workspace=workspaces[i][0])
        if d.task is not None:
            votes.record(u, d.task)
        counts["created"] += len(u.created)
        counts["merged"] += len(u.merged)
        counts["deleted"] += len(u.deleted)
        what = (f"new component {u.created[0]}" if u.created else f"updated {u.recognized}")
        extra = "".join([f", merged {m[1]}->{m[0]}" for m in u.merged] + [f", deleted {k}" for k in u.deleted])
        print(f"[{n:4d}/{len(demos)}] {short_name(d.name, args.demos_dir)}: {what}{extra}  (K={lib.n_components})",
              flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    path = lib.save(args.out / LIBRARY_FILE)
    labels = tasks_file(path)
    labels.write_text(json.dumps(votes.to_dict(), indent=1) + "\n")
    summary = {"library": str(path), "tasks": str(labels), "demos_dir": str(args.demos_dir),
               "extended": None if args.library is None else str(args.library), "n_demos": len(demos),
               "skipped": notes, "workspaces": sources, "without_workspace": raw,
               "n_components": lib.n_components, **counts,
               "components": [{"id": c.id, "task": votes.label_of(c.id), "age": c.age,
                               "support": round(c.support, 3)} for c in lib.components],
               "seconds": round(time.perf_counter() - t0, 3)}
    (args.out / "learn.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(f"wrote {path}: {lib.n_components} components "
          f"({counts['created']} created, {counts['merged']} merged, {counts['deleted']} deleted) "
          f"in {summary['seconds']} s; {labels.name} and learn.json beside it")
    return 0

