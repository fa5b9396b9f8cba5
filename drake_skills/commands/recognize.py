"""``drake-skills recognize LIB PATH...``: which skill is each motion, and what should the robot do."""
from __future__ import annotations

import argparse
import csv
import io
import json
import sys
from pathlib import Path

import numpy as np

from drake_skills.commands import add_out, add_workspace

#: Columns of the printed table and of recognition.csv.
COLUMNS = ("file", "true task", "decision", "skill", "d2", "confidence")


def register(sub) -> None:
    p = sub.add_parser(
        "recognize", help="recognize the skill of human motions and predict the robot's response",
        description="Load a library and demonstration files (or folders of them, searched recursively) and "
                    "print a table: file, true task (the file's label, if any), decision (skill, undecided: "
                    "more than one skill fits and none clearly, with the reason: 'between a and b', or 'seen "
                    "once: k' when the closest skill k was learned from one demonstration and the motion lies beyond "
                    "its stricter limit; or unknown: no skill fits; a motion unknown as a whole that set off more "
                    "than once is read from where it last set off, and the decision says from which sample), the "
                    "skill's task "
                    "name (from the library's .tasks.json written by `learn`) and component id, d2 (squared "
                    "Mahalanobis distance to the best or nearest component; above the novelty limit printed "
                    "under the table a motion is unknown) and the confidence (the best component's posterior among "
                    "the components that fit; components with the same robot response pool theirs for the "
                    "decision, so a skill may show less than 0.99). Only the human part of each file is used "
                    "(a wrist-only file is fine). Writes OUT/recognition.json and OUT/recognition.csv (the table) and, for a "
                    "library with a robot part, OUT/predictions.npz: the conditioned robot trajectory (Eq. 13) "
                    "of every file decided 'skill' in this run, named by file and component.")
    p.add_argument("library", type=Path, metavar="LIB", help="library file (.npz) from `drake-skills learn`")
    p.add_argument("paths", type=Path, nargs="+", metavar="PATH",
                   help="demonstration files (.npz, .csv) or folders of them")
    p.add_argument("--fraction", type=float, default=1.0,
                   help="observe only this fraction of each motion's path (default 1.0, the whole motion)")
    p.add_argument("--keep-going", action="store_true",
                   help="recognize the files that can be read and recognized, list the others with their error "
                        "(recognition.json 'failed') and exit 1; without it the first bad file stops the run")
    add_workspace(p)
    add_out(p, "recognize", "recognition.json, recognition.csv and predictions.npz")
    p.set_defaults(func=run)


def _prefix(lib, human, fraction: float, ws):
    """The first samples of ``human`` covering ``fraction`` of its path, as the library measures it."""
    if fraction >= 1:
        return human
    total = lib.path_length(human, workspace=ws)
    lo, hi = 2, human.shape[0]
    while lo < hi:  # the shortest prefix whose path reaches the fraction
        mid = (lo + hi) // 2
        if lib.path_length(human[:mid], workspace=ws) >= fraction * total:
            hi = mid
        else:
            lo = mid + 1
    return human[:lo]


def _young_components(lib) -> list[int]:
    """Ids of the components the single-demonstration rule applies to now (``library.algorithm.YOUNG_SUPPORT``)."""
    from drake_skills.library.algorithm import YOUNG_SUPPORT, single_demo_rule

    if single_demo_rule(lib.config, lib.state().scale) is None:
        return []
    return [c.id for c in lib.components if c.support < YOUNG_SUPPORT]


def run(args: argparse.Namespace) -> int:
    from drake_skills import SkillLibrary
    from drake_skills.commands import WorkspaceFinder, clear_reports, scan_paths, short_name, tasks_file
    from drake_skills.data.demos import check_layout
    from drake_skills.library.labels import TaskVotes
    from drake_skills.library.novelty import chi2_ppf
    from drake_skills.library.recognition import undecided_reason

    clear_reports(args.out, ("recognition.json", "recognition.csv", "predictions.npz"))
    if not 0 < args.fraction <= 1:
        raise ValueError(f"--fraction must be in (0, 1], got {args.fraction}")
    lib = SkillLibrary.load(args.library)
    if lib.dim_human_ is None or not lib.n_components:
        raise ValueError(f"library file '{args.library}' has no components: learn some demonstrations first")
    labels = tasks_file(args.library)
    votes = TaskVotes.from_dict(json.loads(labels.read_text())) if labels.is_file() else TaskVotes()
    failed = [] if args.keep_going else None
    found, notes = scan_paths(args.paths, failed=failed)
    for note in notes:
        print(f"note: {note}")
    if not found and not failed:
        raise ValueError(f"no demonstrations (.npz or .csv) found in {', '.join(map(str, args.paths))}")
    readable = []
    for d, root in found:  # only the human part is used: a wrist-only recording is what recognition gets
        try:
            check_layout(d, lib.dim_human_, lib.dim_robot_ if d.robot is not None else 0,
                         f"the library '{args.library}'")
        except ValueError as exc:
            if failed is None:
                raise
            failed.append((d.name, str(exc)))
            continue
        readable.append((d, root))
    finders = {}
    rows, preds, raw = [], [], []
    for d, root in readable:
        find = finders.setdefault(root, WorkspaceFinder(args.workspace, root))
        ws, _ = find(d.name)
        try:
            human = _prefix(lib, d.human, args.fraction, ws)
            rec = lib.recognize(human, observed_fraction=args.fraction, workspace=ws)
        except ValueError as exc:
            if failed is None:
                raise ValueError(f"demo '{d.name}': {exc}") from None
            failed.append((d.name, str(exc)))
            continue
        if ws is None:
            raw.append(d.name)
        near = rec.ids.index(rec.best) if rec.best is not None else int(np.argmin(rec.mahalanobis_sq))
        comp = rec.component
        row = {"file": short_name(d.name, root), "path": d.name, "true task": d.task, "decision": rec.status,
               "why": undecided_reason(rec) or ("" if rec.restart is None else
                                                 f"read from sample {rec.restart}: a false start before it"),
               "component": comp, "task": votes.label_of(comp), "nearest": rec.ids[near],
               "d2": float(rec.mahalanobis_sq[near]), "dof": int(rec.dof if np.ndim(rec.dof) == 0 else rec.dof[near]),
               "confidence": rec.confidence, "restart": rec.restart, "contested": list(rec.contested)}
        if comp is not None and lib.has_robot:
            mean, cov = lib.predict_robot(human, args.fraction, workspace=ws, component=comp, restart=rec.restart)
            duration = lib.component(comp).duration
            preds.append((d.name, comp, np.linspace(0.0, duration, mean.shape[0]), mean, cov))
            if d.robot is not None and args.fraction == 1:
                row["final_joint_error_rad"] = float(np.abs(mean[-1] - d.robot[-1]).max())
        rows.append(row)
    print(format_table(rows))
    dofs = sorted({r["dof"] for r in rows})
    limits = ", ".join(f"{chi2_ppf(lib.config.novelty_quantile, k):.1f} for {k} dof" for k in dofs)
    if rows:
        print(f"d2: squared Mahalanobis distance to the best (or, if unknown, the nearest) component;\n"
              f"    a motion is unknown to a component beyond {limits} (chi-square {lib.config.novelty_quantile} "
              f"quantile)")
        young = _young_components(lib)
        if young:
            q1 = lib.config.single_demo_quantile
            strict = ", ".join(f"{chi2_ppf(q1, k):.1f} for {k} dof" for k in dofs)
            print(f"    and to a component learned from one demonstration ({', '.join(map(str, young))}) beyond "
                  f"{strict} (chi-square {q1} quantile, single_demo_quantile), while the library's scale is more "
                  f"prior than data; within the first limit it is not the answer but still a rival (undecided)")
    counts = _counts(rows)
    if counts:
        print("labeled files: " + ", ".join(f"{v} {k}" for k, v in counts.items()))
    if raw:
        print(f"note: {len(raw)} file(s) had no workspace.json or calibration.npz beside them (nor --workspace): "
              f"their positions were taken as already normalized")
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    result = {"library": str(args.library), "tasks": str(labels) if labels.is_file() else None,
              "fraction": args.fraction, "files": rows, "counts": counts, "skipped": notes,
              "without_workspace": raw, "failed": [{"path": str(p), "error": e} for p, e in failed or []]}
    (out / "recognition.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / "recognition.csv").write_text(format_csv(rows))
    written = [out / "recognition.json", out / "recognition.csv"]
    pred_path = out / "predictions.npz"
    if lib.has_robot:
        _save_predictions(pred_path, preds, lib.dim_robot_, lib.config.n_samples)
        written.append(pred_path)
    elif pred_path.exists():
        pred_path.unlink()  # an earlier run's, with another library: it belongs to nothing here
    print(f"wrote {', '.join(str(p) for p in written)}"
          + (f" ({len(preds)} robot trajectories)" if lib.has_robot else ""))
    if failed:
        for path, error in failed:
            named = error if str(path) in error else f"{path}: {error}"  # load errors name the file already
            print(f"drake-skills recognize: error: {named}", file=sys.stderr)
        print(f"drake-skills recognize: {len(failed)} file(s) could not be recognized (listed above and in "
              f"recognition.json 'failed'); the table holds the other {len(rows)}", file=sys.stderr)
        return 1
    return 0


def _save_predictions(path: Path, preds: list, dim_robot: int, n_steps: int) -> None:
    """Arrays ``files`` (n,), ``component`` (n,), ``t`` (n, T), ``robot_mean`` (n, T, D_r), ``robot_cov`` (n, T, D_r, D_r)."""
    from drake_skills._io import atomic_write

    n = len(preds)
    arrays = {
        "format": np.array("drake-skills predictions"),
        "files": np.array([p[0] for p in preds], dtype=str).reshape(n),
        "component": np.array([p[1] for p in preds], dtype=np.int64).reshape(n),
        "t": np.stack([p[2] for p in preds]) if n else np.zeros((0, n_steps)),
        "robot_mean": np.stack([p[3] for p in preds]) if n else np.zeros((0, n_steps, dim_robot)),
        "robot_cov": np.stack([p[4] for p in preds]) if n else np.zeros((0, n_steps, dim_robot, dim_robot)),
    }
    atomic_write(path, lambda f: np.savez(f, **arrays))


def _counts(rows: list[dict]) -> dict:
    """Right / wrong / undecided / unknown over the files with a true task, when the skills have task names."""
    labeled = [r for r in rows if r["true task"] is not None]
    if not labeled or not any(r["task"] for r in rows):
        return {}
    c = {"right skill": 0, "wrong skill": 0, "undecided": 0, "unknown": 0}
    for r in labeled:
        if r["decision"] == "skill":
            c["right skill" if r["task"] == r["true task"] else "wrong skill"] += 1
        else:
            c[r["decision"]] += 1
    return {"files": len(labeled), **c}


def _cells(r: dict) -> list[str]:
    skill = "-" if r["component"] is None else f"{r['task'] or '?'} ({r['component']})"
    conf = "" if r["decision"] == "unknown" else f"{r['confidence']:.2f}"
    decision = f"{r['decision']} ({r['why']})" if r.get("why") else r["decision"]
    return [r["file"], r["true task"] or "-", decision, skill, f"{r['d2']:.1f}", conf]


def format_table(rows: list[dict]) -> str:
    """The rows as an aligned text table with :data:`COLUMNS`."""
    cells = [list(COLUMNS)] + [_cells(r) for r in rows]
    widths = [max(len(c[i]) for c in cells) for i in range(len(COLUMNS))]
    right = {4, 5}
    lines = ["  ".join(c.rjust(w) if i in right else c.ljust(w) for i, (c, w) in enumerate(zip(row, widths)))
             for row in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(line.rstrip() for line in lines)


def format_csv(rows: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["file", "true_task", "decision", "task", "component", "d2", "dof", "confidence", "why"])
    for r in rows:
        w.writerow([r["path"], r["true task"] or "", r["decision"], r["task"] or "",
                    "" if r["component"] is None else r["component"], f"{r['d2']:.6g}", r["dof"],
                    f"{r['confidence']:.6g}", r.get("why", "")])
    return buf.getvalue()

