"""Benchmarks of the controller over LCM (issue 14).

Simulated seconds per second of the closed loop over the in-process bus
(``memq://``): the simulated station (IIWA7 plant at 1 ms in the salad scene,
SimIiwaDriver, status at 200 Hz, wrist at 128 Hz) and the LCM controller
(commands at 200 Hz), in one Simulator, against a taught library; beside it, in
the same run and on the same trials taken in turn, the direct Diagram, so the
ratio does not depend on the machine's load. Wall-clock rates, and process CPU
rates (what the run would get with a core to itself on a loaded machine).
"""
from __future__ import annotations

import time
from dataclasses import replace


def run(quick: bool = False, config=None) -> list[dict]:
    """``config``: the SimConfig of the diagrams and their library (default ``SimConfig()``)."""
    from drake_skills.benchmarks.sim import _taught_sim
    from drake_skills.sim.config import SimConfig
    from drake_skills.sim.lcm_demo import LcmCollaborationSim

    config = config if config is not None else SimConfig()
    impaired = replace(config, lcm=replace(config.lcm, latency=0.02, wrist_drop=0.05))
    cases = {"direct diagram (same trials, in turn)": _taught_sim(None, config),
             "LCM, memq://": _taught_sim(None, config, LcmCollaborationSim),
             "LCM, memq://, 20 ms latency, 5 % wrist messages dropped": _taught_sim(None, impaired,
                                                                                  LcmCollaborationSim)}
    trials = next(iter(cases.values()))[1]
    n = 3 if quick else 10
    totals = {name: [0.0, 0.0, 0.0] for name in cases}  # simulated, wall, cpu
    for demo in trials[:n]:
        for name, (sim, _) in cases.items():
            t_sim, wall, cpu = sim.time, time.perf_counter(), time.process_time()
            sim.run_trial(demo)
            acc = totals[name]
            acc[0] += sim.time - t_sim
            acc[1] += time.perf_counter() - wall
            acc[2] += time.process_time() - cpu
    direct = next(iter(totals.values()))
    rows = []
    for name, (simulated, wall, cpu) in totals.items():
        rows.append({"name": name, "value": round(simulated / wall, 2), "unit": "sim s / wall s",
                     "cpu_rate": round(simulated / cpu, 2),
                     "vs_direct": round((simulated / cpu) / (direct[0] / direct[2]), 2),
                     "goal": ">= 2x real time" if name == "LCM, memq://" else "",
                     "notes": f"{n} trials, {simulated:.1f} s simulated in {wall:.1f} s wall, {cpu:.1f} s CPU"})
    return rows
