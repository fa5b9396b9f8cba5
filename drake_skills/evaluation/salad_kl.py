"""KL to the labeled baseline (Fig. 7c) on the salad data.

Per trial a subject (trial ``i`` takes subject ``i mod n_subjects``) and a random order of
its demonstrations; for ``k = 1 .. kl_demos`` demonstrations per task (nested streams as
in the letters experiment) the incremental library, the labeled ML baseline
(:func:`~drake_skills.library.batch.labeled_ml`) and batch EM with the true K
(:func:`~drake_skills.library.batch.batch_em`) in the library's gating weight space;
``KL(baseline || model)`` by Monte Carlo.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_skills.evaluation.common import Table, nested_streams, stream_rng
from drake_skills.evaluation.salad_data import SaladContext, SaladSettings
from drake_skills.library.batch import batch_em, labeled_ml
from drake_skills.library.incremental import SkillLibrary
from drake_skills.promp.gaussian import mc_kl_mixtures

#: Random stream of the orders (second seed word).
STREAM_KL = 22


@dataclass(frozen=True, eq=False)
class KLTrial:
    """One order of one subject; arrays over k = 1..kl_demos demonstrations per task."""

    subject: str
    kl_incremental: np.ndarray
    kl_em: np.ndarray
    n_components: np.ndarray


def kl_trial(ctx: SaladContext, index: int) -> KLTrial:
    """One random order of one subject's demonstrations: KL to the labeled baseline per k (Fig. 7c)."""
    s = ctx.settings
    data = ctx.subjects[index % len(ctx.subjects)]
    ws = data.workspace(z_factor=s.z_factor)
    rng = stream_rng(s.seed, STREAM_KL, index)
    demos = [d for d in data.demos if d.task in s.tasks]
    tasks = [d.task for d in demos]
    perm = rng.permutation(len(demos))
    kl_inc, kl_em, n_comp = [], [], []
    for stream in nested_streams(tasks, perm, s.kl_per_task):
        lib = SkillLibrary(s.library)
        for j in stream:
            lib.partial_fit(demos[j], workspace=ws)
        h = lib.n_human
        W = np.stack([lib.encode(demos[j], ws)[:h] for j in stream])
        base = labeled_ml(W, [tasks[j] for j in stream]).as_tuple()
        em = batch_em(W, len(s.tasks), random_state=int(rng.integers(2 ** 31 - 1)), n_init=s.em_n_init)
        kl_seed = int(rng.integers(2 ** 31 - 1))
        kl_inc.append(mc_kl_mixtures(base, lib.as_mixture("gating"), s.kl_samples, random_state=kl_seed))
        kl_em.append(mc_kl_mixtures(base, em.as_tuple(), s.kl_samples, random_state=kl_seed))
        n_comp.append(lib.n_components)
    return KLTrial(data.subject.name, np.array(kl_inc), np.array(kl_em), np.array(n_comp))


def kl_table(s: SaladSettings, kl: list[KLTrial]):
    inc = np.stack([r.kl_incremental for r in kl])
    em = np.stack([r.kl_em for r in kl])
    nc = np.stack([r.n_components for r in kl])
    ks = np.arange(1, s.kl_per_task + 1)
    K = len(s.tasks)
    rows = [[int(k), inc[:, i].mean(), inc[:, i].std(), np.median(inc[:, i]), np.percentile(inc[:, i], 10),
             np.percentile(inc[:, i], 90), em[:, i].mean(), em[:, i].std(), np.median(em[:, i]),
             nc[:, i].mean(), float(np.mean(nc[:, i] == K))] for i, k in enumerate(ks)]
    t = Table(["demos per task", "KL inc mean", "KL inc std", "KL inc median", "KL inc p10", "KL inc p90",
               "KL EM mean", "KL EM std", "KL EM median", "components mean", f"P(K = {K})"], rows,
              caption=(f"KL(labeled ML || model) in nats (Monte Carlo, {s.kl_samples} samples from the baseline) "
                       f"in the library's gating (human weight) space, personal workspaces; {s.trials} random "
                       f"orders, trial i on subject (i mod {s.n_subjects}) + 1. Batch EM is given the true "
                       f"K = {K} (Fig. 7c)."))
    return t, ks, inc, em
