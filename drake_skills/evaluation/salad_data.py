"""The salad experiment's settings and data: the simulated subjects, generated once and cached.

The simulated salad scenario (:mod:`drake_skills.scenario.salad`), ``n_subjects``
subjects x 5 tasks x ``n_demos`` demonstrations of one subject model, is generated once
(in parallel) and cached as ``.npz`` files under ``cache_dir``, keyed by the subject
model, the data seed and a hash of the files the generator depends on, so a retuned
scene is regenerated.
"""
from __future__ import annotations

import hashlib
import logging
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Sequence

import numpy as np

from drake_skills.data.demonstration import Demonstration
from drake_skills.data.demos import load_calibration, load_npz, save_calibration, save_npz
from drake_skills.data.workspace import Workspace
from drake_skills.evaluation.common import run_trials
from drake_skills.library.config import LibraryConfig
from drake_skills.scenario.salad import SUBJECT_MODELS, TASKS, SubjectData, generate_subject, make_subject
from drake_skills.sim.models import models_dir

log = logging.getLogger(__name__)

#: Files the generated data depends on (their hash keys the cache).
_DATA_SOURCES = ("models/salad/scene.yaml", "models/iiwa7/iiwa7.sdf", "drake_skills/scenario/salad.py",
                 "drake_skills/scenario/salad_subject.py", "drake_skills/scenario/salad_styles.py",
                 "drake_skills/sim/salad_robot.py", "drake_skills/sim/models.py")
_DEFAULT_FRACTIONS = tuple(round(0.1 * i, 1) for i in range(1, 11))


@dataclass
class SaladSettings:
    """Settings of the salad experiment (the paper: 10 subjects, 15 demos per task, 100 trials)."""

    #: Simulated subjects 1..n_subjects (subjects 3 and 7 are sloppy).
    n_subjects: int = 10
    #: How the simulated people move: "styled" or "classic" (drake_skills.scenario.salad).
    subject_model: str = SUBJECT_MODELS[0]
    #: Demonstrations per task and subject.
    n_demos: int = 15
    #: Tasks (subset of drake_skills.scenario.salad.TASKS).
    tasks: tuple[str, ...] = TASKS
    #: Random splits per subject (Tables 1-2, response error), random orders (Fig. 7c, per
    #: task in Table 3) and trials per held-out subject (Fig. 9).
    trials: int = 100
    #: Training demonstrations per task in a split (None: two thirds of n_demos, 10 of 15);
    #: the others are the test set.
    n_train: int | None = None
    #: Demonstrations per task up to which Fig. 7c goes (None: n_demos).
    kl_demos: int | None = None
    #: Monte-Carlo samples per KL estimate.
    kl_samples: int = 2000
    #: EM restarts per fit.
    em_n_init: int = 5
    #: Demonstrations per task and subject in Table 3 (None: min(4, n_demos), as the paper).
    table3_demos: int | None = None
    #: Training demonstrations per task and subject in Fig. 9 (None: min(5, n_demos)).
    transfer_train: int | None = None
    #: Test demonstrations per task of the held-out subject in Fig. 9 (None: min(5, n_demos)).
    transfer_test: int | None = None
    #: Splits per subject whose test motions are also replayed through the controller's decision logic
    #: (the commits table: first commit, path share at it, skill executed; about 0.1 s per motion).
    commit_splits: int = 2
    #: Observed fractions of the test motion's path for the response error.
    fractions: tuple[float, ...] = _DEFAULT_FRACTIONS
    #: P(correct) the earliest-decision fraction must reach.
    target_accuracy: float = 0.95
    #: Fraction of the calibrated z range kept (Sec. 4.2.2: 0.9).
    z_factor: float = 0.9
    #: Seed of the simulated data set.
    data_seed: int = 0
    #: Seed of the splits, orders and Monte-Carlo estimates.
    seed: int = 0
    #: Settings of every library learned (Table 3's third variant also keeps the start position).
    library: LibraryConfig = field(default_factory=LibraryConfig)

    def __post_init__(self):
        self.tasks = tuple(self.tasks)
        self.fractions = tuple(self.fractions)
        self.validate()

    @classmethod
    def quick(cls, seed: int = 0) -> "SaladSettings":
        """A reduced run (3 subjects, 4 demos per task, 2 trials): seconds, for tests."""
        return cls(n_subjects=3, n_demos=4, trials=2, kl_samples=300, em_n_init=1, seed=seed)

    # ----------------------------------------------------------- resolved sizes
    @property
    def train_per_task(self) -> int:
        n = self.n_train if self.n_train is not None else int(round(2 * self.n_demos / 3))
        return int(min(max(n, 1), self.n_demos - 1))

    @property
    def kl_per_task(self) -> int:
        return int(self.kl_demos if self.kl_demos is not None else self.n_demos)

    @property
    def table3_per_task(self) -> int:
        return int(self.table3_demos if self.table3_demos is not None else min(4, self.n_demos))

    @property
    def transfer_train_per_task(self) -> int:
        return int(self.transfer_train if self.transfer_train is not None else min(5, self.n_demos))

    @property
    def transfer_test_per_task(self) -> int:
        return int(self.transfer_test if self.transfer_test is not None else min(5, self.n_demos))

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first inconsistent setting (run by the constructor)."""
        def positive_int(name, v, lo=1):
            if isinstance(v, bool) or int(v) != v or v < lo:
                raise ValueError(f"SaladSettings.{name} must be an integer >= {lo}, got {v!r}")

        positive_int("n_subjects", self.n_subjects, 2)
        positive_int("n_demos", self.n_demos, 2)
        positive_int("trials", self.trials)
        positive_int("kl_samples", self.kl_samples)
        positive_int("em_n_init", self.em_n_init)
        positive_int("commit_splits", self.commit_splits, 0)
        if self.subject_model not in SUBJECT_MODELS:
            raise ValueError(f"SaladSettings.subject_model must be one of {SUBJECT_MODELS}, got {self.subject_model!r}")
        if self.data_seed < 0:
            raise ValueError(f"SaladSettings.data_seed must be non-negative, got {self.data_seed!r}")
        unknown = [t for t in self.tasks if t not in TASKS]
        if unknown or not self.tasks or len(set(self.tasks)) != len(self.tasks):
            raise ValueError(f"SaladSettings.tasks must be distinct tasks of {TASKS}, got {self.tasks!r}")
        if self.n_train is not None and not 1 <= self.n_train < self.n_demos:
            raise ValueError(f"SaladSettings.n_train must be in [1, n_demos - 1 = {self.n_demos - 1}], "
                             f"got {self.n_train!r}")
        for name, v in (("kl_demos", self.kl_per_task), ("table3_demos", self.table3_per_task),
                        ("transfer_train", self.transfer_train_per_task),
                        ("transfer_test", self.transfer_test_per_task)):
            if not 1 <= v <= self.n_demos:
                raise ValueError(f"SaladSettings.{name} must be in [1, n_demos = {self.n_demos}], got {v!r}")
        f = np.asarray(self.fractions, float)
        if f.ndim != 1 or f.size == 0 or not ((f > 0) & (f <= 1)).all():
            raise ValueError(f"SaladSettings.fractions must be in (0, 1], got {self.fractions!r}")
        if not 0 < self.target_accuracy <= 1:
            raise ValueError(f"SaladSettings.target_accuracy must be in (0, 1], got {self.target_accuracy!r}")
        if not 0 < self.z_factor <= 1:
            raise ValueError(f"SaladSettings.z_factor must be in (0, 1], got {self.z_factor!r}")
        if not isinstance(self.library, LibraryConfig):
            raise ValueError(f"SaladSettings.library must be a LibraryConfig, got {type(self.library).__name__}")

    def grid(self) -> tuple[float, ...]:
        """The observed fractions, sorted, with 1.0 (the full motion, Table 1) always included."""
        return tuple(sorted(set(float(x) for x in self.fractions) | {1.0}))

    def resolved(self) -> dict:
        """The settings with every ``None`` replaced by the value used."""
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d.update(n_train=self.train_per_task, kl_demos=self.kl_per_task, table3_demos=self.table3_per_task,
                 transfer_train=self.transfer_train_per_task, transfer_test=self.transfer_test_per_task,
                 tasks=list(self.tasks), fractions=list(self.fractions), library=self.library.dict())
        return d


def data_cache_key() -> str:
    """Hash of the files the generated salad data depends on (scene, robot model, generator)."""
    root = models_dir().parent
    h = hashlib.sha256()
    for rel in _DATA_SOURCES:
        p = root / rel
        h.update(rel.encode())
        h.update(p.read_bytes() if p.is_file() else b"<missing>")
    return h.hexdigest()[:12]


def _subject_dir(cache_root: Path | None, index: int) -> Path | None:
    return None if cache_root is None else cache_root / f"subject{int(index)}"


@dataclass(frozen=True)
class _DataJob:
    """What generating (or reading) one subject needs."""

    n_demos: int
    data_seed: int
    tasks: tuple[str, ...]
    cache_root: Path | None
    subject_model: str


def _load_or_generate(job: _DataJob, index: int) -> SubjectData:
    """SubjectData of subject ``index``: from the cache if complete, else generated (and cached)."""
    n_demos, seed, tasks = job.n_demos, job.data_seed, job.tasks
    sdir = _subject_dir(job.cache_root, index)
    names = [f"{task}_{k:02d}" for task in tasks for k in range(n_demos)]
    if sdir is not None and (sdir / "calibration.npz").is_file() and all(
            (sdir / f"{n}.npz").is_file() for n in names):
        try:
            subject = make_subject(index, seed, job.subject_model)
            cal = load_calibration(sdir / "calibration.npz")
            demos = []
            for n in names:
                d = load_npz(sdir / f"{n}.npz")
                demos.append(Demonstration(t=d.t, human=d.human, robot=d.robot, task=d.task, subject=d.subject,
                                           name=f"{subject.name}/{n}"))
            return SubjectData(subject=subject, calibration=[cal["xy"], cal["zy"]], demos=demos)
        except (ValueError, KeyError) as exc:  # a damaged cache is regenerated
            log.warning("regenerating subject %d: cached data unusable (%s)", index, exc)
    data = generate_subject(index, n_demos, seed, tasks, job.subject_model)
    if sdir is not None:
        sdir.mkdir(parents=True, exist_ok=True)
        save_calibration(sdir / "calibration.npz", {"xy": data.calibration[0], "zy": data.calibration[1]})
        for d, n in zip(data.demos, names):
            save_npz(d, sdir / f"{n}.npz")
    return data


def load_salad_data(settings: SaladSettings, *, workers: int = 1, progress: bool = False,
                    cache_dir: str | Path | None = None) -> list[SubjectData]:
    """The subjects' calibration and demonstrations (``SubjectData``), generated or from the cache.

    Parameters
    ----------
    settings : SaladSettings
        ``n_subjects``, ``n_demos``, ``tasks``, ``subject_model`` and ``data_seed`` are used.
    workers : int
        Processes generating subjects in parallel.
    cache_dir : str or Path, optional
        Demonstrations are cached under
        ``cache_dir/salad-<hash>/<subject_model>/seed<data_seed>/subject<i>/<task>_<nn>.npz`` (no pickle).
    """
    root = None
    if cache_dir is not None:
        root = (Path(cache_dir) / f"salad-{data_cache_key()}" / settings.subject_model
                / f"seed{int(settings.data_seed)}")
    job = _DataJob(int(settings.n_demos), int(settings.data_seed), tuple(settings.tasks), root,
                   settings.subject_model)
    return run_trials(_load_or_generate, range(1, int(settings.n_subjects) + 1), job, workers=workers,
                      desc="salad: data", progress=progress)


def shared_workspace(subjects: Sequence[SubjectData], z_factor: float | None = 0.9) -> Workspace:
    """One workspace for everybody: the bounding box of all subjects' calibration motions."""
    return Workspace.from_calibration([m for s in subjects for m in s.calibration], z_factor=z_factor)


@dataclass(frozen=True, eq=False)
class SaladContext:
    """What every trial of the salad experiment reads (sent once to each worker)."""

    settings: SaladSettings
    #: The subjects' data, in subject order.
    subjects: tuple[SubjectData, ...]
    #: Each subject's personal workspace (Eq. 14, ``settings.z_factor``).
    workspaces: tuple[Workspace, ...]
    #: The bounding box of all subjects' calibrations.
    shared: Workspace

    @classmethod
    def of(cls, settings: SaladSettings, subjects: Sequence[SubjectData]) -> "SaladContext":
        return cls(settings, tuple(subjects), tuple(d.workspace(z_factor=settings.z_factor) for d in subjects),
                   shared_workspace(subjects, settings.z_factor))
