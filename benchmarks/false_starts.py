"""False starts on development data: held-out motions with a false start put before them, read with and without
``LibraryConfig.skip_false_starts``.

Not a speed benchmark: the experiment behind RESULTS.md's "False starts". Development data only (the buetepage
TRAINING split by internal validation, ``development_splits``: 3 draws x ``--orders`` orders; LASA half A: the
15 shapes the defaults were chosen on, 4 demonstrations of each taught, 3 held out, 3 draws). Every held-out
motion is recognized three ways: clean; after a false start that is the first 15-35 % of its own path, out and
back to near where it began ("same"); after the first 15-35 % of the path of a motion of another task, moved to
begin where this one begins, out and back ("other"). The false start comes back up to 5 % of the motion's extent
away from its start (a random direction), and the motion itself is moved there. Whole motions (``observed_fraction=1``) and beginnings (the real
motion cut at 30 / 50 / 70 % of its path after the false start, the phase estimated), each as correct / wrong /
unknown / undecided, with the setting on and off::

    .venv/bin/python benchmarks/false_starts.py            # about 3 min on the shared 2-core machine
    .venv/bin/python benchmarks/false_starts.py --orders 1 --data-sets lasa
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace

import numpy as np

from drake_skills import Demonstration, LibraryConfig
from drake_skills.data.interaction import load_interactions
from drake_skills.data.lasa import LASA_SHAPES, lasa_workspace, load_lasa
from drake_skills.data.workspace import Workspace
from drake_skills.evaluation.interaction import default_data_path, development_splits
from drake_skills.evaluation.labeled import LabeledLibrary

OUTCOMES = ("correct", "wrong", "unknown", "undecided")  # the order of evaluation.labeled's codes
KINDS = ("clean", "same", "other")
BEGINNINGS = (0.3, 0.5, 0.7)


def _path_index(human: np.ndarray, share: float) -> int:
    """The first sample at which the summed distance between samples reaches ``share`` of the whole."""
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(human, axis=0), axis=1))])
    return int(np.searchsorted(s, share * s[-1]))


def with_false_start(demo: Demonstration, rng: np.random.Generator, source: Demonstration | None = None
                     ) -> tuple[Demonstration, int]:
    """``demo`` after a false start (the first 15-35 % of ``source``'s path, or of its own, out and back to within
    5 % of ``demo``'s extent of its start; ``demo`` moved to begin there), and the sample where ``demo`` begins."""
    src = demo if source is None else source
    i = max(2, _path_index(src.human, rng.uniform(0.15, 0.35)))
    out = src.human[:i] - src.human[0] + demo.human[0]
    # the person comes back near, not exactly to, where they began: up to 5 % of the motion's extent away
    extent = float(np.linalg.norm(demo.human - demo.human[0], axis=1).max())
    miss = rng.normal(size=demo.human.shape[1])
    miss *= rng.uniform(0.0, 0.05) * extent / np.linalg.norm(miss)
    back = out[::-1][1:] + np.linspace(0.0, 1.0, len(out) - 1)[:, None] * miss
    lead = np.vstack([out, back])
    human = np.vstack([lead, demo.human[1:] + miss])
    t = np.mean(np.diff(demo.t)) * np.arange(len(human))
    robot = None if demo.robot is None else np.vstack([np.repeat(demo.robot[:1], len(lead), 0), demo.robot[1:]])
    return Demonstration(t=t, human=human, robot=robot, task=demo.task, name=f"{demo.name}+false-start"), len(lead) - 1


def evaluate(splits, config: LibraryConfig, orders: int, seed: int = 0) -> dict:
    """Counts ``{(kind, observed): array(4)}`` (observed: 1.0 whole, else the beginning's share), setting on and off."""
    counts = {}
    for on in (True, False):
        cfg = replace(config, skip_false_starts=on)
        rng = np.random.default_rng(seed)
        for taught, held in splits:
            for o in range(orders):
                lab = LabeledLibrary(cfg)
                for j in np.random.default_rng(o).permutation(len(taught)):
                    lab.teach(taught[j])
                for d in held:
                    others = [x for x in list(taught) + list(held) if x.task != d.task]
                    motions = {"clean": (d, 0), "same": with_false_start(d, rng),
                               "other": with_false_start(d, rng, others[rng.integers(len(others))])}
                    for kind, (m, begin) in motions.items():
                        key = (on, kind, 1.0)
                        counts.setdefault(key, np.zeros(4))[lab.classify(m.human, m.task)[0]] += 1
                        for f in BEGINNINGS:
                            end = begin + max(2, _path_index(m.human[begin:], f))
                            out = lab.classify(m.human[:end], m.task, observed_fraction=None)[0]
                            counts.setdefault((on, kind, f), np.zeros(4))[out] += 1
    return counts


def _buetepage(path, orders):
    train = list(load_interactions(path).train)
    lo = np.min([d.human.min(0) for d in train], 0)
    hi = np.max([d.human.max(0) for d in train], 0)
    return development_splits(train), LibraryConfig(workspace=Workspace(lo, hi)), orders


def _lasa(draws=3):
    shapes = tuple(LASA_SHAPES[0::2])
    demos = load_lasa(shapes, 7, subsample=2)
    splits = []
    for o in range(draws):
        rng = np.random.default_rng(100 + o)
        taught, held = [], []
        for s in shapes:
            idx = rng.permutation([i for i, d in enumerate(demos) if d.task == s])
            taught += [demos[i] for i in idx[:4]]
            held += [demos[i] for i in idx[4:]]
        splits.append((taught, held))
    return splits, LibraryConfig(workspace=lasa_workspace(demos)), 1


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--orders", type=int, default=4, help="random orders per buetepage draw (default: %(default)s)")
    ap.add_argument("--data-sets", default="buetepage,lasa", help="comma-separated: buetepage, lasa (default: %(default)s)")
    ap.add_argument("--data", default=None, help="buetepage_hr.npz (default: the shared data folder)")
    args = ap.parse_args(argv)
    for name in args.data_sets.split(","):
        if name == "buetepage":
            splits, cfg, orders = _buetepage(args.data or default_data_path(), args.orders)
        elif name == "lasa":
            splits, cfg, orders = _lasa()
        else:
            raise SystemExit(f"false_starts: unknown data set {name!r}; use buetepage or lasa")
        counts = evaluate(splits, cfg, orders)
        print(f"\n## {name}: correct / wrong / unknown / undecided, skip_false_starts on | off\n")
        print("| motion | observed | on | off |\n|---|---|---|---|")
        for kind in KINDS:
            for f in (1.0,) + BEGINNINGS:
                cells = []
                for on in (True, False):
                    c = counts[(on, kind, f)]
                    cells.append(" / ".join(f"{x:.3f}" for x in c / c.sum()))
                where = "whole" if f == 1.0 else f"{int(100 * f)} % of its path"
                print(f"| {kind} | {where} | {cells[0]} | {cells[1]} |")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
