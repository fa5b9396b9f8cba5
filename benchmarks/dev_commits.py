"""First commits of the gating on development data: leave one out over the buetepage TRAINING split.

Each training interaction in turn is held out; the library (the defaults, workspace the bounding
box of the other 31) learns the other 31 in ``--orders`` random orders (interleaved or task by
task), and the held-out one is replayed through the gating's decision logic
(:func:`~drake_skills.evaluation.interaction.replay_commits`, the controller's re-decisions every
62.5 ms) with each ``--confirmations`` value of the decision rule. Prints every wrong first
commit, then per value: first commits wrong / right / none, the median share of the person's path
at commit, and the skills executed right / wrong. The source's test split is never touched.

Not a speed benchmark: the tool behind RESULTS.md's follow-up of the task-by-task regression
("Fragments of one task"; about 2 min per teaching order at 3 orders on the shared 2-core machine)::

    .venv/bin/python benchmarks/dev_commits.py --teaching row --orders 3 --confirmations 2,3
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace

import numpy as np

from drake_skills import LibraryConfig
from drake_skills.data.interaction import load_interactions
from drake_skills.evaluation.interaction import (commit_share, default_data_path, replay_commits, teaching_order,
                                                 workspace_of)
from drake_skills.evaluation.labeled import CORRECT, WRONG, LabeledLibrary
from drake_skills.systems.decision_rule import DecisionRule


def sweep(teaching: str = "random", orders: int = 3, confirmations=(2,), data=None, out=sys.stdout) -> dict:
    """Run the replay; return ``{confirmations: [(task, first outcome or None, share, executed outcome)]}``."""
    train = list(load_interactions(data or default_data_path()).train)
    res: dict = {c: [] for c in confirmations}
    for i, held in enumerate(train):
        others = train[:i] + train[i + 1:]
        ws = workspace_of(others)
        for o in range(orders):
            rng = np.random.default_rng(1000 * i + o)
            lab = LabeledLibrary(replace(LibraryConfig(), workspace=ws))
            for j in teaching_order([d.task for d in others], rng, teaching):
                lab.teach(others[j])
            cfg = lab.library.config
            for c in confirmations:
                g, _ = replay_commits(lab.library, held, ws, DecisionRule(confirmations=c))
                first, share = None, float("nan")
                if g.commits:
                    share = commit_share(held, ws, cfg.resample_tolerance, g.commit_time, **cfg.walk_options())
                    first = lab.outcome(g.commits[0], held.task)
                executed = lab.outcome(g.component, held.task, g.status)
                res[c].append((held.task, first, share, executed))
                if first == WRONG:
                    print(f"  confirmations {c}: {held.task} (training interaction {i}), order {o}: first commit "
                          f"{lab.label_of(g.commits[0])} at {share:.3f} of the path", file=out, flush=True)
        print(f"  {i + 1} of {len(train)} held out", file=sys.stderr, flush=True)
    for c, rows in res.items():
        n = len(rows)
        wrong = sum(r[1] == WRONG for r in rows)
        right = sum(r[1] == CORRECT for r in rows)
        shares = np.array([r[2] for r in rows if r[1] is not None])
        ex_right = sum(r[3] == CORRECT for r in rows)
        ex_wrong = sum(r[3] == WRONG for r in rows)
        median = f"{np.median(shares):.3f}" if shares.size else "-"
        print(f"{teaching}, confirmations {c}: {n} replays; first commits wrong {wrong}, right {right}, none "
              f"{n - wrong - right}; median path share at commit {median}; executed right {ex_right}, wrong "
              f"{ex_wrong}", file=out, flush=True)
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--teaching", choices=("random", "row"), default="random",
                    help="order of the taught interactions: random, or task by task (default: random)")
    ap.add_argument("--orders", type=int, default=3, help="random orders per held-out interaction (default: 3)")
    ap.add_argument("--confirmations", default="2",
                    help="comma-separated DecisionRule.confirmations values (default: 2, the rule's default)")
    ap.add_argument("--data", default=None, help="buetepage_hr.npz (default: the shared data folder)")
    a = ap.parse_args(argv)
    try:
        conf = tuple(int(v) for v in a.confirmations.split(","))
    except ValueError:
        ap.error(f"--confirmations: comma-separated integers, got {a.confirmations!r}")
    if a.orders < 1 or any(c < 1 for c in conf):
        ap.error("--orders and every --confirmations value must be >= 1")
    sweep(a.teaching, a.orders, conf, a.data)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
