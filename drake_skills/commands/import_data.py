"""``drake-skills import interactions NPZ --out DIR``: a recorded data set as one file per demonstration.

Writes what ``learn`` and ``recognize`` read: ``DIR/<split>/<task>_<nn>.npz`` (or
``.csv``), a ``workspace.json`` in each split folder (the bounding box of the training
wrists, so training and test are normalized alike) and ``DIR/README.txt``.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path


from drake_skills.commands import add_out

#: Sampling rate assumed for buetepage_hr (its source does not state one; its README says 100 Hz).
RATE_HZ = 100.0


def register(sub) -> None:
    p = sub.add_parser(
        "import", help="convert a recorded data set into one demonstration file per interaction",
        description="Convert a recorded data set into the files `learn` and `recognize` read: one demonstration "
                    "per file under OUT/<split>/, and a workspace.json in each split folder.")
    isub = p.add_subparsers(dest="dataset", metavar="DATASET")
    isub.required = True
    q = isub.add_parser(
        "interactions", help="human-robot interactions in the layout of ../shared/data/buetepage_hr.npz",
        description="Read an interaction data set in the layout of buetepage_hr.npz (arrays human (N, D), robot "
                    "(N, D_r), offsets (n + 1,), task (n,), split (n,); see ../shared/data/README.md) and write "
                    "OUT/<split>/<task>_<nn>.npz: t in seconds (samples at --rate), human = the --columns of "
                    "the human array (metres; 6:9 is the hand), robot = the robot joints (radians), task label. "
                    "OUT/train/workspace.json and OUT/test/workspace.json hold the same workspace: the per-axis "
                    "bounding box of the training split's human columns. Then: `drake-skills learn OUT/train` "
                    "and `drake-skills recognize out/learn/library.npz OUT/test`.")
    q.add_argument("data", type=Path, metavar="NPZ", help="the data set file, e.g. ../shared/data/buetepage_hr.npz")
    q.add_argument("--columns", default="hand", metavar="START:STOP",
                   help="columns of the human array to use: START:STOP or a name (hand: 6:9 of the buetepage_hr "
                        "layout, the default, or all 3 of a file whose human array holds 3; arm, elbow, shoulder)")
    q.add_argument("--rate", type=float, default=RATE_HZ, help=f"sampling rate in Hz (default {RATE_HZ:g})")
    q.add_argument("--max-gap", type=float, default=0.5, metavar="S",
                   help="fill runs of missing samples (NaN/inf) of up to S seconds (lost samples / --rate) by linear "
                        "interpolation, with a warning; longer ones are an error (default 0.5; 0: refuse any)")
    q.add_argument("--csv", action="store_true", help="write CSV files instead of npz")
    add_out(q, "import", "the demonstration files")
    q.set_defaults(func=run_interactions)


def _interactions(path: Path, columns, rate: float, max_gap_s: float = 0.5):
    """``[(Demonstration, split)]`` read by :func:`drake_skills.data.interaction.load_interactions`."""
    from drake_skills.data.interaction import load_interactions

    demos = load_interactions(path, columns=columns, rate_hz=rate, max_gap_s=max_gap_s)
    if all(s is None for s in demos.split):
        raise ValueError(f"data set '{path}' has no 'split' array: the workspace is the bounding box of the "
                         f"training split, so the file must say which interactions are for training")
    return list(zip(demos, demos.split))


def _remove_previous(out: Path) -> None:
    """Delete the demonstration files an earlier import listed in ``out/manifest.json`` (and nothing else)."""
    manifest = out / "manifest.json"
    if not manifest.is_file():
        return
    try:
        old = json.loads(manifest.read_text())
        if "columns" not in old:  # e.g. the manifest of `generate salad`
            raise KeyError("columns")
        paths = [out / f["path"] for f in old["files"]]
    except (ValueError, KeyError, TypeError):
        raise ValueError(f"'{manifest}' is not the manifest of an import: choose another --out") from None
    for p in paths:
        if p.resolve().is_relative_to(out.resolve()) and p.is_file():
            p.unlink()


def run_interactions(args: argparse.Namespace) -> int:
    from drake_skills.data.interaction import column_selection
    from drake_skills.data.workspace import Workspace

    if not args.rate > 0:
        raise ValueError(f"--rate must be positive, got {args.rate}")
    pairs = _interactions(args.data, column_selection(args.columns, "--columns"), args.rate, args.max_gap)
    train = [d for d, s in pairs if s == "train"]
    if not train:
        raise ValueError(f"data set '{args.data}': no interaction in the 'train' split; the workspace is the "
                         f"bounding box of the training wrists")
    ws = Workspace.from_calibration([d.human for d in train])  # per-axis min and max, no z shrink
    out: Path = args.out
    suffix = ".csv" if args.csv else ".npz"
    counts: dict[tuple[str, str], int] = {}
    files = []
    _remove_previous(out)
    for split in sorted({s for _, s in pairs}):
        ws.save(out / split / "workspace.json")
    for d, split in pairs:
        nn = counts[(split, d.task)] = counts.get((split, d.task), -1) + 1
        path = out / split / f"{d.task}_{nn:02d}{suffix}"
        d.save(path)
        files.append({"path": str(path.relative_to(out)), "task": d.task, "split": split, "samples": d.n_samples})
    (out / "manifest.json").write_text(json.dumps({"source": str(args.data), "columns": args.columns,
                                                   "rate_hz": args.rate, "workspace": ws.dict(),
                                                   "files": files}, indent=1) + "\n")
    (out / "README.txt").write_text(
        f"Imported from {args.data} by `drake-skills import interactions` (human columns {args.columns}, "
        f"{args.rate:g} Hz).\n\n<split>/<task>_<nn>{suffix}  one interaction: t (T,) s, human (T, "
        f"{train[0].dim_human}) m, robot (T, {train[0].dim_robot}) rad, task label.\n"
        f"<split>/workspace.json   the workspace: bounding box of the training split's human columns.\n"
        f"manifest.json            the files.\n")
    by_split = {s: sum(1 for _, x in pairs if x == s) for s in sorted({s for _, s in pairs})}
    print(f"wrote {len(pairs)} demonstrations to {out} ("
          + ", ".join(f"{s}: {k}" for s, k in by_split.items()) + f"), workspace {ws}")
    return 0
