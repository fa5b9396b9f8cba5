"""The salad experiment of Sec. 4.2 (Tables 1-3, Figs. 7c and 9) and the robot's response error.

Every library is a :class:`~drake_skills.library.incremental.SkillLibrary` with
``SaladSettings.library`` (default: the default :class:`LibraryConfig`), scored against
the task labels as in :mod:`drake_skills.evaluation.labeled`. The experiments, one
module each, around typed trial records:

1. personal libraries and the robot response (:mod:`~drake_skills.evaluation.salad_personal`,
   Tables 1 and 2, response error, earliest decision);
2. KL to the labeled baseline (:mod:`~drake_skills.evaluation.salad_kl`, Fig. 7c);
3. components per task across subjects and leave one subject out
   (:mod:`~drake_skills.evaluation.salad_transfer`, Table 3 and Fig. 9).

Settings and data (generated once, cached) are in :mod:`~drake_skills.evaluation.salad_data`,
figures in :mod:`~drake_skills.evaluation.salad_figures`. Each experiment is a set of
independent trials run by :func:`~drake_skills.evaluation.common.run_trials`; trial
randomness comes from ``SeedSequence([seed, stream, ...ids])`` only, so the results do not
depend on the number of workers.
"""
from __future__ import annotations

import importlib
import time
from pathlib import Path

import numpy as np

from drake_skills.evaluation.common import EvalReport, fig_kl_vs_samples, run_trials
from drake_skills.evaluation.labeled import fractions_of
from drake_skills.evaluation.salad_data import SaladContext, SaladSettings, load_salad_data
from drake_skills.evaluation.salad_figures import fig_classification, fig_response, fig_task_components, fig_transfer
from drake_skills.evaluation.salad_kl import kl_table, kl_trial
from drake_skills.evaluation.salad_personal import (PersonalContext, classification_tables, commits_table,
                                                    components_table, personal_trial, response_tables)
from drake_skills.evaluation.salad_transfer import (task_components_tables, task_components_trial, transfer_table,
                                                    transfer_trial)


def evaluate_salad(settings: SaladSettings | None = None, *, workers: int = 1, progress: bool = True,
                   cache_dir: str | Path | None = None, figures: bool = True) -> EvalReport:
    """Run the salad experiment and return its tables and figures.

    Parameters
    ----------
    settings : SaladSettings
    workers : int
        Processes for data generation and the trials (results do not depend on it).
    progress : bool
        tqdm progress bars on stderr.
    cache_dir : str or Path, optional
        Where generated demonstrations are cached (see :func:`load_salad_data`).
    figures : bool
        Also draw the figures.

    Returns
    -------
    EvalReport
        Tables ``classification`` and ``classification_matrix`` (Table 1),
        ``components_per_subject`` (Table 2), ``kl_vs_demos`` (Fig. 7c),
        ``components_per_task`` and ``components_per_task_matrix`` (Table 3),
        ``transfer`` (Fig. 9), ``response_vs_fraction`` and ``earliest_decision``;
        figures ``classification``, ``kl_vs_demos``, ``components_per_task``,
        ``transfer``, ``response_vs_fraction``.
    """
    s = settings if settings is not None else SaladSettings()
    if not isinstance(s, SaladSettings):
        raise ValueError(f"settings must be SaladSettings, got {type(s).__name__}")
    if workers > 1:  # batch EM imports scikit-learn lazily: once here, before the workers fork
        importlib.import_module("sklearn.mixture")
    seconds: dict[str, float] = {}
    t0 = time.perf_counter()
    subjects = load_salad_data(s, workers=workers, progress=progress, cache_dir=cache_dir)
    seconds["data"] = time.perf_counter() - t0
    names = [d.subject.name for d in subjects]
    ctx = SaladContext.of(s, subjects)

    def timed(key, fn, items, desc, context=ctx):
        t = time.perf_counter()
        out = run_trials(fn, items, context, workers=workers, desc=f"salad: {desc}", progress=progress)
        seconds[key] = time.perf_counter() - t
        return out

    personal = timed("personal", personal_trial, [(p, k) for p in range(len(subjects)) for k in range(s.trials)],
                     "personal libraries", PersonalContext(ctx))
    kl = timed("kl", kl_trial, range(s.trials), "KL vs demos")
    tc = timed("components_per_task", task_components_trial, [(t, k) for t in s.tasks for k in range(s.trials)],
               "components per task")
    tr = timed("transfer", transfer_trial, [(p, k) for p in range(len(subjects)) for k in range(s.trials)],
               "leave one subject out")

    cls_long, cls_mat, all_personal = classification_tables(s, names, personal)
    comp = components_table(s, names, personal)
    resp, early, early_summary, resp_rows, anticipation = response_tables(s, personal)
    commits, commits_summary = commits_table(s, personal)
    kl_t, ks, inc, em = kl_table(s, kl)
    tc_long, tc_mat, tc_summary = task_components_tables(s, tc)
    tr_t, tr_acc = transfer_table(s, names, tr)

    rep = EvalReport(f"Salad (Sec. 4.2), {s.subject_model} subjects", {
        "classification": cls_long, "classification_matrix": cls_mat, "components_per_subject": comp,
        "kl_vs_demos": kl_t, "components_per_task": tc_long, "components_per_task_matrix": tc_mat,
        "transfer": tr_t, "response_vs_fraction": resp, "earliest_decision": early,
        "anticipation": anticipation, "commits": commits})
    full = s.grid().index(1.0)
    rep.summary = {
        "settings": s.resolved(),
        "subjects": names,
        "demonstrations": int(sum(len(d.demos) for d in subjects)),
        "personal_correct_wrong_unknown": fractions_of(all_personal),
        "personal_components_mean": {n: float(np.mean([r.n_components for r in personal if r.subject == n]))
                                     for n in names},
        "kl_incremental_mean": inc.mean(axis=0).tolist(),
        "kl_em_mean": em.mean(axis=0).tolist(),
        "components_per_task_mean": tc_summary,
        "transfer_correct_wrong_unknown": tr_acc,
        "earliest_decision_fraction": early_summary,
        "anticipation": {str(r[0]): dict(zip(anticipation.columns[1:], r[1:])) for r in anticipation.rows},
        "response_at_full_observation": dict(zip(resp.columns, resp_rows[full])),
        "commits": commits_summary,
        "seconds": seconds,
    }
    if figures:
        t = time.perf_counter()
        rep.figures = {"classification": fig_classification(s, names, cls_long),
                       "kl_vs_demos": fig_kl_vs_samples(ks, inc, em, xlabel="demonstrations per task",
                                                        title="Salad: KL to the labeled baseline (Fig. 7c)"),
                       "components_per_task": fig_task_components(s, tc),
                       "transfer": fig_transfer(s, names, tr_t),
                       "response_vs_fraction": fig_response(s, resp_rows)}
        seconds["figures"] = time.perf_counter() - t
    seconds["total"] = time.perf_counter() - t0
    return rep
