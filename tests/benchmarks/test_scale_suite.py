"""The ``scale`` bench suite at reduced size: it runs and reports every call at every K (figures, not timed tests)."""
from drake_skills.benchmarks import discover_suites
from drake_skills.benchmarks.scale import QUICK_SIZES


def test_scale_suite_reports_each_call_at_each_size_with_its_ratio_to_the_smallest():
    rows = discover_suites()["scale"](quick=True)
    names = [r["name"] for r in rows]
    for call in ("partial_fit", "recognize (whole motion)", "recognize (beginning, phase estimated)"):
        for K in QUICK_SIZES:
            (row,) = [r for r in rows if r["name"].startswith(f"{call}, K={K} ")]
            assert row["unit"] == "ms" and row["value"] > 0 and row["cpu ms"] > 0
            assert (row["ratio"] == "") == (K == QUICK_SIZES[0])
            assert f"(found {K})" in row["name"]  # the library holds the skills it was shown
    assert {f"save, K={QUICK_SIZES[-1]}", f"load, K={QUICK_SIZES[-1]}", f"file size, K={QUICK_SIZES[-1]}"} <= set(names)
