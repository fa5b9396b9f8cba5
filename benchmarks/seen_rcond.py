"""How `SEEN_RCOND` was chosen: prefix recognition on development data at several shares.

For each share of the largest eigenvalue of ``Phi^T Phi`` a direction needs to count in the
prefix fit statistic (``drake_skills.promp.interaction.SEEN_RCOND``), two measurements, both on
development data (never the buetepage test split):

* the anticipation and commit tables of ``eval interaction`` on the buetepage **training**
  split by internal validation: per task 6 interactions taught, the other 2 recognized, 3
  draws x ``--orders`` random orders (``InteractionContext.from_splits``);
* how often the gating commits to a beginning of an **untaught** synthetic skill (3 skills of
  ``skill_bank(4, seed, separation=3.0)`` taught 3 times each, the 4th replayed sample by
  sample through ``evaluation.interaction.replay_commits``), over ``--banks`` seeds.

Not a speed benchmark: the experiment behind RESULTS.md's "The prefix test now counts the
directions the samples see well", kept so that it can be re-run (about 1 min per share)::

    .venv/bin/python benchmarks/seen_rcond.py --shares 1e-10,2e-3,0.03
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.data.interaction import load_interactions
from drake_skills.data.synthetic import skill_bank
from drake_skills.data.workspace import Workspace
from drake_skills.evaluation.interaction import (InteractionContext, InteractionSettings, default_data_path,
                                                 development_splits, evaluate_interaction, replay_commits)
from drake_skills.promp import interaction


def _set_share(share: float) -> None:
    interaction.SEEN_RCOND = share        # read at each call; every measurement builds new libraries


def _internal_validation(orders: int):
    settings = InteractionSettings(data=default_data_path(), orders=orders, loo_orders=0)
    train = load_interactions(default_data_path()).train
    return [evaluate_interaction(settings, progress=False, figures=False,
                                 context=InteractionContext.from_splits(taught, held, settings))
            for taught, held in development_splits(train)]


def _mean_rows(tables, columns):
    t0 = tables[0]
    idx = [t0.columns.index(c) for c in columns]
    return [[row[0]] + [float(np.mean([t.rows[i][j] for t in tables])) for j in idx[1:]]
            for i, row in enumerate(t0.rows)]


def _untaught_commits(banks: int) -> tuple[int, int]:
    committed = 0
    for seed in range(banks):
        bank = skill_bank(4, seed, separation=3.0)
        rng = np.random.default_rng(1)
        lib = SkillLibrary(LibraryConfig())
        for _ in range(3):
            for k in range(3):
                lib.partial_fit(bank.demo(k, rng))
        g, _ = replay_commits(lib, bank.demo(3, rng), Workspace(np.zeros(3), np.full(3, 10.0)))
        committed += bool(g.commits)
    return committed, banks


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--shares", default="1e-10,1e-3,2e-3,3e-3,0.01,0.03",
                    help="comma-separated shares to measure (default: %(default)s)")
    ap.add_argument("--orders", type=int, default=6, help="random orders per draw (default: %(default)s)")
    ap.add_argument("--banks", type=int, default=24, help="synthetic skill banks (default: %(default)s)")
    args = ap.parse_args(argv)
    default = interaction.SEEN_RCOND
    try:
        for share in (float(x) for x in args.shares.split(",")):
            _set_share(share)
            reps = _internal_validation(args.orders)
            ant = _mean_rows([r.tables["anticipation"] for r in reps], ["observed", "correct", "wrong", "undecided",
                                                                         "unknown"])
            com = _mean_rows([r.tables["commits"] for r in reps], ["task", "first commit correct",
                                                                    "first commit wrong"])
            n, of = _untaught_commits(args.banks)
            print(f"share {share:g}{' (default)' if share == default else ''}")
            print("  observed: " + "  ".join(f"{r[0]:.1f}: {r[1]:.2f}/{r[2]:.2f}" for r in ant)
                  + "   (correct/wrong, training split)")
            print(f"  first commits correct/wrong, all tasks: {com[-1][1]:.3f} / {com[-1][2]:.3f}")
            print(f"  untaught synthetic skill committed to: {n} / {of} banks", flush=True)
    finally:
        _set_share(default)
    return 0


if __name__ == "__main__":
    sys.exit(main())
