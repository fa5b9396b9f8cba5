"""The salad experiment of Sec. 4.2 (Tables 1-3, Figs. 7c and 9) and the robot's response error.

Data: the simulated salad scenario (:mod:`drake_skills.scenario.salad`), ``n_subjects``
subjects x 5 tasks x ``n_demos`` demonstrations, generated once (in parallel) and
cached as ``.npz`` files under ``cache_dir`` (keyed by the data seed and a hash of the
files the generator depends on, so a retuned scene is regenerated). Every library is a
:class:`SkillLibrary` with the default :class:`LibraryConfig`.

A component's task label is the majority task of the training demonstrations it
absorbed: a created component gets one vote for the demonstration's task, every
component the update touched (``Update.updated``) one vote, a merge adds the absorbed
component's votes to the kept one, a deletion drops them
(``drake_skills.library.labels.TaskVotes``, shared with ``CollaborationSim.teach``).
A test motion is *correct* when the recognized component's label is its task,
*wrong* when it is another task, *unknown* when no component explains it.

Experiments (each a set of independent trials run by :func:`run_trials`; trial
randomness comes from ``SeedSequence([seed, stream, ...ids])`` only, so the results do
not depend on the number of workers):

1. Personal libraries (Tables 1 and 2). For every subject and every one of ``trials``
   random splits: per task, ``n_train`` demonstrations for training and the rest for
   testing; the training demonstrations (all tasks) are folded into a fresh library in
   a random order, in the subject's own workspace. Table 1: correct / wrong / unknown
   fractions of the full test motions per subject and task. Table 2: distribution of
   the number of components per subject.
2. Robot response (beyond the paper, same libraries and test motions). For every
   observed fraction ``f`` of the test motion's *path length* (the meaning of
   ``observed_fraction`` in the library): recognize the prefix, and if a component is
   chosen condition its Interaction ProMP on the prefix (Eq. 13). Error of the
   conditioned mean robot trajectory (over the component's phase) against the
   demonstrated one (resampled uniformly in time): joint RMSE in rad, and the distance
   of the flange (forward kinematics of the IIWA7 at the scene's base) at the last
   step, i.e. at the handover, in cm. The unconditioned component mean ("prior") is
   scored the same way. The earliest fraction from which P(correct) stays >= 95 %.
3. KL to the labeled baseline (Fig. 7c). Per trial a subject (trial ``i`` takes subject
   ``i mod n_subjects``) and a random order of its demonstrations; for ``k = 1 ..
   kl_demos`` demonstrations per task (nested streams as in the letters experiment)
   the incremental library, the labeled ML baseline (:func:`labeled_ml`) and batch EM
   with the true K (:func:`batch_em`) in the library's gating weight space;
   ``KL(baseline || model)`` by Monte Carlo.
4. Components per task across subjects (Table 3). Per task and trial, a library is
   learned from ``table3_demos`` random demonstrations of that task of every subject,
   in a random order, once with each subject's personal workspace (Eq. 14, "with") and
   once with one shared workspace, the bounding box of all subjects' calibrations
   ("without"); both subtract the start position (Eq. 14). A third library also keeps
   the start position (shared workspace, ``subtract_start=False``): the paper's
   "without transformation" of Fig. 8.
5. Leave one subject out (Fig. 9). Per held-out subject and trial: a library learned
   from ``transfer_train`` random demonstrations per task of every other subject in a
   random order, tested on ``transfer_test`` random demonstrations per task of the
   held-out subject; with personal workspaces (the held-out subject's own for its
   tests) and with the shared workspace.
"""
from __future__ import annotations

import hashlib
import logging
import time
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from drake_skills.scenario.salad import TASKS
from drake_skills.evaluation.common import EvalReport, Table, count_distribution, fig_kl_vs_samples, run_trials

log = logging.getLogger(__name__)

#: Random streams of the experiments (second seed word).
STREAM_PERSONAL, STREAM_KL, STREAM_TASKS, STREAM_TRANSFER = 21, 22, 23, 24
#: Outcomes of one classification, in table order.
OUTCOMES = ("correct", "wrong", "unknown")
CORRECT, WRONG, UNKNOWN = 0, 1, 2
#: Bins of Table 3 (components per task): <= 1, 2, 3, 4, 5, >= 6.
TASK_COUNT_BINS = ((0, 1), 2, 3, 4, 5, (6, None))
TASK_COUNT_LABELS = ("<=1", "2", "3", "4", "5", ">=6")
#: Libraries of Table 3: key in the trial's result -> row label.
TABLE3_VARIANTS = {"with": "personal workspace", "without": "shared workspace",
                   "raw": "shared workspace, no start offset"}
#: Files the generated data depends on (their hash keys the cache).
_DATA_SOURCES = ("models/salad/scene.yaml", "models/iiwa7/iiwa7.sdf", "drake_skills/scenario/salad.py",
                 "drake_skills/sim/salad_robot.py", "drake_skills/sim/models.py")
_DEFAULT_FRACTIONS = tuple(round(0.1 * i, 1) for i in range(1, 11))


@dataclass
class SaladSettings:
    """Settings of the salad experiment (the paper: 10 subjects, 15 demos per task, 100 trials)."""

    #: Simulated subjects 1..n_subjects (subjects 3 and 7 are sloppy).
    n_subjects: int = 10
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
        """Raise ``ValueError`` naming the first inconsistent setting."""
        def positive_int(name, v, lo=1):
            if isinstance(v, bool) or int(v) != v or v < lo:
                raise ValueError(f"SaladSettings.{name} must be an integer >= {lo}, got {v!r}")

        positive_int("n_subjects", self.n_subjects, 2)
        positive_int("n_demos", self.n_demos, 2)
        positive_int("trials", self.trials)
        positive_int("kl_samples", self.kl_samples)
        positive_int("em_n_init", self.em_n_init)
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

    def grid(self) -> tuple[float, ...]:
        """The observed fractions, sorted, with 1.0 (the full motion, Table 1) always included."""
        return tuple(sorted(set(float(x) for x in self.fractions) | {1.0}))

    def resolved(self) -> dict:
        """The settings with every ``None`` replaced by the value used."""
        d = asdict(self)
        d.update(n_train=self.train_per_task, kl_demos=self.kl_per_task, table3_demos=self.table3_per_task,
                 transfer_train=self.transfer_train_per_task, transfer_test=self.transfer_test_per_task,
                 tasks=list(self.tasks), fractions=list(self.fractions))
        return d


def _rng(seed: int, stream: int, *ids: int) -> np.random.Generator:
    """The generator of one trial, a function of ``(seed, stream, ids)`` only."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(stream), *map(int, ids)]))


# --------------------------------------------------------------------------- data
def data_cache_key() -> str:
    """Hash of the files the generated salad data depends on (scene, robot model, generator)."""
    from drake_skills.sim.models import models_dir

    root = models_dir().parent
    h = hashlib.sha256()
    for rel in _DATA_SOURCES:
        p = root / rel
        h.update(rel.encode())
        h.update(p.read_bytes() if p.is_file() else b"<missing>")
    return h.hexdigest()[:12]


def _subject_dir(cache_root: Path | None, index: int) -> Path | None:
    return None if cache_root is None else cache_root / f"subject{int(index)}"


def _load_or_generate(ctx: dict, index: int):
    """SubjectData of subject ``index``: from the cache if complete, else generated (and cached)."""
    from drake_skills.data.demonstration import Demonstration
    from drake_skills.data.demos import load_calibration, load_npz, save_calibration, save_npz
    from drake_skills.scenario.salad import SubjectData, generate_subject, make_subject

    n_demos, seed, tasks = ctx["n_demos"], ctx["data_seed"], ctx["tasks"]
    sdir = _subject_dir(ctx["cache_root"], index)
    names = [f"{task}_{k:02d}" for task in tasks for k in range(n_demos)]
    if sdir is not None and (sdir / "calibration.npz").is_file() and all(
            (sdir / f"{n}.npz").is_file() for n in names):
        try:
            subject = make_subject(index, seed)
            cal = load_calibration(sdir / "calibration.npz")
            demos = []
            for n in names:
                d = load_npz(sdir / f"{n}.npz")
                demos.append(Demonstration(t=d.t, human=d.human, robot=d.robot, task=d.task, subject=d.subject,
                                           name=f"{subject.name}/{n}"))
            return SubjectData(subject=subject, calibration=[cal["xy"], cal["zy"]], demos=demos)
        except (ValueError, KeyError) as exc:  # a damaged cache is regenerated
            log.warning("regenerating subject %d: cached data unusable (%s)", index, exc)
    data = generate_subject(index, n_demos, seed, tasks)
    if sdir is not None:
        sdir.mkdir(parents=True, exist_ok=True)
        save_calibration(sdir / "calibration.npz", {"xy": data.calibration[0], "zy": data.calibration[1]})
        for d, n in zip(data.demos, names):
            save_npz(d, sdir / f"{n}.npz")
    return data


def load_salad_data(settings: SaladSettings, *, workers: int = 1, progress: bool = False,
                    cache_dir: str | Path | None = None) -> list:
    """The subjects' calibration and demonstrations (``SubjectData``), generated or from the cache.

    Parameters
    ----------
    settings : SaladSettings
        ``n_subjects``, ``n_demos``, ``tasks`` and ``data_seed`` are used.
    workers : int
        Processes generating subjects in parallel.
    cache_dir : str or Path, optional
        Demonstrations are cached under
        ``cache_dir/salad-<hash>/seed<data_seed>/subject<i>/<task>_<nn>.npz`` (no pickle).
    """
    root = None
    if cache_dir is not None:
        root = Path(cache_dir) / f"salad-{data_cache_key()}" / f"seed{int(settings.data_seed)}"
    ctx = {"n_demos": int(settings.n_demos), "data_seed": int(settings.data_seed), "tasks": tuple(settings.tasks),
           "cache_root": root}
    return run_trials(_load_or_generate, range(1, int(settings.n_subjects) + 1), ctx, workers=workers,
                      desc="salad: data", progress=progress)


def shared_workspace(subjects: Sequence, z_factor: float = 0.9):
    """One workspace for everybody: the bounding box of all subjects' calibration motions."""
    from drake_skills.data.workspace import Workspace

    return Workspace.from_calibration([m for s in subjects for m in s.calibration], z_factor=z_factor)


def observed_prefix(human: np.ndarray, fraction: float, workspace=None, tolerance: float = 0.0) -> np.ndarray:
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
    from drake_skills.promp.preprocessing import vertex_indices

    y = workspace.normalize(human, subtract_start=False) if workspace is not None else human
    idx = vertex_indices(y, tolerance)
    human, y = human[idx], y[idx]
    if human.shape[0] < 2:
        raise ValueError("the motion does not move beyond the tolerance: no prefix to observe")
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(y, axis=0), axis=1))])
    target = f * s[-1]
    i = int(np.searchsorted(s, target, side="right"))  # s[i-1] <= target < s[i]
    i = min(max(i, 1), len(s) - 1)
    a = (target - s[i - 1]) / max(s[i] - s[i - 1], 1e-300)
    cut = human[i - 1] + a * (human[i] - human[i - 1])
    prefix = np.vstack([human[:i], cut[None]])
    return prefix if prefix.shape[0] >= 2 else human[:2]


# --------------------------------------------------------------------------- labeled library
class LabeledLibrary:
    """A :class:`SkillLibrary` that keeps the task votes of its components (as ``CollaborationSim.teach``)."""

    def __init__(self, config=None):
        from drake_skills import SkillLibrary
        from drake_skills.library.labels import TaskVotes

        self.library = SkillLibrary(config)
        self._votes = TaskVotes()

    @property
    def votes(self) -> dict[int, Counter]:
        """Component id -> task counts of the demonstrations it absorbed."""
        return self._votes.votes

    def teach(self, demo, workspace=None):
        """Fold ``demo`` in and update the votes from the returned ``Update``."""
        update = self.library.partial_fit(demo, workspace=workspace)
        self._votes.record(update, demo.task)
        return update

    def label_of(self, component: int | None) -> str | None:
        """The majority task of the demonstrations ``component`` absorbed (None if none)."""
        return self._votes.label_of(component)

    def outcome(self, component: int | None, task: str) -> int:
        """CORRECT, WRONG or UNKNOWN for a recognized component and the true task."""
        if component is None:
            return UNKNOWN
        return CORRECT if self.label_of(component) == task else WRONG

    def classify(self, human, task: str, workspace=None, observed_fraction: float = 1.0) -> tuple[int, int | None]:
        rec = self.library.recognize(human, observed_fraction=observed_fraction, workspace=workspace)
        return self.outcome(rec.component, task), rec.component


# --------------------------------------------------------------------------- forward kinematics
_FK = None


def flange_position(q: np.ndarray) -> np.ndarray:
    """p_WE (3,) of the IIWA7 flange at joints q (7,), the robot at its base of ``scene.yaml``."""
    global _FK
    if _FK is None:
        from drake_skills.sim.models import FLANGE_FRAME, make_iiwa7_plant

        plant = make_iiwa7_plant()
        _FK = (plant, plant.CreateDefaultContext(), plant.GetFrameByName(FLANGE_FRAME))
    plant, context, frame = _FK
    plant.SetPositions(context, np.asarray(q, float))
    return np.array(plant.CalcRelativeTransform(context, plant.world_frame(), frame).translation())


def _robot_mean(lib, component: int, n: int) -> np.ndarray:
    """The component's unconditioned mean robot trajectory (n, D_r)."""
    cfg = lib.config
    m = np.asarray(lib.component(component).mean)[lib.n_human:]
    return cfg.basis_robot.phi_uniform(n) @ m.reshape(lib.dim_robot_, -1).T


def response_errors(lab: LabeledLibrary, demo, workspace, fractions: Sequence[float]) -> dict:
    """Decision and robot response error of one test motion at each observed fraction.

    Returns
    -------
    dict of arrays, shape (len(fractions),): ``outcome`` (CORRECT/WRONG/UNKNOWN),
    ``rmse`` (joint RMSE, rad), ``flange`` (end flange error, cm), ``prior_rmse``,
    ``prior_flange`` (the unconditioned component mean); NaN where unknown.
    """
    from drake_skills.promp.preprocessing import resample_in_time

    lib = lab.library
    nf = len(fractions)
    out = {"outcome": np.full(nf, UNKNOWN, dtype=int)}
    for k in ("rmse", "flange", "prior_rmse", "prior_flange"):
        out[k] = np.full(nf, np.nan)
    p_demo = flange_position(demo.robot[-1])
    targets = {}
    for i, f in enumerate(fractions):
        human = observed_prefix(demo.human, f, workspace, lib.config.resample_tolerance)
        outcome, comp = lab.classify(human, demo.task, workspace, f)
        out["outcome"][i] = outcome
        if comp is None:
            continue
        mean, _ = lib.predict_robot(human, f, workspace=workspace, component=comp)
        n = mean.shape[0]
        if n not in targets:
            targets[n] = resample_in_time(demo.t, demo.robot, n)
        prior = _robot_mean(lib, comp, n)
        out["rmse"][i] = float(np.sqrt(np.mean((mean - targets[n]) ** 2)))
        out["prior_rmse"][i] = float(np.sqrt(np.mean((prior - targets[n]) ** 2)))
        out["flange"][i] = 100.0 * float(np.linalg.norm(flange_position(mean[-1]) - p_demo))
        out["prior_flange"][i] = 100.0 * float(np.linalg.norm(flange_position(prior[-1]) - p_demo))
    return out


# --------------------------------------------------------------------------- trials
def personal_trial(ctx: dict, item: tuple[int, int]) -> dict:
    """One random train/test split of one subject (Tables 1-2 and the response error).

    Parameters
    ----------
    item : (subject position in ``ctx["subjects"]``, split index)

    Returns
    -------
    dict: ``subject`` (name), ``n_components``, ``tasks`` of the test motions, and
    per test motion and fraction of ``settings.grid()`` arrays (n_test, n_fractions)
    ``outcome``, ``rmse``, ``flange``, ``prior_rmse``, ``prior_flange``.
    """
    s: SaladSettings = ctx["settings"]
    pos, split = item
    data = ctx["subjects"][pos]
    ws = data.workspace(z_factor=s.z_factor)
    rng = _rng(s.seed, STREAM_PERSONAL, data.subject.index, split)
    n_train = s.train_per_task
    train, test = [], []
    for task in s.tasks:
        demos = data.by_task(task)
        perm = rng.permutation(len(demos))
        train += [demos[j] for j in perm[:n_train]]
        test += [demos[j] for j in perm[n_train:]]
    lab = LabeledLibrary()
    for j in rng.permutation(len(train)):
        lab.teach(train[j], ws)
    grid = s.grid()
    rows = [response_errors(lab, d, ws, grid) for d in test]
    out = {k: np.stack([r[k] for r in rows]) for k in rows[0]}
    out.update(subject=data.subject.name, n_components=lab.library.n_components, tasks=[d.task for d in test])
    return out


def _nested_streams(tasks: Sequence[str], perm: np.ndarray, n_max: int) -> list[list[int]]:
    from drake_skills.evaluation.letters import _nested_streams as nested

    return nested(tasks, perm, n_max)


def kl_trial(ctx: dict, index: int) -> dict:
    """One random order of one subject's demonstrations: KL to the labeled baseline per k (Fig. 7c).

    Returns
    -------
    dict: ``subject``, and arrays over k = 1..kl_demos ``kl_incremental``, ``kl_em``,
    ``n_components``.
    """
    from drake_skills import SkillLibrary
    from drake_skills.library.batch import batch_em, labeled_ml
    from drake_skills.promp.gaussian import mc_kl_mixtures

    s: SaladSettings = ctx["settings"]
    data = ctx["subjects"][index % len(ctx["subjects"])]
    ws = data.workspace(z_factor=s.z_factor)
    rng = _rng(s.seed, STREAM_KL, index)
    demos = [d for d in data.demos if d.task in s.tasks]
    tasks = [d.task for d in demos]
    perm = rng.permutation(len(demos))
    kl_inc, kl_em, n_comp = [], [], []
    for stream in _nested_streams(tasks, perm, s.kl_per_task):
        lib = SkillLibrary()
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
    return {"subject": data.subject.name, "kl_incremental": np.array(kl_inc), "kl_em": np.array(kl_em),
            "n_components": np.array(n_comp)}


def task_components_trial(ctx: dict, item: tuple[str, int]) -> dict:
    """Components of a one-task library across subjects (Table 3).

    The same demonstrations in the same order go into three libraries: with each
    subject's personal workspace (``"with"``), with the shared workspace
    (``"without"``), and with the shared workspace and no start-position offset
    (``"raw"``, the paper's "without transformation" of Fig. 8).
    """
    from drake_skills import LibraryConfig, SkillLibrary

    s: SaladSettings = ctx["settings"]
    task, order = item
    rng = _rng(s.seed, STREAM_TASKS, TASKS.index(task), order)
    demos, personal = [], []
    for data, ws in zip(ctx["subjects"], ctx["workspaces"]):
        pool = data.by_task(task)
        for j in rng.permutation(len(pool))[:s.table3_per_task]:
            demos.append(pool[j])
            personal.append(ws)
    with_ws, without_ws, raw = SkillLibrary(), SkillLibrary(), SkillLibrary(LibraryConfig(subtract_start=False))
    for j in rng.permutation(len(demos)):
        with_ws.partial_fit(demos[j], workspace=personal[j])
        without_ws.partial_fit(demos[j], workspace=ctx["shared"])
        raw.partial_fit(demos[j], workspace=ctx["shared"])
    return {"task": task, "with": with_ws.n_components, "without": without_ws.n_components,
            "raw": raw.n_components}


def transfer_trial(ctx: dict, item: tuple[int, int]) -> dict:
    """Leave one subject out (Fig. 9): learn on the others, test on the held-out subject.

    Returns
    -------
    dict: ``subject`` (held out), ``tasks`` of the test motions, and per variant
    (``"with"``, ``"without"`` normalization) the outcomes (n_test,) and
    ``n_components_<variant>``.
    """
    s: SaladSettings = ctx["settings"]
    held, trial = item
    subjects, wss = ctx["subjects"], ctx["workspaces"]
    rng = _rng(s.seed, STREAM_TRANSFER, subjects[held].subject.index, trial)
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
    out = {"subject": subjects[held].subject.name, "tasks": [d.task for d in test]}
    for variant in ("with", "without"):
        lab = LabeledLibrary()
        for j in order:
            lab.teach(train[j], train_ws[j] if variant == "with" else ctx["shared"])
        ws_test = wss[held] if variant == "with" else ctx["shared"]
        out[variant] = np.array([lab.classify(d.human, d.task, ws_test)[0] for d in test], dtype=int)
        out[f"n_components_{variant}"] = lab.library.n_components
    return out


# --------------------------------------------------------------------------- aggregation
def _fractions_of(outcomes: np.ndarray) -> list[float]:
    """Correct / wrong / unknown fractions of an array of outcomes (sum to 1)."""
    o = np.asarray(outcomes).ravel()
    n = max(o.size, 1)
    return [float(np.sum(o == k)) / n for k in (CORRECT, WRONG, UNKNOWN)]


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


def _classification_tables(s: SaladSettings, names: list[str], personal: list[dict]):
    i_full = s.grid().index(1.0)
    rows, matrix = [], []
    per = {n: {t: [] for t in s.tasks} for n in names}
    for r in personal:
        for task, o in zip(r["tasks"], r["outcome"][:, i_full]):
            per[r["subject"]][task].append(o)
    for n in names:
        cells = []
        for task in s.tasks:
            fr = _fractions_of(per[n][task])
            rows.append([n, task, *fr, len(per[n][task])])
            cells.append(_paper_cell(*fr))
        allo = np.concatenate([np.asarray(per[n][t], int) for t in s.tasks])
        rows.append([n, "all", *_fractions_of(allo), int(allo.size)])
        matrix.append([n, *cells])
    allo = np.concatenate([np.asarray(per[n][t], int) for n in names for t in s.tasks])
    rows.append(["all", "all", *_fractions_of(allo), int(allo.size)])
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


def _components_table(s: SaladSettings, names: list[str], personal: list[dict]) -> Table:
    counts = {n: [r["n_components"] for r in personal if r["subject"] == n] for n in names}
    bins = sorted(set(c for v in counts.values() for c in v) | {len(s.tasks)})
    rows = [[n, float(np.mean(counts[n])), *count_distribution(counts[n], bins)] for n in names]
    return Table(["subject", "mean", *[str(b) for b in bins]], rows,
                 caption=f"Components per personal library (Table 2): fraction of the {s.trials} splits "
                         f"ending with each number of components ({s.train_per_task} training demonstrations "
                         f"per task, {len(s.tasks)} tasks).")


def _response_tables(s: SaladSettings, personal: list[dict]):
    grid = s.grid()
    cat = {k: np.concatenate([r[k] for r in personal]) for k in ("outcome", "rmse", "flange", "prior_rmse",
                                                                   "prior_flange")}
    tasks = np.concatenate([np.asarray(r["tasks"]) for r in personal])
    rows = []
    for i, f in enumerate(grid):
        o = cat["outcome"][:, i]
        ok, ans = o == CORRECT, o != UNKNOWN
        rows.append([f, *_fractions_of(o),
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
    return resp, early, summary, rows


def _kl_table(s: SaladSettings, kl: list[dict]):
    inc = np.stack([r["kl_incremental"] for r in kl])
    em = np.stack([r["kl_em"] for r in kl])
    nc = np.stack([r["n_components"] for r in kl])
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


def _task_components_tables(s: SaladSettings, tc: list[dict]):
    rows, matrix, summary = [], [], {}
    for task in s.tasks:
        counts = {v: [r[v] for r in tc if r["task"] == task] for v in TABLE3_VARIANTS}
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


def _transfer_table(s: SaladSettings, names: list[str], tr: list[dict]):
    rows, acc = [], {}
    for variant, label in (("with", "personal workspace"), ("without", "shared workspace")):
        all_o = []
        for n in names:
            rs = [r for r in tr if r["subject"] == n]
            tasks = np.concatenate([np.asarray(r["tasks"]) for r in rs])
            o = np.concatenate([r[variant] for r in rs])
            all_o.append(o)
            for task in s.tasks:
                m = tasks == task
                rows.append([n, task, label, *_fractions_of(o[m]), int(m.sum())])
            rows.append([n, "all", label, *_fractions_of(o), int(o.size)])
        o = np.concatenate(all_o)
        rows.append(["all", "all", label, *_fractions_of(o), int(o.size)])
        acc[variant] = _fractions_of(o)
    t = Table(["held-out subject", "task", "normalization", "correct", "wrong", "unknown", "tests"], rows,
              caption=(f"Leave one subject out (Fig. 9): a library learned from {s.transfer_train_per_task} "
                       f"demonstrations per task of each other subject (random order), tested on "
                       f"{s.transfer_test_per_task} demonstrations per task of the held-out subject; {s.trials} "
                       f"trials per held-out subject; with personal or one shared workspace."))
    return t, acc


# --------------------------------------------------------------------------- figures
_COLORS = {"correct": "tab:green", "unknown": "tab:blue", "wrong": "tab:red"}


def _stacked(ax, x, c, w, u, width, hatch=None, label=True):
    ax.bar(x, c, width, color=_COLORS["correct"], hatch=hatch, label="correct" if label else None)
    ax.bar(x, u, width, bottom=c, color=_COLORS["unknown"], hatch=hatch, label="unknown" if label else None)
    ax.bar(x, w, width, bottom=np.add(c, u), color=_COLORS["wrong"], hatch=hatch, label="wrong" if label else None)


def _fig_classification(s: SaladSettings, names: list[str], table: Table):
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


def _fig_task_components(s: SaladSettings, tc: list[dict]):
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(s.tasks), figsize=(2.4 * len(s.tasks), 2.8), sharey=True, squeeze=False)
    x = np.arange(len(TASK_COUNT_BINS))
    for ax, task in zip(axes[0], s.tasks):
        for off, variant, c, lab in ((-0.27, "with", "tab:green", "personal"), (0.0, "without", "0.5", "shared"),
                                     (0.27, "raw", "0.8", "shared, start kept")):
            d = count_distribution([r[variant] for r in tc if r["task"] == task], TASK_COUNT_BINS)
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


def _fig_transfer(s: SaladSettings, names: list[str], table: Table):
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


def _fig_response(s: SaladSettings, rows: list[list]):
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


# --------------------------------------------------------------------------- the experiment
def _warm_imports() -> None:
    """Import what the trials use before the worker processes are forked (each would import it again)."""
    import sklearn.mixture  # noqa: F401
    from pydrake.multibody.plant import MultibodyPlant  # noqa: F401

    import drake_skills.library.batch  # noqa: F401
    import drake_skills.library.incremental  # noqa: F401
    import drake_skills.promp.gaussian  # noqa: F401
    import drake_skills.sim.models  # noqa: F401


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
    s = settings or SaladSettings()
    s.validate()
    if workers > 1:
        _warm_imports()
    seconds: dict[str, float] = {}
    t0 = time.perf_counter()
    subjects = load_salad_data(s, workers=workers, progress=progress, cache_dir=cache_dir)
    seconds["data"] = time.perf_counter() - t0
    names = [d.subject.name for d in subjects]
    wss = [d.workspace(z_factor=s.z_factor) for d in subjects]
    ctx = {"settings": s, "subjects": subjects, "workspaces": wss, "shared": shared_workspace(subjects, s.z_factor)}

    def timed(key, fn, items, desc):
        t = time.perf_counter()
        out = run_trials(fn, items, ctx, workers=workers, desc=f"salad: {desc}", progress=progress)
        seconds[key] = time.perf_counter() - t
        return out

    personal = timed("personal", personal_trial, [(p, k) for p in range(len(subjects)) for k in range(s.trials)],
                     "personal libraries")
    kl = timed("kl", kl_trial, range(s.trials), "KL vs demos")
    tc = timed("components_per_task", task_components_trial, [(t, k) for t in s.tasks for k in range(s.trials)],
               "components per task")
    tr = timed("transfer", transfer_trial, [(p, k) for p in range(len(subjects)) for k in range(s.trials)],
               "leave one subject out")

    cls_long, cls_mat, all_personal = _classification_tables(s, names, personal)
    comp = _components_table(s, names, personal)
    resp, early, early_summary, resp_rows = _response_tables(s, personal)
    kl_t, ks, inc, em = _kl_table(s, kl)
    tc_long, tc_mat, tc_summary = _task_components_tables(s, tc)
    tr_t, tr_acc = _transfer_table(s, names, tr)

    rep = EvalReport("Salad (Sec. 4.2)", {
        "classification": cls_long, "classification_matrix": cls_mat, "components_per_subject": comp,
        "kl_vs_demos": kl_t, "components_per_task": tc_long, "components_per_task_matrix": tc_mat,
        "transfer": tr_t, "response_vs_fraction": resp, "earliest_decision": early})
    full = s.grid().index(1.0)
    rep.summary = {
        "settings": s.resolved(),
        "subjects": names,
        "demonstrations": int(sum(len(d.demos) for d in subjects)),
        "personal_correct_wrong_unknown": _fractions_of(all_personal),
        "personal_components_mean": {n: float(np.mean([r["n_components"] for r in personal if r["subject"] == n]))
                                     for n in names},
        "kl_incremental_mean": inc.mean(axis=0).tolist(),
        "kl_em_mean": em.mean(axis=0).tolist(),
        "components_per_task_mean": tc_summary,
        "transfer_correct_wrong_unknown": tr_acc,
        "earliest_decision_fraction": early_summary,
        "response_at_full_observation": dict(zip(resp.columns, resp_rows[full])),
        "seconds": seconds,
    }
    if figures:
        t = time.perf_counter()
        rep.figures = {"classification": _fig_classification(s, names, cls_long),
                       "kl_vs_demos": fig_kl_vs_samples(ks, inc, em, xlabel="demonstrations per task",
                                                        title="Salad: KL to the labeled baseline (Fig. 7c)"),
                       "components_per_task": _fig_task_components(s, tc),
                       "transfer": _fig_transfer(s, names, tr_t),
                       "response_vs_fraction": _fig_response(s, resp_rows)}
        seconds["figures"] = time.perf_counter() - t
    seconds["total"] = time.perf_counter() - t0
    return rep
