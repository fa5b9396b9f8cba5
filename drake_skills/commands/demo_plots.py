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


#: Opens the recording at ``#t=SECONDS`` (and on every change of the address's fragment): pauses the
#: animation and seeks there, once the recorded commands are loaded.
SEEK_SCRIPT = """<script>
(function () {
  function seek() {
    var m = location.hash.match(/t=([0-9.]+)/);
    if (!m) return;
    var t = parseFloat(m[1]), tries = 0;
    var timer = setInterval(function () {
      tries += 1;
      var a = (typeof viewer !== "undefined") ? viewer.animator : null;
      if (a && a.actions && a.actions.length) {
        a.play(); a.pause(); a.seek(t); a.display_progress(t); clearInterval(timer);
      } else if (tries > 400) { clearInterval(timer); }
    }, 25);
  }
  window.addEventListener("hashchange", seek);
  seek();
})();
</script>"""


def legend_html(results) -> str:
    """A fixed panel for the meshcat recording: one row per trial (time in the recording, task, answer, confidence).

    The colour swatch is the one the wrist and the lamp take for that answer, so a
    viewer can find each trial on the timeline and read what the robot decided.
    """
    from drake_skills.sim.wrist_marker import PENDING_RGBA, UNDECIDED_RGBA, UNKNOWN_RGBA, skill_rgba

    def css(rgba):
        return "rgb({:.0f},{:.0f},{:.0f})".format(*(255 * c for c in rgba[:3]))

    rows = []
    for r in results:
        if r.component is not None:
            colour = skill_rgba(r.component)
        else:
            colour = {"unknown": UNKNOWN_RGBA, "undecided": UNDECIDED_RGBA}.get(r.status, PENDING_RGBA)
        answer = r.decision + (f" ({r.recognized_task})" if r.recognized_task else "")
        commit = "" if not math.isfinite(r.decision_fraction) else f"{100 * r.decision_fraction:.0f}%"
        t_answer = r.start_time + (r.decision_delay if math.isfinite(r.decision_delay) else 0.0) + 0.05
        rows.append(f"<tr><td><a href='#t={t_answer:.2f}'>{r.trial}</a></td>"
                    f"<td>{r.start_time:.1f}-{r.end_time:.1f}</td><td>{r.task}</td>"
                    f"<td><span style='display:inline-block;width:10px;height:10px;background:{css(colour)}'>"
                    f"</span> {answer}</td><td>{r.confidence:.2f}</td><td>{commit}</td><td>{r.outcome}</td></tr>")
    return ("<div id='drake-skills-legend' style='position:fixed;left:8px;bottom:8px;max-height:45%;"
            "overflow:auto;background:rgba(255,255,255,0.88);font:11px sans-serif;padding:4px;z-index:10'>"
            "<b>drake-skills demo</b> (grey: observing; colour: the committed skill; magenta: unknown; amber: "
            "undecided; the bar: confidence). Click a trial to see its final answer; open the page with "
            "<code>#t=SECONDS</code> to start there.<table style='border-collapse:collapse'><tr><th>trial</th>"
            "<th>time (s)</th><th>task</th><th>answer</th><th>p</th><th>commit</th><th>result</th></tr>"
            + "".join(rows) + "</table></div>" + SEEK_SCRIPT)
