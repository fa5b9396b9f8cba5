"""Benchmarks of the closed loop in Drake (issue 5).

Simulated seconds per wall-clock second of the full Diagram (wrist source,
normalizer, gating, conditioner, trajectory source, inverse-dynamics
controller, IIWA7 plant at 1 ms in the salad scene) over a stream of trials
against a taught library, without meshcat and with a meshcat recording.
Teaching is done before the clock starts, so only simulation is timed.
"""
from __future__ import annotations

import time

import numpy as np

from drake_skills.scenario.salad import TASKS, generate_subject


def _taught_sim(meshcat, config, make_sim=None):
    """A simulation (``make_sim``, default ``CollaborationSim``) taught 4 demonstrations per task; the held-out trials."""
    from drake_skills.library.incremental import SkillLibrary
    from drake_skills.sim.demo import CollaborationSim

    subject = generate_subject(1, n_demos=6, seed=0)
    sim = (make_sim or CollaborationSim)(config, SkillLibrary(config.library), subject.workspace(), meshcat)
    rng = np.random.default_rng(0)
    for k in range(4):
        for task in rng.permutation(TASKS):
            sim.teach(subject.by_task(task)[k])
    trials = [d for task in TASKS for d in subject.by_task(task)[4:]]
    return sim, trials


def _rate(meshcat, n_trials: int, config) -> tuple[float, float, float]:
    sim, trials = _taught_sim(meshcat, config)
    if meshcat is not None:
        meshcat.StartRecording(sim.config.meshcat.frames_per_second, False)
    t_sim0 = sim.time
    wall0 = time.perf_counter()
    for demo in trials[:n_trials]:
        sim.run_trial(demo)
    wall = time.perf_counter() - wall0
    if meshcat is not None:
        meshcat.StopRecording()
        t0 = time.perf_counter()
        meshcat.PublishRecording()
        meshcat.StaticHtml()
        wall += time.perf_counter() - t0
    simulated = sim.time - t_sim0
    return simulated / wall, simulated, wall


def run(quick: bool = False, config=None) -> list[dict]:
    """``config``: the SimConfig of the diagram and its library (default ``SimConfig()``)."""
    from drake_skills.sim.config import SimConfig
    from drake_skills.sim.diagram import make_meshcat

    config = config if config is not None else SimConfig()
    n = 3 if quick else 10
    rows = []
    rate, simulated, wall = _rate(None, n, config)
    rows.append({"name": "full diagram, no meshcat", "value": round(rate, 2), "unit": "sim s / wall s",
                 "goal": ">= 3x real time", "notes": f"{n} trials, {simulated:.1f} s simulated in {wall:.1f} s"})
    rate, simulated, wall = _rate(make_meshcat(), n, config)
    rows.append({"name": "full diagram, meshcat recording + HTML export", "value": round(rate, 2),
                 "unit": "sim s / wall s", "goal": "",
                 "notes": f"{n} trials, {simulated:.1f} s simulated in {wall:.1f} s (32 fps recording)"})
    return rows
