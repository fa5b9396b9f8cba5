"""Table 3 (components per task across subjects) on the styled subjects, with workspace variants.

Separates two candidate causes of "personal normalization gives MORE components than shared":
(a) units: the shared box is 1.09-1.22x wider per axis, so motions are smaller in shared
    units, while LibraryConfig.prior_floor is absolute in normalized units;
(b) habits that no per-axis scaling removes / per-subject scaling that does not track motion.

Variants (same demonstrations, same order as drake_skills.evaluation.salad_transfer.task_components_trial):
  P    personal workspace (Eq. 14)                       == eval's "personal workspace"
  S    shared workspace                                  == eval's "shared workspace"
  Pw   personal widened to the shared extent, own centre (identical to S when the start is
       subtracted: Eq. 14 minus the start is scale*(y - y0)/extent; checked numerically)
  Pg   personal, every subject's extent times one per-axis factor c_a = shared_a / geomean_s(personal_s,a):
       the same mean units as S, the per-subject relative scaling of P kept
  Sn   shared narrowed by 1/c_a: the mean units of P, one box for everybody
  *0   the same with LibraryConfig(prior_floor=0) (diagnostic only)

Usage (RESULTS.md, "With normalization fewer"; 100 orders: ~10 min single process):

    .venv/bin/python benchmarks/table3_units.py --orders 100 --variants P,S,Pg,Sn,P0,S0,Pg0,Sn0 --out out/table3_units.json

Not a speed benchmark: the experiment behind a claim in RESULTS.md, kept so it can be re-run.
It prints the table (mean / median / share >= 6 components) and the paired differences.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from drake_skills.data.workspace import Workspace
from drake_skills.evaluation.common import stream_rng
from drake_skills.evaluation.salad_data import SaladContext, SaladSettings, load_salad_data
from drake_skills.evaluation.salad_transfer import STREAM_TASKS
from drake_skills.library.incremental import SkillLibrary
from drake_skills.scenario.salad import TASKS


def rescaled(ws: Workspace, factor: np.ndarray) -> Workspace:
    """``ws`` with its per-axis extent times ``factor``, about its own centre."""
    c, half = 0.5 * (ws.lower + ws.upper), 0.5 * (ws.upper - ws.lower) * factor
    return Workspace(c - half, c + half, ws.scale)


def summarize(rows, vs) -> None:
    """Print the table and the paired differences of :func:`main`'s rows."""
    tasks = list(dict.fromkeys(r["task"] for r in rows))
    n = len({r["order"] for r in rows})
    print(f"{n} orders; cells: mean / median / P(>=6)")
    print("| task | " + " | ".join(vs) + " |")
    print("|---|" + "---|" * len(vs))
    for t in tasks:
        rr = [r for r in rows if r["task"] == t]
        cells = []
        for v in vs:
            c = np.array([r[v] for r in rr])
            cells.append(f"{c.mean():.2f} / {np.median(c):g} / {np.mean(c >= 6):.2f}")
        print(f"| {t} | " + " | ".join(cells) + " |")
    print("\nrho^2 t_h (floor^2 = 0.16), mean over orders:")
    for t in tasks:
        rr = [r for r in rows if r["task"] == t]
        print(t, {v: round(float(np.mean([r[v + '_rho2th'] for r in rr])), 3) for v in vs if not v.endswith('0')})
    # paired differences P - S etc
    print("\npaired mean difference (per order), board/standup/dressing:")
    for t in tasks:
        rr = [r for r in rows if r["task"] == t]
        def diff(a, b, rr=rr):
            x = np.array([r[a] - r[b] for r in rr]); return f"{x.mean():+.2f} (sd {x.std(ddof=1)/np.sqrt(len(x)):.2f})"
        pairs = [(a, b) for a, b in [("P", "S"), ("Pg", "S"), ("P", "Sn"), ("Pg", "P"), ("P0", "S0"), ("Pg0", "S0"), ("P0", "Sn0")] if a in vs and b in vs]
        print(t, "; ".join(f"{a}-{b} {diff(a, b)}" for a, b in pairs))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--orders", type=int, default=20)
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--variants", default="P,S,Pg,Sn,P0,S0")
    ap.add_argument("--tasks", default=",".join(TASKS))
    ap.add_argument("--cache", default=None, help="salad demonstration cache (default: none, generate)")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()

    s = SaladSettings(subject_model="styled")
    subjects = load_salad_data(s, cache_dir=a.cache)
    ctx = SaladContext.of(s, subjects)
    ext_p = np.array([w.upper - w.lower for w in ctx.workspaces])          # (10, 3)
    ext_s = ctx.shared.upper - ctx.shared.lower                             # (3,)
    c = ext_s / np.exp(np.log(ext_p).mean(axis=0))
    print("personal extents (m):", ext_p.round(3).tolist(), file=sys.stderr)
    print("shared extent:", ext_s.round(3).tolist(), "c_a:", c.round(3).tolist(), file=sys.stderr)
    wide = [rescaled(w, ext_s / (w.upper - w.lower)) for w in ctx.workspaces]
    glob = [rescaled(w, c) for w in ctx.workspaces]
    narrow = rescaled(ctx.shared, 1.0 / c)
    # Pw == S: the normalized, start-subtracted motion depends only on the extent
    dmax = max(float(np.abs(wide[p].normalize(d.human) - ctx.shared.normalize(d.human)).max())
               for p, data in enumerate(subjects) for d in data.demos[:5])
    print(f"max |Pw - S| normalized difference over 50 demos: {dmax:.2e}", file=sys.stderr)

    base = s.library
    floor0 = replace(base, prior_floor=0.0)
    spec = {"P": (lambda p: ctx.workspaces[p], base), "S": (lambda p: ctx.shared, base),
            "Pw": (lambda p: wide[p], base), "Pg": (lambda p: glob[p], base), "Sn": (lambda p: narrow, base)}
    for k in list(spec):
        spec[k + "0"] = (spec[k][0], floor0)
    variants = a.variants.split(",")
    tasks = a.tasks.split(",")
    rows = []
    t0 = time.perf_counter()
    for order in range(a.start, a.start + a.orders):
        for task in tasks:
            rng = stream_rng(s.seed, STREAM_TASKS, TASKS.index(task), order)
            demos, pos = [], []
            for p, data in enumerate(subjects):
                pool = data.by_task(task)
                for j in rng.permutation(len(pool))[:s.table3_per_task]:
                    demos.append(pool[j])
                    pos.append(p)
            perm = rng.permutation(len(demos))
            row = {"task": task, "order": order}
            for v in variants:
                wsf, cfg = spec[v]
                lib = SkillLibrary(cfg)
                for j in perm:
                    lib.partial_fit(demos[j], workspace=wsf(pos[j]))
                t_h, _ = lib._scale.block_variances(lib.n_human)
                row[v] = lib.n_components
                row[v + "_rho2th"] = cfg.prior_scale ** 2 * t_h
            rows.append(row)
        el = time.perf_counter() - t0
        print(f"order {order} done, {el:.0f} s", file=sys.stderr, flush=True)
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "w") as f:
        json.dump({"variants": variants, "c": c.tolist(), "ext_p": ext_p.tolist(), "ext_s": ext_s.tolist(),
                   "rows": rows, "seconds": time.perf_counter() - t0}, f, indent=1)
    summarize(rows, variants)
    return 0


if __name__ == "__main__":
    sys.exit(main())
