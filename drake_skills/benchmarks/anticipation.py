"""Anticipation: what the controller asks of the library while the person moves, at K = 5.

Every re-decision recognizes the growing prefix with its phase estimated
(``recognize`` without ``observed_fraction``); every re-conditioning estimates the
committed skill's phase and conditions its Interaction ProMP on the prefix
(``estimate_phase`` + ``predict_robot`` with ``variances_only``: the conditioner keeps each
joint's standard deviation, not the cross-joint covariance; a row gives the full one too). The library is the default
``LibraryConfig`` (or ``--config``'s) taught a simulated salad subject, 6
demonstrations per task (the salad scenario's data, normalized in the subject's
workspace); prefixes are cut at 20-80 % of held-out motions' paths.
"""
from __future__ import annotations

import numpy as np

from drake_skills.benchmarks._timing import fastest_cpu_ms, median_ms


def run(quick: bool = False, config=None) -> list[dict]:
    from drake_skills.library.incremental import LibraryConfig, SkillLibrary
    from drake_skills.promp.preprocessing import vertex_path
    from drake_skills.scenario.salad import generate_subject

    lib_config = config.library if config is not None else LibraryConfig()
    data = generate_subject(1, n_demos=8, seed=0)
    ws = data.workspace()
    lib = SkillLibrary(lib_config)
    tasks = sorted({d.task for d in data.demos})
    for k in range(6):
        for t in tasks:
            lib.partial_fit(data.by_task(t)[k], workspace=ws)
    rng = np.random.default_rng(0)
    prefixes = []
    for t in tasks:
        for d in data.by_task(t)[6:]:
            y = ws.normalize(d.human, subtract_start=lib_config.subtract_start)
            idx, _, s = vertex_path(y, lib_config.resample_tolerance, **lib_config.walk_options())
            for f in rng.uniform(0.2, 0.8, 2 if quick else 6):
                prefixes.append(y[: idx[np.searchsorted(s, f * s[-1])] + 1])
    repeats = 20 if quick else 200
    n = len(prefixes)
    k0 = lib.components[0].id

    def recognize(i=[0]):
        lib.recognize(prefixes[i[0] % n], normalized=True)
        i[0] += 1

    def recondition_one(y, full=False):
        f = lib.estimate_phase(y, k0, normalized=True)
        lib.predict_robot(y, f, normalized=True, component=k0, variances_only=not full)

    def recondition(i=[0], full=False):
        recondition_one(prefixes[i[0] % n], full)
        i[0] += 1

    def one(y):
        rec = lib.recognize(y, normalized=True)
        k = rec.best if rec.best is not None else k0
        f = lib.estimate_phase(y, k, normalized=True)
        lib.predict_robot(y, f, normalized=True, component=k, variances_only=True)   # as the conditioner asks

    def both(i=[0]):
        one(prefixes[i[0] % n])
        i[0] += 1

    for _ in range(n):  # a controller meets the same few prefix sizes again: warm their caches once
        both()
    rows = [{"name": f"recognize a prefix, phase estimated, K={lib.n_components}",
             "value": round(median_ms(recognize, repeats), 3), "unit": "ms", "goal": "",
             "notes": "a re-decision of the gating"},
            {"name": "estimate_phase + predict_robot of a prefix",
             "value": round(median_ms(recondition, repeats), 3), "unit": "ms", "goal": "",
             "notes": "a re-conditioning: Eq. 13 on the prefix, 100-step robot mean and per-joint variance"},
            {"name": "the same with the full per-step covariance",
             "value": round(median_ms(lambda: recondition(full=True), repeats), 3), "unit": "ms", "goal": "",
             "notes": "predict_robot's default (7 x 7 per step)"},
            {"name": f"recognize + phase + predict from a prefix, K={lib.n_components}",
             "value": round(median_ms(both, repeats), 3), "unit": "ms", "goal": "<= 2 ms at K=5",
             "notes": "both of the above for one prefix"}]
    passes = 3 if quick else 30
    for name, fn in (("recognize a prefix", lambda y: lib.recognize(y, normalized=True)),
                     ("estimate_phase + predict_robot", recondition_one),
                     ("recognize + phase + predict", one)):
        rows.append({"name": f"{name}, CPU ms", "value": round(fastest_cpu_ms(fn, prefixes, passes), 3),
                     "unit": "ms", "goal": "",
                     "notes": (f"fastest of {passes} passes over the {n} prefixes, each new to the library's path "
                               "memo; steadier than the wall clock on a shared machine (one BLAS thread)")})
    return rows
