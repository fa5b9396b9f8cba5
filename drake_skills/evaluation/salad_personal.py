"""Personal libraries (Tables 1 and 2) and the robot's response to a partly observed motion.

For every subject and every one of ``trials`` random splits: per task, ``n_train``
demonstrations for training and the rest for testing; the training demonstrations (all
tasks) are folded into a fresh library in a random order, in the subject's own
workspace. Table 1: correct / wrong / unknown fractions of the full test motions per
subject and task. Table 2: distribution of the number of components per subject.

Robot response (beyond the paper, same libraries and test motions): for every observed
fraction ``f`` of the test motion's *path length* (the meaning of ``observed_fraction`` in
the library), recognize the prefix and, if a component is chosen, condition its
Interaction ProMP on the prefix (Eq. 13). Error of the conditioned mean robot trajectory
(over the component's phase) against the demonstrated one (resampled uniformly in time):
joint RMSE in rad, and the distance of the flange (forward kinematics of the IIWA7 at the
scene's base) at the last step, i.e. at the handover, in cm. The unconditioned component
mean ("prior") is scored the same way. The earliest fraction from which P(correct) stays
>= 95 %.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from drake_skills.data.demonstration import Demonstration
from drake_skills.data.workspace import Workspace
from drake_skills.evaluation.common import Table, count_distribution, stream_rng
from drake_skills.evaluation.interaction import replayed_commit
from drake_skills.evaluation.labeled import (CORRECT, UNKNOWN, WRONG, LabeledLibrary, fractions_of,
                                             outcome_fractions)
from drake_skills.evaluation.salad_data import SaladContext, SaladSettings
from drake_skills.library.incremental import SkillLibrary
from drake_skills.promp.preprocessing import prefix_samples, resample_in_time, vertex_path, walk_is_causal
from drake_skills.sim.models import FlangeKinematics

#: Random stream of the splits (second seed word).
STREAM_PERSONAL = 21
#: The per-fraction arrays of a test motion, in table order.
ERROR_FIELDS = ("outcome", "rmse", "flange", "prior_rmse", "prior_flange", "anticipated", "phase")


@dataclass(frozen=True, eq=False)
class ResponseErrors:
    """Decision and robot response error of one test motion; arrays of shape (n_fractions,).

    NaN where the motion is unknown.
    """

    #: CORRECT, WRONG or UNKNOWN (ints).
    outcome: np.ndarray
    #: Joint RMSE of the conditioned mean trajectory (rad).
    rmse: np.ndarray
    #: Flange position error at its end, the handover (cm).
    flange: np.ndarray
    #: The same for the recognized component's unconditioned mean.
    prior_rmse: np.ndarray
    prior_flange: np.ndarray
    #: The decision without being told the fraction (phase estimated): CORRECT, WRONG, UNKNOWN or UNDECIDED.
    anticipated: np.ndarray = None
    #: The estimated phase of the best candidate then (NaN when unknown).
    phase: np.ndarray = None


@dataclass(frozen=True, eq=False)
class PersonalTrial:
    """One train/test split of one subject; arrays of shape (n_test, n_fractions of ``settings.grid()``)."""

    subject: str
    n_components: int
    #: Task of each test motion.
    tasks: tuple[str, ...]
    outcome: np.ndarray
    rmse: np.ndarray
    flange: np.ndarray
    prior_rmse: np.ndarray
    prior_flange: np.ndarray
    #: Decisions and estimated phases without the fraction given (see :class:`ResponseErrors`).
    anticipated: np.ndarray
    phase: np.ndarray
    #: The controller's decision logic replayed on each test motion (``settings.commit_splits`` splits per
    #: subject; empty otherwise): the first commit's outcome (CORRECT or WRONG; UNKNOWN: none), the share of
    #: the path done at it (NaN: none) and the outcome of the skill executed at the end.
    first_commit: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    commit_share: np.ndarray = field(default_factory=lambda: np.zeros(0))
    executed: np.ndarray = field(default_factory=lambda: np.zeros(0, int))


@dataclass(frozen=True, eq=False)
class PersonalContext:
    """The salad context and the forward kinematics of the flange (one plant per process)."""

    salad: SaladContext
    flange_position: FlangeKinematics = field(default_factory=FlangeKinematics)


def observed_prefix(human: np.ndarray, fraction: float, workspace=None, tolerance: float = 0.0, *,
                    adapt_to_noise: bool = True, average_holds: bool = True) -> np.ndarray:
    """The first ``fraction`` of a motion's path length (measured in the normalized workspace).

    The cut falls between two samples; the last row is interpolated there, so the
    prefix's path length is exactly ``fraction`` of the whole (what the library's
    ``observed_fraction`` assumes).

    Parameters
    ----------
    human : array, shape (T, D)
    fraction : float in (0, 1]
    workspace : Workspace, optional
    tolerance : float
        The library's ``resample_tolerance`` (normalized units): path length is
        measured through the same vertices the library uses
        (:func:`~drake_skills.promp.preprocessing.path_vertices`), so the prefix
        is ``fraction`` of the length the library sees.
    adapt_to_noise : bool
        The library's ``adapt_to_noise`` (default: the library's default). When the walk
        adapts to a noisy motion the prefix is its first samples whose own walk reaches
        ``fraction`` of the whole's (:func:`~drake_skills.promp.preprocessing.prefix_samples`),
        not interpolated.
    average_holds : bool
        The library's ``average_holds`` (default: the library's default), for that walk.

    Returns
    -------
    prefix : array, shape (m, D), m >= 2
    """
    human = np.asarray(human, float)
    f = float(fraction)
    if not 0 < f <= 1:
        raise ValueError(f"fraction must be in (0, 1], got {fraction!r}")
    if f == 1.0:
        return human
    y = workspace.normalize(human, subtract_start=False) if workspace is not None else human
    if not walk_is_causal(y, tolerance, adapt_to_noise=adapt_to_noise):
        return human[:prefix_samples(y, f, tolerance, adapt_to_noise=True, average_holds=average_holds)]
    idx, _, s = vertex_path(y, tolerance)
    human = human[idx]
    if human.shape[0] < 2:
        raise ValueError("the motion does not move beyond the tolerance: no prefix to observe")
    target = f * s[-1]
    i = int(np.searchsorted(s, target, side="right"))  # s[i-1] <= target < s[i]
    i = min(max(i, 1), len(s) - 1)
    a = (target - s[i - 1]) / max(s[i] - s[i - 1], 1e-300)
    cut = human[i - 1] + a * (human[i] - human[i - 1])
    prefix = np.vstack([human[:i], cut[None]])
    return prefix if prefix.shape[0] >= 2 else human[:2]


def _robot_mean(lib: SkillLibrary, component: int, n: int) -> np.ndarray:
    """The component's unconditioned mean robot trajectory (n, D_r)."""
    cfg = lib.config
    m = np.asarray(lib.component(component).mean)[lib.n_human:]
    return cfg.basis_robot.phi_uniform(n) @ m.reshape(lib.dim_robot_, -1).T


def response_errors(lab: LabeledLibrary, demo: Demonstration, workspace: Workspace, fractions: Sequence[float],
                    flange_position: FlangeKinematics) -> ResponseErrors:
    """Decision and robot response error of one test motion at each observed fraction.

    ``flange_position`` maps joints (7,) to the flange position (3,) (forward kinematics).
    """
    lib = lab.library
    nf = len(fractions)
    out = {"outcome": np.full(nf, UNKNOWN, dtype=int), "anticipated": np.full(nf, UNKNOWN, dtype=int)}
    for k in ("rmse", "flange", "prior_rmse", "prior_flange", "phase"):
        out[k] = np.full(nf, np.nan)
    p_demo = flange_position(demo.robot[-1])
    targets = {}
    for i, f in enumerate(fractions):
        human = observed_prefix(demo.human, f, workspace, lib.config.resample_tolerance, **lib.config.walk_options())
        got = lib.recognize(human, observed_fraction=f, workspace=workspace)
        comp = got.component
        out["outcome"][i] = lab.outcome(comp, demo.task, got.status)
        rec = lib.recognize(human, workspace=workspace)  # the fraction not given: the phase is estimated
        out["anticipated"][i] = lab.outcome(rec.component, demo.task, rec.status)
        out["phase"][i] = rec.phase
        if comp is None:
            continue
        mean, _ = lib.predict_robot(human, f, workspace=workspace, component=comp, restart=got.restart)
        n = mean.shape[0]
        if n not in targets:
            targets[n] = resample_in_time(demo.t, demo.robot, n)
        prior = _robot_mean(lib, comp, n)
        out["rmse"][i] = float(np.sqrt(np.mean((mean - targets[n]) ** 2)))
        out["prior_rmse"][i] = float(np.sqrt(np.mean((prior - targets[n]) ** 2)))
        out["flange"][i] = 100.0 * float(np.linalg.norm(flange_position(mean[-1]) - p_demo))
        out["prior_flange"][i] = 100.0 * float(np.linalg.norm(flange_position(prior[-1]) - p_demo))
    return ResponseErrors(**out)


def personal_trial(ctx: PersonalContext, item: tuple[int, int]) -> PersonalTrial:
    """One random train/test split of one subject (Tables 1-2 and the response error).

    Parameters
    ----------
    ctx : PersonalContext
    item : (subject position in ``ctx.salad.subjects``, split index)
    """
    s = ctx.salad.settings
    pos, split = item
    data = ctx.salad.subjects[pos]
    ws = data.workspace(z_factor=s.z_factor)
    rng = stream_rng(s.seed, STREAM_PERSONAL, data.subject.index, split)
    n_train = s.train_per_task
    train, test = [], []
    for task in s.tasks:
        demos = data.by_task(task)
        perm = rng.permutation(len(demos))
        train += [demos[j] for j in perm[:n_train]]
        test += [demos[j] for j in perm[n_train:]]
    lab = LabeledLibrary(s.library)
    for j in rng.permutation(len(train)):
        lab.teach(train[j], ws)
    grid = s.grid()
    rows = [response_errors(lab, d, ws, grid, ctx.flange_position) for d in test]
    commits = [replayed_commit(lab, d, ws)[:3] for d in test] if split < s.commit_splits else []
    first, share, executed = (np.array(x) for x in zip(*commits)) if commits else (np.zeros(0, int), np.zeros(0),
                                                                                  np.zeros(0, int))
    return PersonalTrial(data.subject.name, lab.library.n_components, tuple(d.task for d in test),
                         **{k: np.stack([getattr(r, k) for r in rows]) for k in ERROR_FIELDS},
                         first_commit=first.astype(int), commit_share=share.astype(float),
                         executed=executed.astype(int))


def commits_table(s: SaladSettings, personal: list[PersonalTrial]) -> tuple[Table, dict]:
    """Per task and over all: the first commits of the replayed decision logic and the path share at them."""
    first = np.concatenate([r.first_commit for r in personal])
    share = np.concatenate([r.commit_share for r in personal])
    executed = np.concatenate([r.executed for r in personal])
    tasks = np.concatenate([np.asarray(r.tasks) for r in personal if r.first_commit.size] or [np.zeros(0, str)])
    rows, summary = [], {}
    for task in (*s.tasks, "all"):
        m = np.ones(len(tasks), bool) if task == "all" else tasks == task
        c = m & np.isfinite(share)
        n, nc = int(m.sum()), int(c.sum())
        nan = float("nan")
        row = [task, n, nc / n if n else nan, float(np.sum(first[c] == CORRECT)) / nc if nc else nan,
               float(np.sum(first[c] == WRONG)) / nc if nc else nan, _nanstat(share[c], np.mean),
               _nanstat(share[c], np.median), *(fractions_of(executed[m]) if n else [float("nan")] * 3)]
        rows.append(row)
        summary[task] = dict(zip(("motions", "committed", "first_commit_correct", "first_commit_wrong",
                                  "mean_commit_share", "median_commit_share", "executed_correct",
                                  "executed_wrong", "executed_none"), row[1:]))
    table = Table(["task", "test motions", "committed", "first commit correct", "first commit wrong",
                   "mean path share at commit", "median path share at commit", "executed correct",
                   "executed wrong", "executed none (unknown or undecided)"], rows,
                  caption=(f"The controller's decision logic (gating_step, default DecisionRule: re-decide every "
                           f"1/16 s, commit after 2 equal answers) replayed on the test motions of the first "
                           f"{s.commit_splits} splits per subject, personal libraries: the first commit (correct / "
                           f"wrong over commits) and the share of the person's path done at it; 'executed' is the "
                           f"skill the robot runs at the end (a wrong commit revised in time is not executed). The "
                           f"demo's own stream (a library that learns only when it asks) is benchmarks/demo_replay.py."))
    return table, summary


def _nanstat(a, fn) -> float:
    a = np.asarray(a, float)
    a = a[np.isfinite(a)]
    return float(fn(a)) if a.size else float("nan")


def _paper_cell(c: float, w: float, u: float) -> str:
    """Table 1's cell: correct, then (wrong unknown) when not all correct."""
    return f"{c:.2f}" if w == 0 and u == 0 else f"{c:.2f} ({w:.2f} {u:.2f})"


def earliest_fraction(grid: Sequence[float], p_correct: Sequence[float], target: float) -> float | None:
    """Smallest fraction of ``grid`` from which ``p_correct`` stays >= ``target`` (None if never)."""
    best = None
    for f, p in sorted(zip(grid, p_correct), reverse=True):
        if not (np.isfinite(p) and p >= target):
            break
        best = f
    return best


def classification_tables(s: SaladSettings, names: list[str], personal: list[PersonalTrial]):
    i_full = s.grid().index(1.0)
    rows, matrix = [], []
    per = {n: {t: [] for t in s.tasks} for n in names}
    for r in personal:
        for task, o in zip(r.tasks, r.outcome[:, i_full]):
            per[r.subject][task].append(o)
    for n in names:
        cells = []
        for task in s.tasks:
            fr = fractions_of(per[n][task])
            rows.append([n, task, *fr, len(per[n][task])])
            cells.append(_paper_cell(*fr))
        allo = np.concatenate([np.asarray(per[n][t], int) for t in s.tasks])
        rows.append([n, "all", *fractions_of(allo), int(allo.size)])
        matrix.append([n, *cells])
    allo = np.concatenate([np.asarray(per[n][t], int) for n in names for t in s.tasks])
    rows.append(["all", "all", *fractions_of(allo), int(allo.size)])
    n_test = s.n_demos - s.train_per_task
    how = (f"personal libraries, {s.train_per_task} training and {n_test} test demonstrations per task, "
           f"{s.trials} random splits per subject, full test motions")
    long = Table(["subject", "task", "correct", "wrong", "unknown", "tests"], rows,
                 caption=f"Classification (Table 1): fractions of test motions whose recognized component's "
                         f"majority label is the task (correct), another task (wrong), or no component "
                         f"(unknown); {how}.")
    mat = Table(["subject", *s.tasks], matrix,
                caption=f"Table 1 in the paper's layout: correct (wrong unknown); {how}.")
    return long, mat, allo


def components_table(s: SaladSettings, names: list[str], personal: list[PersonalTrial]) -> Table:
    counts = {n: [r.n_components for r in personal if r.subject == n] for n in names}
    bins = sorted(set(c for v in counts.values() for c in v) | {len(s.tasks)})
    rows = [[n, float(np.mean(counts[n])), *count_distribution(counts[n], bins)] for n in names]
    return Table(["subject", "mean", *[str(b) for b in bins]], rows,
                 caption=f"Components per personal library (Table 2): fraction of the {s.trials} splits "
                         f"ending with each number of components ({s.train_per_task} training demonstrations "
                         f"per task, {len(s.tasks)} tasks).")


def response_tables(s: SaladSettings, personal: list[PersonalTrial]):
    grid = s.grid()
    cat = {k: np.concatenate([getattr(r, k) for r in personal]) for k in ERROR_FIELDS}
    tasks = np.concatenate([np.asarray(r.tasks) for r in personal])
    rows = []
    for i, f in enumerate(grid):
        o = cat["outcome"][:, i]
        ok, ans = o == CORRECT, np.isin(o, [CORRECT, WRONG])
        rows.append([f, *fractions_of(o),
                     _nanstat(cat["rmse"][ok, i], np.mean), _nanstat(cat["rmse"][ok, i], np.median),
                     _nanstat(cat["prior_rmse"][ok, i], np.mean),
                     _nanstat(cat["flange"][ok, i], np.mean), _nanstat(cat["flange"][ok, i], np.median),
                     _nanstat(cat["prior_flange"][ok, i], np.mean),
                     _nanstat(cat["rmse"][ans, i], np.mean), _nanstat(cat["flange"][ans, i], np.mean)])
    resp = Table(
        ["observed fraction", "correct", "wrong", "unknown",
         "joint RMSE mean (rad)", "joint RMSE median (rad)", "prior joint RMSE mean (rad)",
         "flange end error mean (cm)", "flange end error median (cm)", "prior flange end error mean (cm)",
         "answered: joint RMSE mean (rad)", "answered: flange end error mean (cm)"],
        rows,
        caption=(f"Robot response vs the observed fraction of the human motion's path (personal libraries, "
                 f"{cat['outcome'].shape[0]} test motions over all "
                 f"subjects and splits). Errors of the conditioned mean robot trajectory (Eq. 13) against the "
                 f"demonstrated one: joint RMSE over the trajectory, and flange position error at its end "
                 f"(the handover), over correctly recognized motions; 'prior' is the recognized component's "
                 f"unconditioned mean; 'answered' includes wrong decisions."))
    erows, summary = [], {}
    for task in (*s.tasks, "all"):
        m = np.ones(len(tasks), bool) if task == "all" else tasks == task
        p = [float(np.mean(cat["outcome"][m, i] == CORRECT)) if m.any() else float("nan")
             for i in range(len(grid))]
        f0 = earliest_fraction(grid, p, s.target_accuracy)
        i0 = grid.index(f0) if f0 is not None else None
        erows.append([task, "never" if f0 is None else f0, p[i0] if i0 is not None else float("nan"), p[-1],
                      int(m.sum())])
        summary[task] = f0
    pct = f"{100 * s.target_accuracy:g} %"
    early = Table(["task", f"earliest fraction (P(correct) >= {pct})", "P(correct) there", "P(correct) at 1.0",
                   "tests"], erows,
                  caption=(f"Earliest observed fraction of the path from which the decision is right at least "
                           f"{pct} of the time at every larger fraction of the grid {list(grid)} "
                           f"(personal libraries)."))
    arows = []
    for i, f in enumerate(grid):
        o = cat["anticipated"][:, i]
        ph = cat["phase"][:, i]
        known = np.isfinite(ph)
        arows.append([f, *outcome_fractions(o), _nanstat(ph, np.mean),
                      _nanstat(np.abs(ph[known] - f), np.mean) if known.any() else float("nan")])
    anticipation = Table(
        ["true observed fraction", "correct", "wrong", "unknown", "undecided", "estimated phase (mean)",
         "phase error (mean abs)"], arows,
        caption=("Anticipation: the test motions' prefixes recognized WITHOUT being told how much of the motion "
                 "they cover (the library estimates each skill's phase from the path length and the samples); "
                 "correct / wrong / unknown / undecided, and the estimated phase of the best candidate against "
                 "the true fraction of the path (personal libraries)."))
    return resp, early, summary, rows, anticipation
