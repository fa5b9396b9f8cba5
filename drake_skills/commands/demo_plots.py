"""One plot per demo trial: what the gating believed while the person moved, and when it committed."""
from __future__ import annotations

import math
from pathlib import Path


def plot_trial(result, outcome, path: Path) -> Path:
    """Component probabilities and the estimated phase against time, the commit and the final answer marked.

    Parameters
    ----------
    result : drake_skills.sim.demo.TrialResult
    outcome : drake_skills.sim.demo.TrialOutcome
    path : Path
        The PNG to write.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t0 = outcome.start_time
    beliefs = outcome.beliefs
    fig, (ax, axp) = plt.subplots(2, 1, figsize=(6.4, 4.2), sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    ids = sorted({k for b in beliefs for k, _ in b.posterior})
    times = [b.time - t0 for b in beliefs]
    for k in ids:
        ax.plot(times, [dict(b.posterior).get(k, 0.0) for b in beliefs], ".-", lw=1, ms=3, label=f"skill {k}")
    axp.plot(times, [b.phase for b in beliefs], "k.-", lw=1, ms=3)
    if math.isfinite(outcome.plan_start):
        for a in (ax, axp):
            a.axvline(outcome.plan_start - t0, color="tab:green", ls="--", lw=1)
        ax.text(outcome.plan_start - t0, 1.02, " commit", color="tab:green", fontsize=8, va="bottom")
    if math.isfinite(outcome.decision_time):
        for a in (ax, axp):
            a.axvline(outcome.decision_time, color="0.4", ls=":", lw=1)
        ax.text(outcome.decision_time, 1.02, f" at rest: {outcome.status}", color="0.3", fontsize=8, va="bottom")
    ax.set(ylabel="p(skill | motion so far)", ylim=(-0.05, 1.15),
           title=f"trial {result.trial}: {result.task} -> {result.decision}"
                 + (f" ({result.recognized_task})" if result.recognized_task else "") + f" [{result.outcome}]")
    axp.set(xlabel="time since the trial started (s)", ylabel="phase", ylim=(-0.05, 1.05))
    if ids:
        ax.legend(fontsize=7, loc="center right")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path
