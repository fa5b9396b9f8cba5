"""Does the gating see the wrist come to rest when the tracker is noisy?

Not a speed benchmark: the measurement behind RESULTS.md's "The controller with a noisy tracker".
Salad subject 1 (seed 0): 3 demonstrations per task taught and 5 replayed through the gating's
decision logic (``evaluation.interaction.replay_commits``, the default ``DecisionRule``), all with
the same white noise (metres, per axis) added, each replayed motion followed by 1.5 s of rest
(the hand at its last position, with the noise). Prints, per noise level, how many final answers
came from the wrist resting (the others at the rule's 10 s time-out) and the right / wrong ones::

    .venv/bin/python benchmarks/noisy_rest.py --noise 0,0.002,0.005,0.01      # ~30 s
"""
from __future__ import annotations

import argparse

import numpy as np

from drake_skills.data.demonstration import Demonstration
from drake_skills.evaluation.interaction import replay_commits
from drake_skills.evaluation.labeled import LabeledLibrary
from drake_skills.library.config import LibraryConfig
from drake_skills.scenario.salad import generate_subject


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--noise", default="0,0.002,0.005,0.01", help="comma-separated noise levels (m)")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise (default 0)")
    a = p.parse_args(argv)
    data = generate_subject(1, n_demos=8, seed=0)
    ws = data.workspace(z_factor=0.9)
    tasks = sorted({d.task for d in data.demos})
    rng = np.random.default_rng(a.seed)

    def noisy(d, sigma, rest=0.0):
        dt = d.t[1] - d.t[0]
        n = int(round(rest / dt))
        t = np.concatenate([d.t, d.t[-1] + dt * np.arange(1, n + 1)])
        h = np.vstack([d.human, np.repeat(d.human[-1:], n, axis=0)])
        return Demonstration(t=t, human=h + rng.normal(0, sigma, h.shape), robot=None if n else d.robot,
                             task=d.task, name=d.name)

    print("| noise (m) | final answers at rest | right | wrong | of |")
    print("|---|---|---|---|---|")
    for sigma in (float(x) for x in a.noise.split(",")):
        lab = LabeledLibrary(LibraryConfig(workspace=ws))
        for k in range(3):
            for t in tasks:
                lab.teach(noisy(data.by_task(t)[k], sigma))
        rest = right = wrong = n = 0
        for t in tasks:
            for d in data.by_task(t)[3:]:
                g, at_rest = replay_commits(lab.library, noisy(d, sigma, rest=1.5), ws)
                ok = g.status == "skill" and lab.label_of(g.component) == d.task
                rest += at_rest
                right += ok
                wrong += g.status == "skill" and not ok
                n += 1
        print(f"| {sigma:g} | {rest} | {right} | {wrong} | {n} |", flush=True)


if __name__ == "__main__":
    main()
