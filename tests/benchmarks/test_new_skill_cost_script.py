"""benchmarks/new_skill_cost.py (RESULTS.md, "A skill never taught, as a hypothesis for beginnings"): its counts."""
from bench_scripts import load


def test_one_bank_counts_every_beginning_once_and_the_hypothesis_only_holds_answers():
    out = load("new_skill_cost").measure(banks=1, taught=3, demos=3, shares=(0.3, 0.6))
    assert out["taught beginnings"] == 6 and out["untaught beginnings"] == 2
    # the hypothesis only turns answers into "undecided": never a new answer, never a wrong one
    assert out["held, on"] <= out["answered right, off"] + out["answered wrong, off"]
    assert out["answered wrong, on"] <= out["answered wrong, off"]
    assert out["answered, on"] <= out["answered, off"]
    assert out["answered right, off"] >= 4          # measured: 6 of 6 (separated skills)
