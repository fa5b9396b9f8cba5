"""``drake-skills learn DEMOS_DIR --out LIB``: fold demonstrations into a library, one at a time."""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


def register(sub) -> None:
    from drake_skills.commands import add_config

    p = sub.add_parser(
        "learn", help="learn (or extend) a skill library from a directory of demonstrations",
        description="Fold the demonstrations in DEMOS_DIR (.npz or .csv files, searched recursively) into a "
                    "skill library one at a time, as the robot would during deployment. A calibration.npz "
                    "beside a subject's demonstrations gives that subject's workspace (Eq. 14).")
    p.add_argument("demos_dir", type=Path, metavar="DEMOS_DIR", help="directory of demonstrations")
    p.add_argument("--out", type=Path, default=Path("out/learn/library.npz"),
                   help="library file to write (default ./out/learn/library.npz)")
    p.add_argument("--library", type=Path, default=None,
                   help="existing library to extend (default: start empty)")
    add_config(p)  # for a new library only; an extended one keeps its own
    p.add_argument("--seed", type=int, default=0, help="seed of the presentation order (default 0)")
    p.add_argument("--in-order", action="store_true", help="present the demonstrations in file order, not shuffled")
    p.set_defaults(func=run)


def _subject_workspaces(demos_dir: Path) -> dict:
    """Workspace per subject directory that has a calibration file."""
    from drake_skills.data.demos import load_calibration
    from drake_skills.data.workspace import Workspace

    out = {}
    for cal in sorted(demos_dir.rglob("calibration.npz")):
        motions = load_calibration(cal)
        if isinstance(motions, dict):
            motions = list(motions.values())
        out[cal.parent.resolve()] = Workspace.from_calibration(motions, z_factor=0.9)
    return out


def run(args: argparse.Namespace) -> int:
    from drake_skills import SkillLibrary
    from drake_skills.data.demos import load_dir
    from drake_skills.sim.config import load_library_config

    if not args.demos_dir.is_dir():
        raise FileNotFoundError(f"demonstration directory '{args.demos_dir}' does not exist")
    demos = load_dir(args.demos_dir)
    if not demos:
        raise ValueError(f"no demonstrations (.npz or .csv) found under '{args.demos_dir}'")
    workspaces = _subject_workspaces(args.demos_dir)
    if args.library is not None:
        if args.config is not None:
            raise ValueError("--config applies to a new library only; the existing library keeps its own")
        lib = SkillLibrary.load(args.library)
    else:
        lib = SkillLibrary(load_library_config(args.config))
    order = np.arange(len(demos)) if args.in_order else np.random.default_rng(args.seed).permutation(len(demos))
    print(f"learning from {len(demos)} demonstrations in {args.demos_dir} "
          f"({len(workspaces)} subject calibration(s)); library starts with {lib.n_components} component(s)")
    t0 = time.perf_counter()
    counts = {"created": 0, "merged": 0, "deleted": 0}
    for n, i in enumerate(order, 1):
        d = demos[i]
        ws = None
        if d.name:
            ws = workspaces.get(Path(d.name).resolve().parent)
        u = lib.partial_fit(d, workspace=ws)
        counts["created"] += len(u.created)
        counts["merged"] += len(u.merged)
        counts["deleted"] += len(u.deleted)
        what = (f"new component {u.created[0]}" if u.created else f"updated {u.recognized}")
        extra = "".join([f", merged {m[1]}->{m[0]}" for m in u.merged] + [f", deleted {k}" for k in u.deleted])
        print(f"[{n:4d}/{len(demos)}] {Path(d.name).name if d.name else i}: {what}{extra}  "
              f"(K={lib.n_components})", flush=True)
    path = lib.save(args.out)
    summary = {"library": str(path), "n_demos": len(demos), "n_components": lib.n_components, **counts,
               "components": [{"id": c.id, "age": c.age, "support": round(c.support, 3)} for c in lib.components],
               "seconds": round(time.perf_counter() - t0, 3)}
    path.with_suffix(".json").write_text(json.dumps(summary, indent=2))
    print(f"wrote {path}: {lib.n_components} components "
          f"({counts['created']} created, {counts['merged']} merged, {counts['deleted']} deleted) "
          f"in {summary['seconds']} s")
    return 0
