"""The anticipation suite of `drake-skills bench` and its CPU-time helper (figures printed, not asserted)."""
import pytest

from drake_skills.benchmarks import _timing, anticipation
from drake_skills.benchmarks._timing import fastest_cpu_ms


def test_fastest_cpu_ms_is_the_fastest_pass_per_item_after_a_warm_up(monkeypatch):
    """A fake CPU clock: item x costs x ms, plus 10 ms more in the second timed pass (a busy neighbour's cache)."""
    clock = [0.0]
    calls = []
    monkeypatch.setattr(_timing.time, "process_time", lambda: clock[0])

    def work(x):
        calls.append(x)
        clock[0] += 1e-3 * x + (10e-3 if len(calls) == 7 else 0.0)   # call 7: the second timed pass's first

    ms = fastest_cpu_ms(work, [1, 2, 3], batches=2)
    assert calls == [1, 2, 3] * 3                  # one warm-up pass, then the two timed
    assert ms == pytest.approx(2.0, abs=1e-9)       # (1 + 2 + 3) / 3 items: the first timed pass, the faster
    with pytest.raises(ValueError, match="at least one item"):
        fastest_cpu_ms(work, [], batches=2)
    with pytest.raises(ValueError, match="batches >= 1, got 0"):
        fastest_cpu_ms(work, [1], batches=0)


def test_the_anticipation_suite_reports_the_controllers_calls_by_wall_clock_and_cpu_time():
    rows = anticipation.run(quick=True)
    names = [r["name"] for r in rows]
    assert names[3].startswith("recognize + phase + predict from a prefix, K=5") and rows[3]["goal"]
    assert names[4:] == ["recognize a prefix, CPU ms", "estimate_phase + predict_robot, CPU ms",
                         "recognize + phase + predict, CPU ms"]
    assert all(r["unit"] == "ms" and r["value"] > 0 for r in rows)
    assert all("3 passes over the 20 prefixes" in r["notes"] for r in rows[4:])
