"""Tasks the wrist cannot tell apart: buetepage_hr with one task's human motions given to another task's
interactions, learned with and without the task-name settings of ``LibraryConfig``.

Not a speed benchmark: the experiment behind RESULTS.md's "Skills taught as several tasks". One of our kept-back
real sets (a camera-tracked human-human handover set) cannot be separated from the wrist alone (labelled
nearest neighbour 0.44-0.59), so a library merges its tasks. To measure that case here, task B's interactions keep
their own robot response (and name) but get the human motion of another repetition of task A, drawn at random:
the wrist says nothing about A or B. Three such constructions (hand_wave -> hand_shake, parachute -> rocket,
hand_shake -> parachute) and the data as recorded; whole motions recognized (correct / wrong / unknown /
undecided) and components, with the defaults (``keep_tasks_apart``, ``same_task_reach`` 2, ``mixed_task_share``
0.2, ``other_task_reach`` 2), without the reach, without both recognition rules, and with the names not used at all.

Development data by default: the buetepage TRAINING split by internal validation (``development_splits``: per task
6 taught, the rest held out, 3 draws x ``--orders`` orders; the borrowed human motions come from the training split
too). ``--split test``: learn the training split, recognize the source's test split (``--orders`` orders)::

    .venv/bin/python benchmarks/inseparable.py                 # about 2 min on the shared 2-core machine
    .venv/bin/python benchmarks/inseparable.py --split test
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace

import numpy as np

from drake_skills import Demonstration, LibraryConfig
from drake_skills.data.interaction import load_interactions
from drake_skills.data.workspace import Workspace
from drake_skills.evaluation.interaction import default_data_path, development_splits
from drake_skills.evaluation.labeled import CORRECT, UNDECIDED, UNKNOWN, WRONG, LabeledLibrary

CONSTRUCTIONS = (("hand_wave", "hand_shake"), ("parachute", "rocket"), ("hand_shake", "parachute"), (None, None))
#: The settings compared (column headers): the defaults; without the reach; without either recognition rule (the
#: names still used to learn); the names not used at all (counted only: the paper's library).
VARIANTS = {"defaults": {}, "other_task_reach 0": {"other_task_reach": 0.0},
            "recognition rules off": {"mixed_task_share": 1.0, "other_task_reach": 0.0},
            "names unused": {"mixed_task_share": 1.0, "other_task_reach": 0.0, "same_task_reach": 1.0,
                             "keep_tasks_apart": False}}


def borrowed(demos, pool, a: str | None, b: str | None, rng: np.random.Generator) -> list[Demonstration]:
    """``demos`` with every interaction of task ``b`` given the human motion of a random interaction of ``a`` from
    ``pool`` (its robot response resampled to that motion's length, its name kept); None: unchanged."""
    if a is None:
        return list(demos)
    donors = [d for d in pool if d.task == a]
    out = []
    for d in demos:
        if d.task != b:
            out.append(d)
            continue
        src = donors[int(rng.integers(len(donors)))]
        z = np.linspace(0.0, 1.0, src.t.shape[0])
        zr = np.linspace(0.0, 1.0, d.t.shape[0])
        robot = np.stack([np.interp(z, zr, d.robot[:, j]) for j in range(d.robot.shape[1])], axis=1)
        out.append(Demonstration(t=src.t, human=src.human, robot=robot, task=b, name=f"{d.name}<-{src.name}"))
    return out


def evaluate(pairs, workspace, orders: int, seed: int = 0) -> dict:
    """{(a, b, variant): (counts (4,) in CORRECT, WRONG, UNKNOWN, UNDECIDED order, mean components)}."""
    out = {}
    for a, b in CONSTRUCTIONS:
        for share in VARIANTS:
            counts, ks = np.zeros(4), []
            for p, (taught, held, pool) in enumerate(pairs):
                for o in range(orders):
                    rng = np.random.default_rng(seed + 1000 * p + o)
                    tr = borrowed(taught, pool, a, b, rng)
                    te = borrowed(held, pool, a, b, rng)
                    lab = LabeledLibrary(LibraryConfig(workspace=workspace, **VARIANTS[share]))
                    for j in rng.permutation(len(tr)):
                        lab.teach(tr[j])
                    ks.append(lab.library.n_components)
                    for d in te:
                        counts[lab.classify(d.human, d.task)[0]] += 1
            out[(a, b, share)] = (counts, float(np.mean(ks)))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--split", choices=("dev", "test"), default="dev",
                    help="dev: the training split by internal validation (default); test: the source's test split")
    ap.add_argument("--orders", type=int, default=4, help="random orders per draw (default: %(default)s)")
    ap.add_argument("--data", default=None, help="buetepage_hr.npz (default: the shared data folder)")
    args = ap.parse_args(argv)
    inter = load_interactions(args.data or default_data_path())
    train, test = list(inter.train), list(inter.test)
    ws = Workspace(np.min([d.human.min(0) for d in train], 0), np.max([d.human.max(0) for d in train], 0))
    if args.split == "dev":
        pairs = [(list(t), list(h), list(t) + list(h)) for t, h in development_splits(train)]
    else:
        pairs = [(train, test, train + test)]
    res = evaluate(pairs, ws, args.orders)
    print(f"## {args.split}: whole motions, correct / wrong / unknown / undecided (components)\n")
    print("| construction | " + " | ".join(VARIANTS) + " |\n|" + "---|" * (len(VARIANTS) + 1))
    for a, b in CONSTRUCTIONS:
        cells = []
        for share in VARIANTS:
            c, k = res[(a, b, share)]
            f = c[[CORRECT, WRONG, UNKNOWN, UNDECIDED]] / c.sum()
            cells.append(" / ".join(f"{x:.3f}" for x in f) + f" ({k:.1f})")
        name = "as recorded" if a is None else f"{b} given {a}'s motions"
        print(f"| {name} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
