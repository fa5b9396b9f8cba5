"""The long run (issue 16): 100,000 ``partial_fit`` updates, the library's invariants checked throughout.

One library learns a stream in which new skills keep arriving (:mod:`drake_skills.data.synthetic`
skills, introduced one by one over the first half of the stream, so K grows), mixed
with what a deployed robot also sees: one-off motions that fit no skill (outliers the
library must delete again), identical repeats of the last demonstration, 5-sample
motions, motions at a quarter and at four times the usual speed, and demonstrations
of a skill spread wide. Every ``check_every`` updates (and after the last)
:func:`~drake_skills.library.invariants.invariant_violations` checks the state
(sums kept in two places agree, counts, finite values, SPD shared covariance), and the
counts are checked after every update. Rows: invariant violations (must be 0),
the stream's make-up, and the time per update (median, wall and CPU) in tenths of the
stream with the number of components K at the end of each.

Not a test: at full size it runs for several minutes (``drake-skills bench --suite
soak``; it is not run by a plain ``drake-skills bench``); the suite's test runs it at a
tiny size.
"""
from __future__ import annotations

import logging
import time
import warnings

import numpy as np

from drake_skills.data.demonstration import Demonstration
from drake_skills.data.synthetic import skill_bank
from drake_skills.library.incremental import LibraryConfig, SkillLibrary
from drake_skills.library.invariants import invariant_violations
from drake_skills.library.views import StillMotionError

log = logging.getLogger(__name__)

#: Not part of a plain ``drake-skills bench`` (it runs for minutes): only with ``--suite soak``.
DEFAULT = False
#: Updates of the full run and of ``--quick``.
N_UPDATES, QUICK_UPDATES = 100_000, 2_000
#: Skills that arrive over the first half of the stream (full, quick).
N_SKILLS, QUICK_SKILLS = 60, 10
#: Fraction of the stream of each kind of demonstration besides a taught skill's.
MIX = {"one-off": 0.05, "repeat": 0.03, "short": 0.03, "fast": 0.02, "slow": 0.02, "wide": 0.05}


def _variant(kind: str, demo: Demonstration, rng) -> Demonstration:
    if kind == "short":  # 5 samples
        idx = np.linspace(0, len(demo.t) - 1, 5).round().astype(int)
        return Demonstration(t=demo.t[idx], human=demo.human[idx], robot=demo.robot[idx], name="short")
    if kind in ("fast", "slow"):
        return Demonstration(t=demo.t * (0.25 if kind == "fast" else 4.0), human=demo.human, robot=demo.robot,
                             name=kind)
    if kind == "one-off":  # a reach to anywhere, fitting no skill
        human = np.outer(np.linspace(0.0, 1.0, len(demo.t)), rng.uniform(-8.0, 8.0, 3))
        return Demonstration(t=demo.t, human=human, robot=demo.robot, name="one-off")
    return demo


def soak(n_updates: int, n_skills: int, *, config: LibraryConfig | None = None, check_every: int = 100,
         seed: int = 0, progress=None) -> dict:
    """Run the stream; return violations, counts and per-update timings.

    Parameters
    ----------
    n_updates : int
    n_skills : int
        Skills introduced over the first half of the stream.
    config : LibraryConfig, optional
    check_every : int
        Updates between two full invariant checks (the counts are checked every update).
    seed : int
    progress : callable, optional
        Called as ``progress(i)`` after update ``i`` (e.g. a progress bar's update).

    Returns
    -------
    dict
        ``violations`` (list of (update, message)), ``checks``, ``kinds`` (counts),
        ``wall`` and ``cpu`` (n_updates,) seconds per update, ``K`` (n_updates,)
        components after each update, ``events`` (history counts), ``refused`` (updates that raised
        ``StillMotionError``: 5-sample motions whose samples read as tracker noise; a refused motion of
        another kind, or one that changed the library, is a violation), ``library``.
    """
    rng = np.random.default_rng(seed)
    bank = skill_bank(n_skills, rng)
    lib = SkillLibrary(config if config is not None else LibraryConfig())
    kinds = list(MIX) + ["skill"]
    probs = np.array(list(MIX.values()) + [1.0 - sum(MIX.values())])
    wall, cpu, K = np.zeros(n_updates), np.zeros(n_updates), np.zeros(n_updates, int)
    violations, checks, counts, refused = [], 0, dict.fromkeys(kinds, 0), 0
    last = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the one-offs and fast motions warn about their units, by design
        for i in range(n_updates):
            taught = min(n_skills, 1 + int(2 * n_skills * i / max(n_updates, 1)))
            kind = str(rng.choice(kinds, p=probs)) if last is not None else "skill"
            if kind == "repeat":
                demo = last
            else:
                scatter = 0.15 if kind == "wide" else 0.03
                demo = _variant(kind, bank.demo(int(rng.integers(taught)), rng, scatter=scatter), rng)
            counts[kind] += 1
            # (lib.history copies every event: its length is read from the list itself, outside the timing)
            before = (lib.n_seen, lib.n_components, len(lib._history))
            c0, t0 = time.process_time(), time.perf_counter()
            was_refused = False
            try:
                lib.partial_fit(demo)
            except StillMotionError as e:  # a 5-sample motion may read as tracker noise: refused, the library unchanged
                refused += 1
                was_refused = True
                if demo.name != "short":  # a 5-sample motion, or the repeat of one
                    violations.append((i + 1, f"a {kind} demonstration was refused: {e}"))
            wall[i], cpu[i] = time.perf_counter() - t0, time.process_time() - c0
            if was_refused and (lib.n_seen, lib.n_components, len(lib._history)) != before:
                violations.append((i + 1, f"a refused update changed (n_seen, K, history) from {before} to "
                                          f"{(lib.n_seen, lib.n_components, len(lib._history))}"))
            last = demo
            K[i] = lib.n_components
            state = None
            if lib.n_seen != i + 1 - refused:
                violations.append((i + 1, f"n_seen is {lib.n_seen} after {i + 1} updates, {refused} refused"))
            if (i + 1) % check_every == 0 or i + 1 == n_updates:
                state = lib.state()
                checks += 1
                violations += [(i + 1, p) for p in invariant_violations(state)]
            if progress is not None:
                progress(i)
    events: dict[str, int] = {}
    for e in lib.history:
        events[e["event"]] = events.get(e["event"], 0) + 1
    return {"violations": violations, "checks": checks, "kinds": counts, "refused": refused, "wall": wall,
            "cpu": cpu, "K": K, "events": events, "library": lib}


def run(quick: bool = False, config=None, *, n_updates: int | None = None) -> list[dict]:
    """``config``: a SimConfig whose ``library`` is soaked (default ``LibraryConfig()``)."""
    from tqdm import tqdm

    n = n_updates if n_updates is not None else (QUICK_UPDATES if quick else N_UPDATES)
    n_skills = QUICK_SKILLS if quick or n < N_UPDATES // 10 else N_SKILLS
    lib_config = config.library if config is not None else LibraryConfig()
    with tqdm(total=n, desc="soak", leave=False, dynamic_ncols=True, mininterval=1.0) as bar:
        out = soak(n, n_skills, config=lib_config, progress=lambda i: bar.update(1))
    v = out["violations"]
    mix = ", ".join(f"{k} {c}" for k, c in out["kinds"].items())
    ev = ", ".join(f"{k} {c}" for k, c in sorted(out["events"].items()))
    rows = [{"name": f"invariant violations over {n} updates", "value": len(v), "unit": "count", "goal": "0",
             "notes": (f"{out['checks']} full checks (every 100 updates and the last), counts every update; "
                       f"first: {v[0]}" if v else f"{out['checks']} full checks (every 100 updates and the last), "
                                                   f"counts every update")},
            {"name": "stream", "value": n, "unit": "updates",
             "notes": f"{n_skills} skills arriving over the first half; {mix}; refused {out['refused']} (the library "
                      f"unchanged); history: {ev}"}]
    tenth = max(1, n // 10)
    for a in range(0, n, tenth):
        b = min(n, a + tenth)
        rows.append({"name": f"partial_fit, updates {a + 1}-{b}, K={int(out['K'][b - 1])}",
                     "value": round(1e3 * float(np.median(out["wall"][a:b])), 3), "unit": "ms",
                     "cpu ms": round(1e3 * float(np.median(out["cpu"][a:b])), 3),
                     "notes": f"median over the updates; K = components after update {b}; "
                              f"max {1e3 * float(out['wall'][a:b].max()):.1f} ms"})
    return rows
