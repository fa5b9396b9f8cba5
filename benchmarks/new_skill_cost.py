"""What the hypothesis of a skill never taught costs on taught synthetic skills, and what it holds of untaught ones.

Not a speed benchmark: the figures behind RESULTS.md's "A skill never taught, as a hypothesis for beginnings",
its limit. For each of ``--banks`` banks of well-separated synthetic skills (``skill_bank(taught + 1, seed,
separation=2.0)``) a library learns ``--demos`` demonstrations of each of the first ``--taught`` skills,
interleaved; beginnings (``--shares`` of the samples) of a new demonstration of every skill, the last one never
taught, are recognized with the default ``new_skill_weight`` and with it off (the same library)::

    .venv/bin/python benchmarks/new_skill_cost.py          # a few seconds
"""
from __future__ import annotations

import argparse
import sys
import warnings
from dataclasses import replace

import numpy as np

from drake_skills import LibraryConfig, SkillLibrary
from drake_skills.data.synthetic import skill_bank


def measure(banks: int = 8, taught: int = 4, demos: int = 3, shares=(0.3, 0.5, 0.7)) -> dict:
    out = dict.fromkeys(("taught beginnings", "answered right, off", "held, on", "answered wrong, off",
                         "answered wrong, on", "untaught beginnings", "answered, off", "answered, on"), 0)
    for seed in range(banks):
        bank = skill_bank(taught + 1, seed, separation=2.0)
        rng = np.random.default_rng(seed)
        on = SkillLibrary(LibraryConfig())
        for _ in range(demos):
            for k in range(taught):
                on.partial_fit(bank.demo(k, rng))
        off = SkillLibrary.from_state(replace(on.state(), config=replace(on.config, new_skill_weight=0.0)))
        truth = {k: on.recognize(bank.demo(k, rng).human, observed_fraction=1.0).component for k in range(taught)}
        for k in range(taught + 1):
            human = bank.demo(k, rng).human
            for share in shares:
                part = human[:int(share * len(human))]
                a, b = off.recognize(part), on.recognize(part)
                if k < taught:
                    out["taught beginnings"] += 1
                    out["answered right, off"] += a.status == "skill" and a.component == truth[k]
                    out["held, on"] += a.status == "skill" and b.status != "skill"
                    out["answered wrong, off"] += a.status == "skill" and a.component != truth[k]
                    out["answered wrong, on"] += b.status == "skill" and b.component != truth[k]
                else:
                    out["untaught beginnings"] += 1
                    out["answered, off"] += a.status == "skill"
                    out["answered, on"] += b.status == "skill"
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--banks", type=int, default=8, help="synthetic banks (seeds 0 ..; default 8)")
    ap.add_argument("--taught", type=int, default=4, help="skills taught per bank (default 4)")
    ap.add_argument("--demos", type=int, default=3, help="demonstrations per taught skill (default 3)")
    args = ap.parse_args(argv)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = measure(args.banks, args.taught, args.demos)
    for k, v in out.items():
        print(f"{k:24s} {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
