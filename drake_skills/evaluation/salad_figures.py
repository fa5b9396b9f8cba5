"""The figures of the salad experiment (Table 1 as bars, Table 3, Fig. 9, the response error)."""
from __future__ import annotations

import numpy as np

from drake_skills.evaluation.common import Table, count_distribution
from drake_skills.evaluation.salad_data import SaladSettings
from drake_skills.evaluation.salad_transfer import TASK_COUNT_BINS, TASK_COUNT_LABELS, TaskComponentsTrial

_COLORS = {"correct": "tab:green", "unknown": "tab:blue", "wrong": "tab:red"}


def _stacked(ax, x, c, w, u, width, hatch=None, label=True):
    ax.bar(x, c, width, color=_COLORS["correct"], hatch=hatch, label="correct" if label else None)
    ax.bar(x, u, width, bottom=c, color=_COLORS["unknown"], hatch=hatch, label="unknown" if label else None)
    ax.bar(x, w, width, bottom=np.add(c, u), color=_COLORS["wrong"], hatch=hatch, label="wrong" if label else None)


def fig_classification(s: SaladSettings, names: list[str], table: Table):
    import matplotlib.pyplot as plt

    T = len(s.tasks)
    fig, ax = plt.subplots(figsize=(max(6.0, 0.32 * len(names) * (T + 1)), 3.6))
    lookup = {(r[0], r[1]): r[2:5] for r in table.rows}
    for i, n in enumerate(names):
        x = i * (T + 1) + np.arange(T)
        c, w, u = (np.array([lookup[(n, t)][j] for t in s.tasks]) for j in range(3))
        _stacked(ax, x, c, w, u, 0.85, label=i == 0)
        for xi, t in zip(x, s.tasks):
            ax.text(xi, 0.02, t[:2], ha="center", va="bottom", fontsize=6, rotation=90, color="w")
    ax.set_xticks([i * (T + 1) + (T - 1) / 2 for i in range(len(names))])
    ax.set_xticklabels([n.replace("subject", "S") for n in names])
    ax.set_ylim(0, 1)
    ax.set_ylabel("fraction of test motions")
    ax.set_title("Personal libraries: classification per subject and task (Table 1)", fontsize=10)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    return fig


def fig_task_components(s: SaladSettings, tc: list[TaskComponentsTrial]):
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(s.tasks), figsize=(2.4 * len(s.tasks), 2.8), sharey=True, squeeze=False)
    x = np.arange(len(TASK_COUNT_BINS))
    for ax, task in zip(axes[0], s.tasks):
        for off, variant, c, lab in ((-0.27, "with", "tab:green", "personal"), (0.0, "without", "0.5", "shared"),
                                     (0.27, "raw", "0.8", "shared, start kept")):
            d = count_distribution([r.count(variant) for r in tc if r.task == task], TASK_COUNT_BINS)
            ax.bar(x + off, d, 0.27, color=c, label=lab)
        ax.set_xticks(x)
        ax.set_xticklabels(TASK_COUNT_LABELS, fontsize=7)
        ax.set_title(task, fontsize=9)
        ax.set_xlabel("components")
    axes[0, 0].set_ylabel("fraction of orders")
    axes[0, 0].legend(fontsize=7, title="workspace", title_fontsize=7)
    fig.suptitle("Components per task across subjects (Table 3)", fontsize=10)
    fig.tight_layout()
    return fig


def fig_transfer(s: SaladSettings, names: list[str], table: Table):
    import matplotlib.pyplot as plt

    lookup = {(r[0], r[1], r[2]): r[3:6] for r in table.rows}
    panels = (*s.tasks, "all")
    fig, axes = plt.subplots(len(panels), 1, figsize=(max(6.0, 0.7 * len(names) + 1.5), 1.7 * len(panels)),
                             sharex=True, squeeze=False)
    x = np.arange(len(names))
    for ax, task in zip(axes[:, 0], panels):
        for off, label, hatch in ((-0.2, "personal workspace", None), (0.2, "shared workspace", "//")):
            vals = np.array([lookup[(n, task, label)] for n in names])
            _stacked(ax, x + off, vals[:, 0], vals[:, 1], vals[:, 2], 0.38, hatch=hatch,
                     label=task == panels[0] and hatch is None)
        ax.set_ylim(0, 1)
        ax.set_ylabel(task, fontsize=8)
    axes[0, 0].legend(fontsize=6, ncol=3, loc="lower left")
    axes[-1, 0].set_xticks(x)
    axes[-1, 0].set_xticklabels([n.replace("subject", "S") for n in names])
    axes[-1, 0].set_xlabel("held-out subject (left bar: personal workspace, right hatched: shared workspace)")
    fig.suptitle("Leave one subject out: correct / unknown / wrong (Fig. 9)", fontsize=10)
    fig.tight_layout()
    return fig


def fig_response(s: SaladSettings, rows: list[list]):
    import matplotlib.pyplot as plt

    a = np.array([[float(v) for v in r] for r in rows])
    f = a[:, 0]
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.4))
    ax = axes[0]
    for j, name in ((1, "correct"), (2, "wrong"), (3, "unknown")):
        ax.plot(f, a[:, j], "o-", color=_COLORS[name], label=name)
    ax.axhline(s.target_accuracy, color="k", ls=":", lw=1)
    ax.set_ylim(-0.02, 1.02)
    ax.set_ylabel("fraction of test motions")
    ax.set_title("decision", fontsize=9)
    ax = axes[1]
    ax.plot(f, a[:, 4], "o-", color="tab:green", label="conditioned (mean)")
    ax.plot(f, a[:, 5], "s--", color="tab:green", alpha=0.6, label="conditioned (median)")
    ax.plot(f, a[:, 6], "o-", color="0.5", label="component mean (prior)")
    ax.set_ylabel("joint RMSE (rad)")
    ax.set_title("joint trajectory error (correct decisions)", fontsize=9)
    ax = axes[2]
    ax.plot(f, a[:, 7], "o-", color="tab:green", label="conditioned (mean)")
    ax.plot(f, a[:, 8], "s--", color="tab:green", alpha=0.6, label="conditioned (median)")
    ax.plot(f, a[:, 9], "o-", color="0.5", label="component mean (prior)")
    ax.set_ylabel("flange error at the handover (cm)")
    ax.set_title("handover position error (correct decisions)", fontsize=9)
    for ax in axes:
        ax.set_xlabel("observed fraction of the human path")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    for ax in axes[1:]:
        ax.set_ylim(bottom=0)
    fig.suptitle("Robot response vs observed fraction (personal libraries)", fontsize=10)
    fig.tight_layout()
    return fig
