"""``drake-skills plot-demos DIR``: human wrist trajectories per task, top and front views (Fig. 5(b)).

``demos.png`` shows one subject, a colour per task (the paper's Fig. 5(b)); with more
than one subject under DIR, ``tasks.png`` shows every task across the subjects, a colour
per subject: how much the people differ in each task.
"""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

#: Colour per task (matplotlib tab10); unknown tasks cycle through the rest.
TASK_COLOURS = {"board": "tab:blue", "tomato": "tab:red", "bowl": "tab:green", "dressing": "tab:orange",
                "standup": "tab:purple"}


def register(sub) -> None:
    from drake_skills.commands import add_out

    p = sub.add_parser(
        "plot-demos", help="plot the human wrist trajectories of one subject (top and front views)",
        description="Plot the human wrist trajectories of the demonstrations under DIR for one subject, one "
                    "colour per task, seen from the top (x-y) and from the front (y-z), like the paper's "
                    "Fig. 5(b) (OUT/demos.png); with more than one subject, also every task across the subjects, "
                    "one colour per subject (OUT/tasks.png: the spread per task).")
    p.add_argument("demos_dir", type=Path, metavar="DIR", help="directory of demonstrations (searched recursively)")
    p.add_argument("--subject", default=None, help="subject to plot (default: the first one found)")
    p.add_argument("--columns", default=None, metavar="I,J,K",
                   help="the three human columns to plot as x, y, z (0-based; default 0,1,2; e.g. 6,7,8 for the "
                        "hand of a 9-column arm: shoulder, elbow, hand)")
    add_out(p, "plot-demos", "demos.png and tasks.png")
    p.set_defaults(func=run)


def plot_demos(demos, title: str = ""):
    """Figure with top (x-y) and front (y-z) views of the human wrist trajectories.

    Parameters
    ----------
    demos : list of Demonstration
        With ``human`` of shape (T, 3) (or (T, 2): only the top view is meaningful).
    title : str

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, front) = plt.subplots(1, 2, figsize=(11, 5))
    spare = iter(["tab:brown", "tab:pink", "tab:gray", "tab:olive", "tab:cyan"] * 10)
    colours = dict(TASK_COLOURS)
    seen = set()
    for d in demos:
        task = d.task or "unlabelled"
        if task not in colours:
            colours[task] = next(spare)
        c = colours[task]
        label = task if task not in seen else None
        seen.add(task)
        h = d.human
        top.plot(h[:, 1], h[:, 0], color=c, lw=0.8, alpha=0.8, label=label)
        top.plot(h[0, 1], h[0, 0], "k.", ms=3)
        if h.shape[1] >= 3:
            front.plot(h[:, 1], h[:, 2], color=c, lw=0.8, alpha=0.8)
            front.plot(h[0, 1], h[0, 2], "k.", ms=3)
    top.set_title("top view")
    front.set_title("front view (from behind the person)")
    _views(top, front)
    top.legend(loc="best", fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def _views(top, front):
    # the person sits at -x looking toward +x: show y increasing to the left, as seen by the person
    top.set_xlabel("y [m] (person's left ←)")
    top.set_ylabel("x [m] (away from the person ↑)")
    front.set_xlabel("y [m] (person's left ←)")
    front.set_ylabel("z [m]")
    for ax in (top, front):
        ax.invert_xaxis()
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)


def plot_tasks_across_subjects(demos, title: str = ""):
    """Figure with one column per task: top (x-y) and front (y-z) views, a colour per subject.

    Parameters
    ----------
    demos : list of Demonstration
        With ``task`` and ``subject`` labels and ``human`` of shape (T, 3).
    title : str

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    found = list(dict.fromkeys(d.task or "unlabelled" for d in demos))
    tasks = [t for t in TASK_COLOURS if t in found] + [t for t in found if t not in TASK_COLOURS]
    subjects = sorted({d.subject or "?" for d in demos}, key=lambda s: (len(s), s))
    demos = sorted(demos, key=lambda d: subjects.index(d.subject or "?"))
    cmap = plt.get_cmap("tab10" if len(subjects) <= 10 else "tab20")
    colour = {s: cmap(i % cmap.N) for i, s in enumerate(subjects)}
    fig, axes = plt.subplots(2, len(tasks), figsize=(4.2 * len(tasks), 8), squeeze=False)
    for j, task in enumerate(tasks):
        top, front = axes[0, j], axes[1, j]
        seen = set()
        for d in demos:
            if (d.task or "unlabelled") != task:
                continue
            s, h = d.subject or "?", d.human
            top.plot(h[:, 1], h[:, 0], color=colour[s], lw=0.7, alpha=0.8, label=s if s not in seen else None)
            seen.add(s)
            if h.shape[1] >= 3:
                front.plot(h[:, 1], h[:, 2], color=colour[s], lw=0.7, alpha=0.8)
        top.set_title(f"{task}: top view")
        front.set_title(f"{task}: front view")
        _views(top, front)
    axes[0, 0].legend(loc="best", fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def run(args: argparse.Namespace) -> int:
    from drake_skills.data.demos import scan_dir

    scan = scan_dir(args.demos_dir)
    for note in scan.notes():
        print(f"note: {note}")
    everyone = demos = scan.demos
    if not demos:
        raise ValueError(f"no demonstrations (.npz or .csv) found under '{args.demos_dir}'")
    width = min(d.dim_human for d in demos)
    cols = _columns(args.columns, width)
    if cols != list(range(min(3, width))) or max(d.dim_human for d in demos) > 3:
        print(f"note: plotting human columns {','.join(map(str, cols))} as x, y, z of "
              f"{max(d.dim_human for d in demos)}" + ("" if args.columns else "; --columns I,J,K for others"))
    everyone = demos = [replace(d, human=d.human[:, cols]) for d in demos]
    subjects = sorted({d.subject for d in demos if d.subject}, key=lambda s: (len(s), s))
    subject = args.subject or (subjects[0] if subjects else None)
    if subject is not None:
        if subject not in subjects:
            raise ValueError(f"subject {subject!r} not found; subjects are {subjects}" if subjects else
                             f"subject {subject!r} not found: the demonstrations under '{args.demos_dir}' carry no "
                             f"'subject' label; leave out --subject")
        demos = [d for d in demos if d.subject == subject]
    fig = plot_demos(demos, title=f"{subject or args.demos_dir}: {len(demos)} demonstrations")
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "demos.png"
    fig.savefig(path, dpi=110)
    print(f"wrote {path} ({len(demos)} demonstrations of {subject or 'all subjects'})")
    if len(subjects) > 1:
        fig = plot_tasks_across_subjects(everyone, title=f"{args.demos_dir}: every task across {len(subjects)} "
                                                         f"subjects ({len(everyone)} demonstrations)")
        path = args.out / "tasks.png"
        fig.savefig(path, dpi=90)
        print(f"wrote {path} (each task across {len(subjects)} subjects)")
    return 0


def _columns(spec: str | None, width: int) -> list[int]:
    """The human columns ``--columns`` names (default the first three), checked against ``width``."""
    if spec is None:
        return list(range(min(3, width)))
    try:
        cols = [int(c) for c in spec.split(",")]
    except ValueError:
        raise ValueError(f"--columns takes column indices like 6,7,8, got {spec!r}") from None
    if len(cols) != min(3, width) or len(set(cols)) != len(cols) or any(c < 0 or c >= width for c in cols):
        raise ValueError(f"--columns takes {min(3, width)} different indices in 0..{width - 1} (the demonstrations "
                         f"have {width} human columns), got {spec!r}")
    return cols
