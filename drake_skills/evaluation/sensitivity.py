"""How the defaults hold up: the learned scale's prior and the test quantiles, on letters and salad at once.

``LibraryConfig`` promises one setting for LASA letters and the simulated salad
scenario. This experiment shows how much room that promise has. For each
named configuration (default and a few alternatives):

* **letters**: all 35 demonstrations (5 shapes x 7) folded in random order;
  the fraction of orders that end with exactly one component per shape
  (components labeled by the majority of the demonstrations they absorbed);
* **salad**: a personal library per subject from 10 random demonstrations per
  task, tested on the other 5 (as Table 1): correct / wrong / unknown, and the
  mean number of components.

The alternatives move each setting that remains once the scale is learned
(:mod:`drake_skills.library.scale`): the prior's scale and floor, the novelty and
merge quantiles, and the raw arc length of the paper (``resample_tolerance`` 0).
"""
from __future__ import annotations

from collections import Counter
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from drake_skills.data.demonstration import Demonstration
from drake_skills.data.lasa import DEFAULT_LETTERS, lasa_workspace, load_lasa
from drake_skills.data.workspace import Workspace
from drake_skills.evaluation.common import EvalReport, Table, run_trials, stream_rng
from drake_skills.evaluation.labeled import CORRECT, WRONG, LabeledLibrary
from drake_skills.evaluation.salad_data import SaladSettings, load_salad_data
from drake_skills.library.config import LibraryConfig
from drake_skills.scenario.salad import SubjectData

STREAM_LETTERS, STREAM_SALAD = 31, 32

#: The configurations compared: name -> LibraryConfig overrides.
CONFIGS: dict[str, dict] = {
    "default": {},
    "raw arc length (tolerance 0)": {"resample_tolerance": 0.0},
    "prior scale 0.2": {"prior_scale": 0.2},
    "prior scale 0.4": {"prior_scale": 0.4},
    "prior floor 0.2": {"prior_floor": 0.2},
    "prior floor 0.8": {"prior_floor": 0.8},
    "novelty and merge 0.9999": {"novelty_quantile": 0.9999, "merge_quantile": 0.9999, "split_quantile": 0.99999},
}


@dataclass
class SensitivitySettings:
    """Settings of the sensitivity experiment."""

    #: name -> LibraryConfig overrides.
    configs: dict = field(default_factory=lambda: dict(CONFIGS))
    #: Random orders of the letters per configuration.
    letter_orders: int = 100
    #: Random train/test splits per subject and configuration.
    salad_splits: int = 10
    #: Simulated subjects.
    n_subjects: int = 10
    #: Demonstrations per task and subject (10 train, the rest test).
    n_demos: int = 15
    #: Training demonstrations per task.
    n_train: int = 10
    #: Seed of the simulated data.
    data_seed: int = 0
    #: Experiment seed.
    seed: int = 0
    #: The configuration the overrides apply to ("default" is this one).
    library: LibraryConfig = field(default_factory=LibraryConfig)

    def __post_init__(self):
        if not isinstance(self.library, LibraryConfig):
            raise ValueError(f"SensitivitySettings.library must be a LibraryConfig, got {type(self.library).__name__}")
        if not self.configs:
            raise ValueError("SensitivitySettings.configs: no configurations to compare")
        for overrides in self.configs.values():
            self.config(overrides)  # bad overrides fail here, before any work
        for name in ("letter_orders", "salad_splits", "n_subjects", "n_demos"):
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or v < 1:
                raise ValueError(f"SensitivitySettings.{name} must be an integer >= 1, got {v!r}")
        if not 1 <= self.n_train < self.n_demos:
            raise ValueError(f"SensitivitySettings.n_train must be in [1, n_demos), got {self.n_train} of "
                             f"{self.n_demos}")

    def config(self, overrides: dict) -> LibraryConfig:
        """``library`` with ``overrides``; an unknown field raises ``ValueError`` naming it."""
        d = self.library.dict()
        d.update(overrides)
        return LibraryConfig.from_dict(d)

    @classmethod
    def quick(cls, seed: int = 0) -> "SensitivitySettings":
        """A reduced run (what the tests use)."""
        return cls(configs={k: CONFIGS[k] for k in list(CONFIGS)[:2]}, letter_orders=3,
                   salad_splits=1, n_subjects=2, n_demos=4, n_train=3, seed=seed)


@dataclass(frozen=True, eq=False)
class SensitivityContext:
    """What every trial reads: the settings, the letters and their workspace, the salad subjects."""

    settings: SensitivitySettings
    letters: tuple[Demonstration, ...]
    letters_ws: Workspace
    shapes: tuple[str, ...]
    salad: tuple[SubjectData, ...]


@dataclass(frozen=True)
class SplitResult:
    """One salad split: fractions of the test motions and the library's size."""

    correct: float
    wrong: float
    unknown: float
    components: int


def letters_order(ctx: SensitivityContext, item: tuple) -> bool:
    """One random order of all letters: does it end with one component per shape?"""
    name, order = item
    demos, ws = ctx.letters, ctx.letters_ws
    lab = LabeledLibrary(ctx.settings.config(ctx.settings.configs[name]))
    rng = stream_rng(ctx.settings.seed, STREAM_LETTERS, order)
    for i in rng.permutation(len(demos)):
        lab.teach(demos[i], ws)
    labels = [lab.label_of(c.id) for c in lab.library.components]
    return len(labels) == len(ctx.shapes) and set(labels) == set(ctx.shapes)


def salad_split(ctx: SensitivityContext, item: tuple) -> SplitResult:
    """One train/test split of one subject: outcome counts and the number of components."""
    name, subject, split = item
    s = ctx.settings
    data = ctx.salad[subject - 1]
    ws = data.workspace()
    rng = stream_rng(s.seed, STREAM_SALAD, subject, split)
    train, test = [], []
    for task in sorted({d.task for d in data.demos}):
        ds = data.by_task(task)
        p = rng.permutation(len(ds))
        train += [ds[i] for i in p[:s.n_train]]
        test += [ds[i] for i in p[s.n_train:]]
    lab = LabeledLibrary(s.config(s.configs[name]))
    for i in rng.permutation(len(train)):
        lab.teach(train[i], ws)
    counts = Counter(lab.classify(d.human, d.task, ws)[0] for d in test)
    n = max(len(test), 1)
    return SplitResult(counts[CORRECT] / n, counts[WRONG] / n, 1.0 - (counts[CORRECT] + counts[WRONG]) / n,
                       lab.library.n_components)


def evaluate_sensitivity(settings: SensitivitySettings | None = None, *, workers: int = 1, progress: bool = True,
                         cache_dir: str | Path | None = None) -> EvalReport:
    """Run the experiment; one table row per configuration."""
    s = settings if settings is not None else SensitivitySettings()
    letters = load_lasa(DEFAULT_LETTERS)
    salad = load_salad_data(SaladSettings(n_subjects=s.n_subjects, n_demos=s.n_demos, data_seed=s.data_seed),
                            workers=workers, progress=progress, cache_dir=cache_dir)
    ctx = SensitivityContext(s, tuple(letters), lasa_workspace(letters), tuple(sorted({d.task for d in letters})),
                             tuple(salad))
    names = list(s.configs)
    l_items = [(n, o) for n in names for o in range(s.letter_orders)]
    l_res = run_trials(letters_order, l_items, ctx, workers=workers, desc="sensitivity: letters",
                       progress=progress)
    s_items = [(n, subj, k) for n in names for subj in range(1, s.n_subjects + 1) for k in range(s.salad_splits)]
    s_res = run_trials(salad_split, s_items, ctx, workers=workers, desc="sensitivity: salad", progress=progress)
    rows, summary = [], {}
    for name in names:
        ok = [r for (n, _), r in zip(l_items, l_res) if n == name]
        sr = [r for (n, _, _), r in zip(s_items, s_res) if n == name]
        worst = min((float(np.mean([r.correct for (n, subj, _), r in zip(s_items, s_res)
                                    if n == name and subj == j])), j) for j in range(1, s.n_subjects + 1))
        row = {
            "letters_one_per_shape": float(np.mean(ok)),
            "salad_correct": float(np.mean([r.correct for r in sr])),
            "salad_wrong": float(np.mean([r.wrong for r in sr])),
            "salad_unknown": float(np.mean([r.unknown for r in sr])),
            "salad_worst_subject": worst[1], "salad_worst_subject_correct": worst[0],
            "salad_components": float(np.mean([r.components for r in sr])),
        }
        summary[name] = {"overrides": s.configs[name], **row}
        rows.append([name, row["letters_one_per_shape"], row["salad_correct"], row["salad_wrong"],
                     row["salad_unknown"], f"{worst[1]} ({worst[0]:.2f})", row["salad_components"]])
    table = Table(
        ["configuration", "letters: one component per shape", "salad correct", "wrong", "unknown",
         "worst subject (correct)", "salad components"], rows,
        caption=f"Letters: fraction of {s.letter_orders} random orders of all {len(letters)} demonstrations "
                f"that end with one component per shape. Salad: personal libraries of {s.n_subjects} subjects, "
                f"{s.n_train} training demonstrations per task, tested on {s.n_demos - s.n_train}, "
                f"{s.salad_splits} splits per subject. Same data and orders for every configuration.")
    return EvalReport("Sensitivity of the defaults", {"sensitivity": table}, {},
                      {"configs": summary, "settings": asdict(s) | {"library": s.library.dict()}})
