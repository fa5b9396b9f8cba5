"""What reading a motion again after a false start costs ``recognize`` (``LibraryConfig.skip_false_starts``).

A small library (3 synthetic skills, 20 demonstrations) with the setting on and off; medians of 200 calls of
``recognize`` on: a known motion (whole, and its first 80 samples with the phase estimated), an unknown motion
with a false start before it (whole and a beginning), an unknown motion without one. Each call gets the motion
with 1e-9 of noise added so that the library's path memo does not answer it. Prints ms on and off and their
ratio, measured in one run::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/false_start_cost.py
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from drake_skills import LibraryConfig, SkillLibrary  # noqa: E402
from synthetic import WORKSPACE, synthetic_demo  # noqa: E402


def main(repeats: int = 200) -> int:
    libs = {}
    for on in (True, False):
        lib = SkillLibrary(LibraryConfig(workspace=WORKSPACE, skip_false_starts=on))
        r = np.random.default_rng(0)
        for i in range(20):
            lib.partial_fit(synthetic_demo(i % 4 if i % 4 < 3 else 0, r))
        libs[on] = lib
    r = np.random.default_rng(5)
    untaught = synthetic_demo(3, r)
    z = np.sin(np.linspace(0, np.pi, 30))[:, None]
    fs = np.vstack([untaught.human[0] + z * [1.0, -4.0, 2.0], untaught.human[1:]])
    known = synthetic_demo(1, r).human
    cases = {"a known motion, whole": (known, 1.0), "its first 80 samples, phase estimated": (known[:80], None),
             "an unknown motion after a false start, whole": (fs, 1.0),
             "its first 110 samples, phase estimated": (fs[:110], None),
             "an unknown motion without a false start, whole": (untaught.human, 1.0)}
    rng = np.random.default_rng(1)
    print(f"K = {libs[True].n_components}; median ms of {repeats} calls\n")
    print("| recognize | on (ms) | off (ms) | on / off |\n|---|---|---|---|")
    for name, (h, f) in cases.items():
        row = []
        for on in (True, False):
            lib = libs[on]
            ts = []
            for _ in range(repeats):
                hh = h + 1e-9 * rng.standard_normal(h.shape)   # defeats the path memo
                t0 = time.perf_counter()
                lib.recognize(hh, observed_fraction=f)
                ts.append(time.perf_counter() - t0)
            row.append(np.median(ts) * 1e3)
        print(f"| {name} | {row[0]:.3f} | {row[1]:.3f} | {row[0] / row[1]:.2f} |")
    return 0


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=200, help="calls per case (default: %(default)s)")
    sys.exit(main(ap.parse_args().repeats))
