"""How many of a tracker's glitches ``promp.preprocessing.spike_samples`` finds, on the buetepage training split.

Not a speed benchmark: the tables behind RESULTS.md's "Tracker glitches" (the protocol of a cold
review's scripts, 2026-12-02). One-frame glitches in a random direction are added to a share of the
frames (1..T-2) of every training interaction, with white noise; the table counts the glitch
samples found and, in parentheses, the other samples also flagged. Then the detection against the
share of glitched frames and against the length of a prefix (what the gating sees early on)::

    .venv/bin/python benchmarks/glitch_detection.py        # ~20 s
"""
from __future__ import annotations

import numpy as np

from drake_skills.data.interaction import load_interactions
from drake_skills.evaluation.interaction import default_data_path, workspace_of
from drake_skills.promp.preprocessing import spike_samples

TOL = 0.1


def inject(h, rate, size, rng):
    h = h.copy()
    truth = np.zeros(len(h), bool)
    for s in np.flatnonzero(rng.random(len(h) - 2) < rate) + 1:
        v = rng.normal(size=h.shape[1])
        h[s] += size * v / np.linalg.norm(v)
        truth[s] = True
    return h, truth


def main() -> None:
    inter = load_interactions(default_data_path(), rate_hz=100.0)
    ws = workspace_of(inter.train)
    print("| rate, noise | 3 cm | 10 cm | 20 cm | 30 cm |")
    print("|---|---|---|---|---|")
    for every in (1, 3):
        for sigma in (0.0, 0.005, 0.01, 0.02):
            cells = []
            for size in (0.03, 0.1, 0.2, 0.3):
                rng = np.random.default_rng(7)
                found = total = false = 0
                for d in inter.train:
                    h = d.human[::every] + rng.normal(0, sigma, d.human[::every].shape)
                    h, truth = inject(h, 0.01, size, rng)
                    m = spike_samples(ws.normalize(h), TOL)
                    found += int((m & truth).sum())
                    total += int(truth.sum())
                    false += int((m & ~truth).sum())
                cells.append(f"{found}/{total} (+{false})")
            print(f"| {100 // every} Hz, {sigma * 1000:.0f} mm | " + " | ".join(cells) + " |", flush=True)
    for rate in (0.01, 0.02, 0.03, 0.05):
        rng = np.random.default_rng(7)
        f = t = 0
        for d in inter.train:
            h, truth = inject(d.human, rate, 0.1, rng)
            m = spike_samples(ws.normalize(h), TOL)
            f += int((m & truth).sum())
            t += int(truth.sum())
        print(f"10 cm glitches on {rate:.0%} of the frames (100 Hz): found {f}/{t}")
    for every in (1, 3):
        for n in (30, 60, 100, 200):
            rng = np.random.default_rng(8)
            f = t = 0
            for d in inter.train:
                h, truth = inject(d.human[::every], 0.02, 0.1, rng)
                h, truth = h[:n], truth[:n]
                truth[-1] = False
                m = spike_samples(ws.normalize(h), TOL)
                f += int((m & truth).sum())
                t += int(truth.sum())
            print(f"{100 // every} Hz, first {n} frames, 2 % glitches of 10 cm: found {f}/{t}")


if __name__ == "__main__":
    main()
