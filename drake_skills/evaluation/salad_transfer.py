"""Across subjects: components per task (Table 3) and leave one subject out (Fig. 9).

Table 3. Per task and trial, a library is learned from ``table3_demos`` random
demonstrations of that task of every subject, in a random order, once with each
subject's personal workspace (Eq. 14, "with") and once with one shared workspace, the
bounding box of all subjects' calibrations ("without"); both subtract the start
position (Eq. 14). A third library also keeps the start position (shared workspace,
``subtract_start=False``): the paper's "without transformation" of Fig. 8.

Fig. 9. Per held-out subject and trial: a library learned from ``transfer_train`` random
demonstrations per task of every other subject in a random order, tested on
``transfer_test`` random demonstrations per task of the held-out subject; with personal
workspaces (the held-out subject's own for its tests) and with the shared workspace.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from drake_skills.evaluation.common import Table, count_distribution, stream_rng
from drake_skills.evaluation.labeled import LabeledLibrary, fractions_of
from drake_skills.evaluation.salad_data import SaladContext, SaladSettings
from drake_skills.library.incremental import SkillLibrary
from drake_skills.scenario.salad import TASKS

#: Random streams (second seed word).
STREAM_TASKS, STREAM_TRANSFER = 23, 24
#: Bins of Table 3 (components per task): <= 1, 2, 3, 4, 5, >= 6.
TASK_COUNT_BINS = ((0, 1), 2, 3, 4, 5, (6, None))
TASK_COUNT_LABELS = ("<=1", "2", "3", "4", "5", ">=6")
#: Libraries of Table 3: variant (the summary's key) -> row label.
TABLE3_VARIANTS = {"with": "personal workspace", "without": "shared workspace",
                   "raw": "shared workspace, no start offset"}
#: Libraries of Fig. 9: variant -> label.
TRANSFER_VARIANTS = {"with": "personal workspace", "without": "shared workspace"}


@dataclass(frozen=True)
class TaskComponentsTrial:
    """Components of the three one-task libraries of one order (Table 3)."""

    task: str
    #: With each subject's personal workspace ("with").
    personal: int
    #: With the shared workspace ("without").
    shared: int
    #: With the shared workspace, start position kept ("raw").
    raw: int

    def count(self, variant: str) -> int:
        """Components of the library of a :data:`TABLE3_VARIANTS` key."""
        return {"with": self.personal, "without": self.shared, "raw": self.raw}[variant]


@dataclass(frozen=True, eq=False)
class TransferTrial:
    """One held-out subject and trial (Fig. 9); outcomes (n_test,) are CORRECT / WRONG / UNKNOWN."""

    #: The held-out subject.
    subject: str
    #: Task of each test motion.
    tasks: tuple[str, ...]
    personal: np.ndarray
    shared: np.ndarray
    n_components_personal: int
    n_components_shared: int

    def outcomes(self, variant: str) -> np.ndarray:
        """The outcomes of a :data:`TRANSFER_VARIANTS` key."""
        return {"with": self.personal, "without": self.shared}[variant]


def task_components_trial(ctx: SaladContext, item: tuple[str, int]) -> TaskComponentsTrial:
    """Components of a one-task library across subjects (Table 3).

    The same demonstrations in the same order go into the three libraries, without their task name: Table 3
    counts the components a library needs for one task's motions across people, as the paper's library learns
    them (without names); given its one name, a library merges the task's fragments by it
    (``LibraryConfig.same_task_reach``) and counts what the teacher said rather than what the motions need.
    """
    s = ctx.settings
    task, order = item
    rng = stream_rng(s.seed, STREAM_TASKS, TASKS.index(task), order)
    demos, personal = [], []
    for data, ws in zip(ctx.subjects, ctx.workspaces):
        pool = data.by_task(task)
        for j in rng.permutation(len(pool))[:s.table3_per_task]:
            demos.append(replace(pool[j], task=None))
            personal.append(ws)
    with_ws, without_ws = SkillLibrary(s.library), SkillLibrary(s.library)
    raw = SkillLibrary(replace(s.library, subtract_start=False))
    for j in rng.permutation(len(demos)):
        with_ws.partial_fit(demos[j], workspace=personal[j])
        without_ws.partial_fit(demos[j], workspace=ctx.shared)
        raw.partial_fit(demos[j], workspace=ctx.shared)
    return TaskComponentsTrial(task, with_ws.n_components, without_ws.n_components, raw.n_components)


def transfer_trial(ctx: SaladContext, item: tuple[int, int]) -> TransferTrial:
    """Leave one subject out (Fig. 9): learn on the others, test on the held-out subject.

    Parameters
    ----------
    item : (position of the held-out subject in ``ctx.subjects``, trial index)
    """
    s = ctx.settings
    held, trial = item
    subjects, wss = ctx.subjects, ctx.workspaces
    rng = stream_rng(s.seed, STREAM_TRANSFER, subjects[held].subject.index, trial)
    train, train_ws = [], []
    for pos, data in enumerate(subjects):
        if pos == held:
            continue
        for task in s.tasks:
            pool = data.by_task(task)
            for j in rng.permutation(len(pool))[:s.transfer_train_per_task]:
                train.append(pool[j])
                train_ws.append(wss[pos])
    test = []
    for task in s.tasks:
        pool = subjects[held].by_task(task)
        test += [pool[j] for j in rng.permutation(len(pool))[:s.transfer_test_per_task]]
    order = rng.permutation(len(train))
    outcomes, components = {}, {}
    for variant in TRANSFER_VARIANTS:
        lab = LabeledLibrary(s.library)
        for j in order:
            lab.teach(train[j], train_ws[j] if variant == "with" else ctx.shared)
        ws_test = wss[held] if variant == "with" else ctx.shared
        outcomes[variant] = np.array([lab.classify(d.human, d.task, ws_test)[0] for d in test], dtype=int)
        components[variant] = lab.library.n_components
    return TransferTrial(subjects[held].subject.name, tuple(d.task for d in test), outcomes["with"],
                         outcomes["without"], components["with"], components["without"])


def task_components_tables(s: SaladSettings, tc: list[TaskComponentsTrial]):
    rows, matrix, summary = [], [], {}
    for task in s.tasks:
        counts = {v: [r.count(v) for r in tc if r.task == task] for v in TABLE3_VARIANTS}
        dist = {v: count_distribution(c, TASK_COUNT_BINS) for v, c in counts.items()}
        for v, label in TABLE3_VARIANTS.items():
            rows.append([task, label, *dist[v], float(np.mean(counts[v]))])
        matrix.append([task, *[f"{a:.2f} ({b:.2f})" for a, b in zip(dist["with"], dist["without"])]])
        summary[task] = {v: float(np.mean(c)) for v, c in counts.items()}
    how = (f"one library per task from {s.table3_per_task} random demonstrations of that task of each of the "
           f"{s.n_subjects} subjects, in a random order, {s.trials} orders")
    long = Table(["task", "normalization", *TASK_COUNT_LABELS, "mean"], rows,
                 caption=(f"Components per task across subjects (Table 3): {how}; 'personal workspace' normalizes "
                          f"each demonstration with its subject's calibration (Eq. 14), 'shared workspace' with "
                          f"the bounding box of all calibrations, both subtracting the start position; the third "
                          f"row also keeps the start position (LibraryConfig(subtract_start=False)), the paper's "
                          f"'without transformation' of Fig. 8."))
    mat = Table(["task", *TASK_COUNT_LABELS], matrix,
                caption=f"Table 3 in the paper's layout: personal (shared) workspace; {how}.")
    return long, mat, summary


def transfer_table(s: SaladSettings, names: list[str], tr: list[TransferTrial]):
    rows, acc = [], {}
    for variant, label in TRANSFER_VARIANTS.items():
        all_o = []
        for n in names:
            rs = [r for r in tr if r.subject == n]
            tasks = np.concatenate([np.asarray(r.tasks) for r in rs])
            o = np.concatenate([r.outcomes(variant) for r in rs])
            all_o.append(o)
            for task in s.tasks:
                m = tasks == task
                rows.append([n, task, label, *fractions_of(o[m]), int(m.sum())])
            rows.append([n, "all", label, *fractions_of(o), int(o.size)])
        o = np.concatenate(all_o)
        rows.append(["all", "all", label, *fractions_of(o), int(o.size)])
        acc[variant] = fractions_of(o)
    t = Table(["held-out subject", "task", "normalization", "correct", "wrong", "unknown", "tests"], rows,
              caption=(f"Leave one subject out (Fig. 9): a library learned from {s.transfer_train_per_task} "
                       f"demonstrations per task of each other subject (random order), tested on "
                       f"{s.transfer_test_per_task} demonstrations per task of the held-out subject; {s.trials} "
                       f"trials per held-out subject; with personal or one shared workspace."))
    return t, acc
