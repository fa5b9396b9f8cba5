"""``drake-skills learn DEMOS_DIR --out DIR``: fold demonstrations into a library, one at a time."""
from __future__ import annotations

import argparse
import contextlib
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
                    "labels of the components, for `recognize`) and OUT/learn.json (what happened). An existing "
                    "OUT/library.npz is replaced only if it is the --library being extended (then the update "
                    "holds the file's lock, so several learns may extend one library at once and none loses "
                    "demonstrations) or with --force.")
    p.add_argument("demos_dir", type=Path, metavar="DEMOS_DIR", help="folder of demonstrations")
    add_out(p, "learn", "library.npz, library.tasks.json and learn.json")
    p.add_argument("--library", type=Path, default=None, metavar="LIB",
                   help="existing library file to extend (default: start empty); it is not modified unless it "
                        "is OUT/library.npz, which is then extended in place under its lock")
    p.add_argument("--force", action="store_true",
                   help="replace an existing OUT/library.npz that is not the --library being extended")
    add_workspace(p)
    add_config(p)  # for a new library only; an extended one keeps its own
    add_seed(p, 0, "seed of the presentation order (default 0)")
    p.add_argument("--in-order", action="store_true", help="present the demonstrations in file order, not shuffled")
    p.add_argument("--raw-units", action="store_true",
                   help="learn demonstrations whose units look wrong: without a workspace, motions that span "
                        "far less or far more than the normalized range (e.g. raw metres or millimetres); with one, "
                        "motions spanning more than ten workspaces (millimetres against a workspace in metres); "
                        "robot values 30 times larger than the library's so far (degrees for radians). Without "
                        "it learn refuses them, as the library's settings would merge or split their skills")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from drake_skills import SkillLibrary
    from drake_skills._lock import FileLock, LockTimeout
    from drake_skills.commands import WorkspaceFinder, scan_paths, tasks_file
    from drake_skills.data.demos import check_layout
    from drake_skills.library import storage
    from drake_skills.library.labels import TaskVotes
    from drake_skills.sim.config import load_library_config

    if args.demos_dir.is_file():
        raise ValueError(f"'{args.demos_dir}' is a file: learn takes the folder of demonstrations it is in "
                         f"(learn {args.demos_dir.parent})")
    if not args.demos_dir.is_dir():
        raise FileNotFoundError(f"demonstration directory '{args.demos_dir}' does not exist")
    found, notes = scan_paths([args.demos_dir])
    for note in notes:
        print(f"note: {note}")
    demos = [d for d, _ in found]
    if not demos:
        raise ValueError(f"no demonstrations (.npz or .csv) found under '{args.demos_dir}'")
    out_file = storage.library_path(args.out / LIBRARY_FILE)
    in_place = args.library is not None and storage.library_path(args.library).resolve() == out_file.resolve()
    _refuse_to_replace(out_file, in_place, args.force)
    if args.library is not None:
        if args.config is not None:
            raise ValueError("--config applies to a new library only; the existing library keeps its own")
        lib = SkillLibrary.load(args.library)
    else:
        lib = SkillLibrary(load_library_config(args.config))
    # every file is checked before anything is learned or written: a bad one leaves nothing half done
    if lib.dim_human_ is not None:
        dims, declared = (lib.dim_human_, lib.dim_robot_), f"the library '{args.library}'"
    else:
        dims, declared = (demos[0].dim_human, demos[0].dim_robot), f"its first demonstration '{demos[0].name}'"
    for d in demos:
        check_layout(d, *dims, declared)
    find = WorkspaceFinder(args.workspace, args.demos_dir)
    workspaces = [find(d.name) for d in demos]
    _check_units(lib, demos, workspaces, args.raw_units)
    with contextlib.ExitStack() as stack:
        try:
            stack.enter_context(FileLock(out_file, timeout=0))
        except LockTimeout:
            print(f"waiting for {out_file}: another process is updating it", flush=True)
            stack.enter_context(FileLock(out_file))
        # under the lock: the file as it is now (another learn may have extended it while we waited)
        _refuse_to_replace(out_file, in_place, args.force)
        if in_place:
            lib = SkillLibrary.load(out_file)
        votes = TaskVotes()
        if args.library is not None and tasks_file(args.library).is_file():
            votes = TaskVotes.from_dict(json.loads(tasks_file(args.library).read_text()))
        return _learn(args, lib, votes, demos, workspaces, notes, out_file, in_place)


def _check_units(lib, demos, workspaces, raw_units: bool) -> None:
    """Refuse a workspace of other dimensions (naming its file) and, unless ``raw_units``, raw-unit motions.

    Without a workspace a demonstration is taken as already normalized ([0, 10]); in raw metres
    the library's settings see every skill as one (salad subject 1 in metres: one component for
    five tasks), in millimetres as many.
    """
    from drake_skills.library.guards import data_warning

    for d, (ws, source) in zip(demos, workspaces):
        if ws is not None and ws.dim != d.dim_human:
            raise ValueError(f"workspace '{source}' is {ws.dim}-D but demo '{d.name}' has {d.dim_human} human "
                             f"columns")
    if raw_units:
        return
    from drake_skills.library.guards import ROBOT_UNITS_FACTOR, units_error

    # the robot's units, checked across the whole batch first: partial_fit compares a demonstration only
    # with those taught before it, so a demonstration in degrees shown first would set the scale
    rms = {d.name: float(np.sqrt(np.mean(np.square(d.robot)))) for d in demos if d.robot is not None}
    if len(rms) >= 2:
        typical = float(np.median(list(rms.values())))
        odd = sorted(n for n, r in rms.items() if r > ROBOT_UNITS_FACTOR * typical)
        if odd:
            raise ValueError(f"demo(s) {', '.join(repr(n) for n in odd[:3])}{' ...' if len(odd) > 3 else ''}: "
                             f"robot values more than {ROBOT_UNITS_FACTOR:g} times the RMS of the other "
                             f"demonstrations (median {typical:.3g}): other units (degrees for radians)? Nothing was "
                             f"learned; convert them, or --raw-units to learn them as they are")

    for d, (ws, source) in zip(demos, workspaces):
        ws = ws if ws is not None else lib.config.workspace
        if ws is not None:
            message = units_error(ws.normalize(d.human, subtract_start=lib.config.subtract_start), ws,
                                  f"demo '{d.name}' (workspace {source or 'of the library config'})")
            if message is not None:
                raise ValueError(message + ", or --raw-units to learn them as they are")
    if lib.config.workspace is not None:
        return
    for d, (ws, _) in zip(demos, workspaces):
        if ws is not None:
            continue
        y = d.human - d.human[0] if lib.config.subtract_start else d.human
        found = data_warning(y, None, False, whole=True, query=False, where=f"demo '{d.name}'",
                             trained_with_workspace=False)
        if found is not None and found[0] == "units":
            extent = float(np.ptp(y, axis=0).max())
            side = "below" if " below " in found[2] else "above"
            raise ValueError(f"demo '{d.name}' has no workspace and spans {extent:.3g} units, far {side} the "
                             f"normalized range [0, 10] the library's settings assume (a whole motion spans 1 to 100 "
                             f"units in it): raw metres or millimetres? Nothing was learned: give the workspace "
                             f"(--workspace FILE, or a workspace.json or calibration.npz beside the "
                             f"demonstrations), or --raw-units to learn them as they are")


def _refuse_to_replace(out_file: Path, in_place: bool, force: bool) -> None:
    if out_file.exists() and not in_place and not force:
        raise FileExistsError(
            f"'{out_file}' exists and is not the --library being extended: refusing to replace it. Pass "
            f"--library {out_file} to extend it, --force to replace it, or another --out")


def _noise_report(config, demos, workspaces) -> dict:
    """Each demonstration's white tracker noise as a share of the arc-length tolerance (normalized units).

    ``adapted`` counts those above ``share`` (``NOISE_SHARE``), whose walk ``adapt_to_noise`` changes
    (``promp.preprocessing.vertex_path``). Noise the tracker smoothed in time is not seen.
    ``glitch_samples`` / ``with_glitches``: samples of the tracker's glitches
    (``promp.preprocessing.spike_samples``) and the demonstrations that have any.
    """
    from drake_skills.promp.preprocessing import NOISE_SHARE, noise_level, spike_samples

    tol = config.resample_tolerance
    if not tol > 0:
        return {"median": None, "max": None, "adapted": 0, "share": NOISE_SHARE, "glitch_samples": 0,
                "with_glitches": 0}
    shares, glitches = [], []
    for d, (ws, _) in zip(demos, workspaces):
        ws = ws if ws is not None else config.workspace
        y = ws.normalize(d.human) if ws is not None else d.human
        shares.append(noise_level(y) / tol)
        glitches.append(int(spike_samples(y, tol).sum()))
    shares = np.asarray(shares)
    return {"median": round(float(np.median(shares)), 4), "max": round(float(shares.max()), 4),
            "adapted": int(np.sum(shares > NOISE_SHARE)), "share": NOISE_SHARE,
            "glitch_samples": int(sum(glitches)), "with_glitches": int(sum(g > 0 for g in glitches))}


def _learn(args, lib, votes, demos, workspaces, notes, out_file: Path, in_place: bool) -> int:
    """Fold the demonstrations into ``lib`` and write the library, its labels and learn.json (``out_file`` locked)."""
    from drake_skills.commands import short_name, tasks_file

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
        u = lib.partial_fit(d, workspace=workspaces[i][0], check_units=not args.raw_units)
        if d.task is not None:
            votes.record(u, d.task)
        counts["created"] += len(u.created)
        counts["merged"] += len(u.merged)
        counts["deleted"] += len(u.deleted)
        what = (f"new component {u.created[0]}" if u.created else f"updated {u.recognized}")
        extra = "".join([f", merged {m[1]}->{m[0]}" for m in u.merged] + [f", deleted {k}" for k in u.deleted])
        print(f"[{n:4d}/{len(demos)}] {short_name(d.name, args.demos_dir)}: {what}{extra}  (K={lib.n_components})",
              flush=True)
    noise = _noise_report(lib.config, demos, workspaces)
    if noise["with_glitches"]:
        print(f"note: {noise['with_glitches']} of {len(demos)} demonstration(s) have tracker glitches "
              f"({noise['glitch_samples']} samples far off the line between their neighbours, then back): "
              + ("replaced by that line" if lib.config.adapt_to_noise else "kept, adapt_to_noise is off"))
    if noise["adapted"]:
        print(f"note: {noise['adapted']} of {len(demos)} demonstration(s) have tracker noise above "
              f"{noise['share']} of the arc-length tolerance (largest {noise['max']:.2f}): their path was smoothed and "
              f"walked with a wider tolerance"
              + ((", its vertices the means of their samples so that a rest adds no path"
                  if lib.config.average_holds else "") if lib.config.adapt_to_noise else
                 " would have been, but adapt_to_noise is off"))
    args.out.mkdir(parents=True, exist_ok=True)
    # in place, the generation check of save confirms no one wrote the file meanwhile (we hold its lock)
    path = lib.save(out_file, expected_generation=lib.generation if in_place else None)
    labels = tasks_file(path)
    labels.write_text(json.dumps(votes.to_dict(), indent=1) + "\n")
    summary = {"library": str(path), "tasks": str(labels), "demos_dir": str(args.demos_dir),
               "extended": None if args.library is None else str(args.library), "n_demos": len(demos),
               "skipped": notes, "workspaces": sources, "without_workspace": raw,
               "n_components": lib.n_components, **counts, "tracker_noise": noise,
               "components": [{"id": c.id, "task": votes.label_of(c.id), "age": c.age,
                               "support": round(c.support, 3)} for c in lib.components],
               "seconds": round(time.perf_counter() - t0, 3)}
    (args.out / "learn.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(f"wrote {path}: {lib.n_components} components "
          f"({counts['created']} created, {counts['merged']} merged, {counts['deleted']} deleted) "
          f"in {summary['seconds']} s; {labels.name} and learn.json beside it")
    return 0

