"""How the library copes with tracker noise, with and without ``LibraryConfig.adapt_to_noise`` and ``average_holds``.

Not a speed benchmark: the experiment behind RESULTS.md's "Tracker noise", kept so that it can
be re-run. White noise (per axis, metres for buetepage, millimetres for LASA) is added to every
taught and recognized motion; ``--every 3`` keeps every third sample (100 Hz -> 33 Hz).

* ``buetepage``: ../shared/data/buetepage_hr.npz (or ``DRAKE_SKILLS_SHARED``), wrist columns.
  ``--split test``: the 32 training interactions taught in ``--orders`` random orders, the 9 test
  interactions recognized. ``--split dev`` (how the rule was chosen): per task 6 training
  interactions taught and the other 2 recognized, 3 draws x ``--orders`` orders.
* ``lasa``: 15 shapes in one library (``--half a`` or ``b``: every other shape of the 30), 4
  demonstrations of each taught and 3 recognized, ``--orders`` orders (``evaluation.scale``).

Examples (about 1 min each on the shared 2-core machine)::

    .venv/bin/python benchmarks/tracker_noise.py buetepage --split test --orders 20 --noise 0,0.005,0.01
    .venv/bin/python benchmarks/tracker_noise.py buetepage --split test --noise 0.005,0.01,0.02 --every 3
    .venv/bin/python benchmarks/tracker_noise.py lasa --half a --noise 1,2,4
    .venv/bin/python benchmarks/tracker_noise.py buetepage --noise 0,0.005 --glitches 0.01,0.1
    .venv/bin/python benchmarks/tracker_noise.py buetepage --split dev --noise 0.01 --smooth 4   # correlated noise
    .venv/bin/python benchmarks/tracker_noise.py lasa --half a --noise 2,4 --variants points,adapted
"""
from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from drake_skills.data.demonstration import Demonstration
from drake_skills.library.config import LibraryConfig


#: The walks compared: name -> (column title, LibraryConfig settings).
VARIANTS = {"plain": ("plain walk", {"adapt_to_noise": False}),
            "points": ("adapted, vertices at samples", {"average_holds": False}),
            "adapted": ("adapted, holds averaged (default)", {})}
#: Glitches: (share of the frames that start one, size in the data's units, frames per glitch).
GLITCHES = (0.0, 0.0, 1)


#: Gaussian width (samples) the noise is smoothed over before it is added, rescaled to the same standard
#: deviation (a tracker that filters its output: noise correlated in time); 0: white.
SMOOTH = 0.0


def _noisy(d: Demonstration, sigma: float, every: int, rng) -> Demonstration:
    n = rng.normal(0.0, sigma, d.human[::every].shape)
    if SMOOTH > 0 and sigma > 0:
        from scipy.ndimage import gaussian_filter1d

        n = gaussian_filter1d(n, SMOOTH, axis=0, mode="nearest")
        n *= sigma / n.std(axis=0, keepdims=True)
    h = d.human[::every] + n
    rate, size, run = GLITCHES
    if rate > 0:
        h = h.copy()
        for s in np.flatnonzero(rng.random(len(h) - run - 1) < rate) + 1:
            v = rng.normal(0.0, 1.0, h.shape[1])
            h[s:s + run] += size * v / np.linalg.norm(v)
    return Demonstration(t=d.t[::every], human=h, robot=None if d.robot is None else d.robot[::every],
                         task=d.task, name=d.name)


def buetepage(sigma: float, every: int, split: str, orders: int, config: LibraryConfig, seed: int = 7):
    from drake_skills.data.interaction import load_interactions
    from drake_skills.evaluation.interaction import default_data_path, workspace_of
    from drake_skills.evaluation.labeled import LabeledLibrary

    inter = load_interactions(default_data_path(), rate_hz=100.0)
    rng = np.random.default_rng(seed)
    train = [_noisy(d, sigma, every, rng) for d in inter.train]
    if split == "test":
        cases = [(train, [_noisy(d, sigma, every, rng) for d in inter.test])]
    else:
        cases, tasks = [], sorted({d.task for d in train})
        for draw in range(3):
            r = np.random.default_rng(100 + draw)
            tr, te = [], []
            for t in tasks:
                idx = [i for i, d in enumerate(train) if d.task == t]
                r.shuffle(idx)
                tr += [train[i] for i in idx[:6]]
                te += [train[i] for i in idx[6:]]
            cases.append((tr, te))
    rows = []
    for tr, te in cases:
        ws = workspace_of(tr)
        for o in range(orders):
            lab = LabeledLibrary(replace(config, workspace=ws))
            for j in np.random.default_rng(o).permutation(len(tr)):
                lab.teach(tr[j])
            out = [lab.library.recognize(d.human, observed_fraction=1.0) for d in te]
            right = sum(r.status == "skill" and lab.label_of(r.component) == d.task for r, d in zip(out, te))
            wrong = sum(r.status == "skill" and lab.label_of(r.component) != d.task for r, d in zip(out, te))
            rows.append((lab.library.n_components, right / len(te), wrong / len(te)))
    return np.mean(rows, axis=0)


def lasa(sigma: float, half: str, orders: int, config: LibraryConfig, seed: int = 3):
    from drake_skills.data.lasa import load_lasa
    from drake_skills.evaluation.scale import LASA_SHAPES, LasaContext, ScaleSettings, lasa_trial

    shapes = tuple(LASA_SHAPES[0 if half == "a" else 1::2])
    rng = np.random.default_rng(seed)
    demos = tuple(_noisy(d, sigma, 1, rng) for d in load_lasa(shapes))
    ctx = LasaContext(demos, ScaleSettings(lasa_orders=orders, lasa_shapes=shapes, library=config))
    trials = [lasa_trial(ctx, i) for i in range(orders)]
    counts = np.array([t.counts for t in trials], float)
    share = (counts / counts.sum(axis=1, keepdims=True)).mean(axis=0)
    return np.array([np.mean([t.components for t in trials]), share[0], share[1]])


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("data", choices=("buetepage", "lasa"))
    p.add_argument("--noise", default="0,0.005,0.01", help="comma-separated noise levels (buetepage: m, lasa: mm)")
    p.add_argument("--every", type=int, default=1, help="keep every n-th sample (buetepage)")
    p.add_argument("--split", choices=("test", "dev"), default="test", help="buetepage: test split or dev split")
    p.add_argument("--half", choices=("a", "b"), default="b", help="lasa: which half of the 30 shapes")
    p.add_argument("--orders", type=int, default=3, help="random orders of teaching (default 3)")
    p.add_argument("--glitches", default=None, metavar="RATE,SIZE[,RUN]",
                   help="also add tracker glitches: a share RATE of the frames starts one, SIZE away (the noise's "
                        "units) in a random direction for RUN frames (default 1), e.g. 0.01,0.1")
    p.add_argument("--variants", default=",".join(VARIANTS),
                   help="comma-separated walks to compare: plain (adapt_to_noise off), points (adapted, every vertex "
                        "a sample: average_holds off), adapted (the defaults); default all three")
    p.add_argument("--smooth", type=float, default=0.0,
                   help="smooth the noise over a Gaussian of this many samples, rescaled to the same standard "
                        "deviation (a tracker that filters its output; default 0: white)")
    p.add_argument("--seed", type=int, default=None,
                   help="seed of the noise draw (default: 7 for buetepage, 3 for lasa, as in RESULTS.md)")
    a = p.parse_args(argv)
    global SMOOTH
    SMOOTH = a.smooth
    if a.glitches:
        parts = [float(x) for x in a.glitches.split(",")]
        if len(parts) not in (2, 3) or not (0 <= parts[0] < 1 and parts[1] >= 0) or (len(parts) == 3 and not (
                parts[2] >= 1 and parts[2] == int(parts[2]))):
            p.error(f"--glitches RATE,SIZE[,RUN] with 0 <= RATE < 1, SIZE >= 0 and an integer RUN >= 1, got {a.glitches!r}")
        global GLITCHES
        GLITCHES = (parts[0], parts[1], int(parts[2]) if len(parts) == 3 else 1)
    names = [v for v in a.variants.split(",") if v]
    bad = [v for v in names if v not in VARIANTS]
    if bad or not names:
        p.error(f"--variants: choose from {','.join(VARIANTS)}, got {a.variants!r}")
    print("| noise | " + " | ".join(f"{VARIANTS[v][0]}: components / correct / wrong" for v in names) + " |")
    print("|---|" + "---|" * len(names))
    for sigma in (float(x) for x in a.noise.split(",")):
        cells = []
        for v in names:
            cfg = LibraryConfig(**VARIANTS[v][1])
            seed = a.seed if a.seed is not None else (7 if a.data == "buetepage" else 3)
            r = (buetepage(sigma, a.every, a.split, a.orders, cfg, seed) if a.data == "buetepage"
                 else lasa(sigma, a.half, a.orders, cfg, seed))
            cells.append(f"{r[0]:.1f} / {r[1]:.3f} / {r[2]:.3f}")
        print(f"| {sigma:g} | " + " | ".join(cells) + " |", flush=True)

if __name__ == "__main__":
    main()
