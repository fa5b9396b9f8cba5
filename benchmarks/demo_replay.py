"""Replay `drake-skills demo`'s trial streams offline through the gating's decision logic (no Drake).

For every subject and seed, the demo's stream of trials (``sim.demo.trial_stream``) is fed
sample by sample to ``systems.gating.gating_step`` (via
``evaluation.interaction.replay_commits``) against a library that, as in the demo, learns a
trial's demonstration only when the robot asks (the final answer is not a skill). Counts:
skills executed right and wrong, asked (a taught task answered unknown or undecided), new
(an untaught task, then taught), the first commits on taught and untaught tasks, and the share
of the person's path done at the commit (``evaluation.interaction.commit_share``).

Not a speed benchmark: the experiment behind RESULTS.md's "The rest rule", kept so that it
can be re-run. 10 subjects x 2 seeds: ~45 s::

    .venv/bin/python benchmarks/demo_replay.py --subjects 1-10 --seeds 0,1
    .venv/bin/python benchmarks/demo_replay.py --end-phase 0    # without the rest rule
    .venv/bin/python benchmarks/demo_replay.py --config my.yaml # other LibraryConfig settings
    .venv/bin/python benchmarks/demo_replay.py --why            # each wrong first commit, and by nu
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace

import numpy as np

from drake_skills import SkillLibrary
from drake_skills.evaluation.interaction import commit_share, replay_commits
from drake_skills.scenario.salad import generate_subject
from drake_skills.sim.config import load_config
from drake_skills.sim.demo import trial_stream


def _ints(spec: str) -> list[int]:
    out = []
    for part in spec.split(","):
        lo, _, hi = part.partition("-")
        out += list(range(int(lo), int(hi or lo) + 1))
    return out


def _share(lib, demo, workspace, commit_time: float) -> float:
    cfg = lib.config
    return commit_share(demo, workspace, cfg.resample_tolerance, commit_time, **cfg.walk_options())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", default="1-10", help="e.g. 1-10 or 3,7 (default 1-10)")
    ap.add_argument("--seeds", default="0,1", help="demo seeds (default 0,1)")
    ap.add_argument("--end-phase", type=float, default=None,
                    help="DecisionRule.end_phase (default: the SimConfig's; 0 turns the rest rule off)")
    ap.add_argument("--config", default=None,
                    help="a YAML file of LibraryConfig settings (as `drake-skills eval --config`; default: the defaults)")
    ap.add_argument("--why", action="store_true",
                    help="print every wrong first commit on a taught task: trial, the shared scale's pooled dof nu, "
                         "the supports of the committed component and of the true task's, the path share")
    a = ap.parse_args()
    from drake_skills.sim.config import load_library_config

    library = load_library_config(a.config) if a.config else None
    tot = dict(trials=0, right=0, wrong=0, asked=0, new=0)
    first = {"taught": [0, 0], "untaught": [0, 0]}   # first commit right, wrong
    by_nu = []    # (nu, first commit wrong, its component's support) per first commit on a taught task
    shares = []   # path share at the first commit of a skill executed right
    for subj in _ints(a.subjects):
        for seed in _ints(a.seeds):
            cfg = replace(load_config(None), seed=seed, subject=subj)
            if library is not None:
                cfg = replace(cfg, library=library)
            rule = cfg.decision if a.end_phase is None else replace(cfg.decision, end_phase=a.end_phase)
            data = generate_subject(cfg.subject, n_demos=cfg.demos_per_task, seed=cfg.seed, model=cfg.subject_model)
            ws = data.workspace(z_factor=cfg.z_factor)
            lib = SkillLibrary(replace(cfg.library, workspace=ws))
            label, taught = {}, set()
            for i, d in enumerate(trial_stream(data.demos, cfg.trials, np.random.default_rng(cfg.seed))):
                tot["trials"] += 1
                comp, commits = None, ()
                if lib.n_components:
                    g, _ = replay_commits(lib, d, ws, rule)
                    comp, commits = g.component, g.commits
                if commits:
                    first["taught" if d.task in taught else "untaught"][label.get(commits[0]) != d.task] += 1
                    if a.why and d.task in taught:
                        by_nu.append((lib.state().scale.dof, label.get(commits[0]) != d.task,
                                      lib.component(commits[0]).support))
                        prior_strength = lib.config.prior_strength
                    if a.why and d.task in taught and label.get(commits[0]) != d.task:
                        own = [c.support for c in lib.components if label.get(c.id) == d.task]
                        share = _share(lib, d, ws, g.commit_time)
                        print(f"first commit wrong: subject {subj} seed {seed} trial {i + 1}: {d.task} as "
                              f"{label.get(commits[0])} (support {lib.component(commits[0]).support:.0f}; own "
                              f"{', '.join(f'{s:.0f}' for s in own)}), nu {lib.state().scale.dof:.0f}, "
                              f"at {share:.2f} of the path; executed {label.get(comp)}")
                if comp is None:
                    tot["asked" if d.task in taught else "new"] += 1
                    for c in lib.partial_fit(d).created:
                        label[c] = d.task
                    taught.add(d.task)
                elif label.get(comp) == d.task:
                    tot["right"] += 1
                    shares.append(_share(lib, d, ws, g.commit_time))
                else:
                    tot["wrong"] += 1
                    print(f"wrong: subject {subj} seed {seed} trial {i + 1}: {d.task} executed as {label.get(comp)} "
                          f"(commits {[label.get(c) for c in commits]})")
    print(" ".join(f"{k} {v}" for k, v in tot.items()))
    for k, (ok, bad) in first.items():
        print(f"first commits on {k} tasks: {ok} right, {bad} wrong")
    if a.why and by_nu:
        nu, bad, sup = map(np.asarray, zip(*by_nu))
        nu0 = f"{prior_strength:g}"
        for name, m in ((f"nu < {nu0}", nu < prior_strength), (f"nu >= {nu0}", nu >= prior_strength),
                        ("support < 1.5", sup < 1.5),
                        (f"nu < {nu0} and support < 1.5", (nu < prior_strength) & (sup < 1.5))):
            print(f"first commits on taught tasks at {name}: {int(m.sum() - bad[m].sum())} right, {int(bad[m].sum())} wrong")
    if shares:
        q = np.nanpercentile(shares, [25, 50, 75])
        print(f"path share at the commit of the skills executed right: mean {np.nanmean(shares):.2f}, "
              f"quartiles {q[0]:.2f} / {q[1]:.2f} / {q[2]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
