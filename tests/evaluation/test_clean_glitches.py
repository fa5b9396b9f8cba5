"""No sample of any clean data set we have is a tracker glitch, so adapt_to_noise leaves their walks exactly alone.

The thresholds of ``promp.preprocessing.spike_samples`` were set under this constraint (RESULTS.md, "Tracker
glitches"); a cold review checked it more widely (every subsampling offset, every prefix). Asserted here on:
buetepage at 100, 33 and 10 Hz (../shared/data), LASA-30 at 1000, 200 and 50 samples, salad subjects 1-10 (every
sample and every 5th) and 30 synthetic skills: 0 glitch samples.
"""
import numpy as np

from drake_skills.data.interaction import load_interactions
from drake_skills.data.lasa import load_lasa, lasa_workspace
from drake_skills.data.synthetic import skill_bank
from drake_skills.evaluation.interaction import workspace_of
from drake_skills.evaluation.scale import LASA_SHAPES
from drake_skills.promp.preprocessing import spike_samples
from drake_skills.scenario.salad import generate_subject
from shared_data import require

TOL = 0.1


def _count(ys):
    return sum(int(spike_samples(y, TOL).sum()) for y in ys)


def test_no_clean_buetepage_sample_is_a_glitch_at_100_33_or_10_hz():
    inter = load_interactions(require(), rate_hz=100.0)
    ws = workspace_of(inter.train)
    ys = [ws.normalize(d.human) for d in inter.train + inter.test]
    assert {every: _count([y[::every] for y in ys]) for every in (1, 3, 10)} == {1: 0, 3: 0, 10: 0}


def test_no_clean_lasa_salad_or_synthetic_sample_is_a_glitch():
    demos = load_lasa(tuple(LASA_SHAPES))
    ws = lasa_workspace(demos)
    ys = [ws.normalize(d.human) for d in demos]
    assert {every: _count([y[::every] for y in ys]) for every in (1, 5, 20)} == {1: 0, 5: 0, 20: 0}
    salad = {}
    for i in range(1, 11):
        s = generate_subject(i, n_demos=3)
        w = s.workspace()
        salad[i] = _count([w.normalize(d.human)[::every] for d in s.demos for every in (1, 5)])
    assert salad == dict.fromkeys(range(1, 11), 0)
    bank, rng = skill_bank(30, 0), np.random.default_rng(1)
    assert _count([bank.demo(k, rng).human for k in range(30)]) == 0
