"""Each component's novelty test widened to its own scatter where that exceeds the shared scale: measured and dropped.

Not a speed benchmark: the experiment behind RESULTS.md's "A component's own scatter as its scale". The library
judges every component on one shared within-skill covariance ``Sigma`` (predictive ``Sigma (1 + 1/s_k)``). Some
LASA shapes vary more than the pool, and their held-out demonstrations fall past the novelty limit ("unknown").
The variant tested here takes, in every whitened direction, the larger of the shared scale and the component's
own (expert) covariance ``(kappa I + L^-1 S_k L^-T) / (kappa + s_k - 1)`` (``kappa = expert_prior``; no new
setting), for learning and for whole motions alike (the prefix tests are left as they are). It is patched in
here, not in the library.

Three measurements, each with the library as it is (``shared``) and with the variant (``own scatter``):

* LASA half A (development), half B and all 30 shapes: ``evaluate_scale`` (3 orders, 4 of 7 taught);
* new LASA shapes: one half taught (4 demonstrations of each of its shapes, 3 draws), every demonstration of
  the other half's shapes shown; any skill answer is wrong;
* new buetepage tasks: ``evaluation.interaction.untaught_trial`` (each task left out in turn, its interactions of
  both splits shown as whole motions).

::

    .venv/bin/python benchmarks/own_scatter.py          # about 30 s on the shared 2-core machine
"""
from __future__ import annotations

import argparse
import sys
from contextlib import contextmanager
from dataclasses import replace

import numpy as np

from drake_skills import LibraryConfig
from drake_skills.data.lasa import LASA_SHAPES, lasa_workspace, load_lasa
from drake_skills.evaluation.interaction import (InteractionContext, InteractionSettings, default_data_path,
                                                 untaught_trial)
from drake_skills.evaluation.labeled import UNDECIDED, UNKNOWN, WRONG, LabeledLibrary
from drake_skills.evaluation.scale import ScaleSettings, evaluate_scale
from drake_skills.library import algorithm, recognition

_LOG_2PI = np.log(2.0 * np.pi)


def _own_scatter(comps, metric, h: int, kappa: float):
    """Whitened directions (K, r, h), scaled so that ``|dz|^2 - |V dz|^2`` is the widened distance, and the
    log-determinants (K,) of the widened covariances (relative to the shared one)."""
    parts, rmax = [], 1
    for c in comps.items:
        if c.support < 1.5:      # one demonstration (algorithm.YOUNG_SUPPORT): no scatter of its own
            parts.append((np.zeros((h, 0)), 0.0))
            continue
        U, sv, _ = np.linalg.svd(metric.inv_chol @ c.cluster.factor[:h], full_matrices=False)
        e = np.maximum((kappa + sv ** 2) / (kappa + c.support - 1.0) - 1.0, 0.0)
        U, e = U[:, e > 0], e[e > 0]
        parts.append((U * np.sqrt(e / (1.0 + e)), float(np.sum(np.log1p(e)))))
        rmax = max(rmax, U.shape[1])
    V, logdet = np.zeros((len(parts), rmax, h)), np.zeros(len(parts))
    for k, (W, ld) in enumerate(parts):
        V[k, :W.shape[1]], logdet[k] = W.T, ld
    return V, logdet


def _widened_scores(kappa: float):
    def gating_scores(w_h, comps, metric, whitened=None):
        h = w_h.shape[0]
        if not len(comps):
            return np.zeros(0), np.zeros(0)
        V, logdet = _own_scatter(comps, metric, h, kappa)
        inflate = 1.0 + 1.0 / comps.support
        diff = (metric.whiten(comps.means_h) if whitened is None else whitened) - metric.whiten(w_h)
        proj = np.einsum("krh,kh->kr", V, diff)
        d2 = (np.einsum("ij,ij->i", diff, diff) - np.einsum("kr,kr->k", proj, proj)) / inflate
        return -0.5 * (h * _LOG_2PI + metric.logdet + h * np.log(inflate) + logdet + d2), d2
    return gating_scores


@contextmanager
def variant(name: str, kappa: float):
    saved = algorithm.gating_scores, recognition.gating_scores
    if name == "own scatter":
        algorithm.gating_scores = recognition.gating_scores = _widened_scores(kappa)
    try:
        yield
    finally:
        algorithm.gating_scores, recognition.gating_scores = saved


def lasa_rows(orders: int) -> dict:
    out = {}
    for label, shapes in (("LASA half A (development)", LASA_SHAPES[0::2]), ("LASA half B", LASA_SHAPES[1::2]),
                          ("LASA-30", LASA_SHAPES)):
        rep = evaluate_scale(ScaleSettings(lasa_orders=orders, lasa_shapes=tuple(shapes), sizes=(10,),
                                           orders=("random",), prefix_probes=0), progress=False, figures=False)
        s = rep.summary["lasa"]
        out[label] = (f"{s['components_mean']:.1f} / {s['correct_mean']:.3f} / {s['wrong_mean']:.3f} "
                      f"(single-pattern correct {s['single_pattern_correct']:.3f})")
    return out


def new_lasa_shapes(draws: int) -> str:
    counts = np.zeros(4, int)
    for half in (0, 1):
        taught, shown = load_lasa(tuple(LASA_SHAPES[half::2])), load_lasa(tuple(LASA_SHAPES[1 - half::2]))
        by: dict = {}
        for d in taught:
            by.setdefault(d.task, []).append(d)
        for draw in range(draws):
            rng = np.random.default_rng(draw)
            train = [v[i] for v in by.values() for i in rng.permutation(len(v))[:4]]
            lab = LabeledLibrary(replace(LibraryConfig(), workspace=lasa_workspace(train)))
            for i in rng.permutation(len(train)):
                lab.teach(train[i])
            for d in shown:
                counts[lab.classify(d.human, d.task)[0]] += 1
    n = counts.sum()
    return (f"{counts[WRONG]} of {n} wrong ({counts[WRONG] / n:.3f}); unknown {counts[UNKNOWN] / n:.3f}, "
            f"undecided {counts[UNDECIDED] / n:.3f}")


def new_buetepage_tasks(orders: int) -> str:
    s = InteractionSettings(data=str(default_data_path()), orders=1)
    ctx = InteractionContext.of(s)
    res = [untaught_trial(ctx, (t, o)) for t in range(len(ctx.task_mean)) for o in range(orders)]
    whole = np.concatenate([r.whole for r in res])
    executed = np.concatenate([r.executed for r in res])
    return (f"whole motions {int(np.sum(whole == WRONG))} of {whole.size} wrong ({np.mean(whole == WRONG):.3f}); "
            f"controller executed a skill {np.mean(executed == WRONG):.3f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--orders", type=int, default=3, help="LASA orders (evaluate_scale; default 3)")
    ap.add_argument("--draws", type=int, default=3, help="draws of the taught LASA half (default 3)")
    ap.add_argument("--untaught-orders", type=int, default=1, help="orders per left-out buetepage task (default 1)")
    ap.add_argument("--kappa", type=float, default=LibraryConfig().expert_prior,
                    help="pseudo-demonstrations of the shared scale in a component's own (default expert_prior)")
    args = ap.parse_args(argv)
    rows: dict = {}
    for name in ("shared", "own scatter"):
        with variant(name, args.kappa):
            r = lasa_rows(args.orders)
            r["new LASA shapes"] = new_lasa_shapes(args.draws)
            r["new buetepage tasks"] = new_buetepage_tasks(args.untaught_orders)
        for k, v in r.items():
            rows.setdefault(k, {})[name] = v
        print(f"{name}: done", file=sys.stderr)
    print("| data (components / correct / wrong) | shared scale (the library) | own scatter where wider |")
    print("|---|---|---|")
    for k, v in rows.items():
        print(f"| {k} | {v['shared']} | {v['own scatter']} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
