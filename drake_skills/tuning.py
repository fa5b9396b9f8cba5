"""``drake_skills.tuning``: cross-validated choice of the library settings that remain, on Ray.

``LibraryConfig()`` is meant to serve every data set unchanged; a user with a labeled
subset of their own demonstrations can check that, and choose the settings that remain
(:data:`SEARCH_SPACE`: the prior of the learned scale, the chi-square quantiles of the
novelty, merge and split tests, the basis count and the ridge) by cross-validation:

* **Folds.** The demonstrations are split into ``n_folds`` folds stratified by task
  (every task's demonstrations dealt round-robin after a seeded shuffle), so every fold
  trains on every task.
* **Objective** (higher is better), per fold and order of presentation::

      score = (correct - 10 wrong) / held_out - 0.02 max(0, K - tasks)

  where ``correct`` / ``wrong`` count the held-out whole motions recognized as the right
  / another task (a component's task is the majority task of what it absorbed),
  "unknown" and "undecided" count 0, and ``K`` is the number of components the training
  folds produced. A wrong answer (the robot executes the wrong skill) costs ten times
  what an "unknown" (the robot holds still and asks) forgoes; a component beyond the
  number of tasks costs a fiftieth of a correct answer. The trial's score is the mean
  over folds and orders.
* **Search.** Random search, seeded: trial 0 is the base config (the defaults unless
  given), trials 1.. draw every setting of :data:`SEARCH_SPACE` independently
  (log-uniform, or log-uniform in ``1 - q`` for a quantile). The best mean score wins;
  a tie keeps the earlier trial (so the defaults unless something is strictly better).
  Results depend only on ``seed``, never on how Ray schedules the trials.

Ray runs one task per trial: on a local Ray started here (loopback only, no dashboard)
unless ``address`` names a running cluster (whose workers must have drake-skills
installed). Ray is an optional dependency (``pip install 'drake-skills[tune]'``, which
``make test`` and ``make demo`` install); it is imported only in this module.
"""
from __future__ import annotations

import contextlib
import logging
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from drake_skills.data.demonstration import Demonstration
from drake_skills.data.workspace import Workspace
from drake_skills.evaluation.common import Table, stream_rng
from drake_skills.evaluation.labeled import CORRECT, UNDECIDED, UNKNOWN, WRONG, LabeledLibrary
from drake_skills.library.config import LibraryConfig, WorkspaceBounds

log = logging.getLogger(__name__)

#: Setting -> (kind, low, high). "log": log-uniform; "int": uniform integer in [low, high];
#: "quantile": q = 1 - 10^u with u uniform in [log10(1 - high), log10(1 - low)].
SEARCH_SPACE = {
    "prior_scale": ("log", 0.1, 1.0),
    "prior_floor": ("log", 0.1, 2.0),
    "shrinkage": ("uniform", 0.1, 0.6),
    "novelty_quantile": ("quantile", 0.99, 0.99999),
    "merge_quantile": ("quantile", 0.99, 0.9999),
    "split_quantile": ("quantile", 0.999, 0.999999),
    "n_basis_human": ("int", 4, 12),
    "ridge": ("log", 1e-4, 1e-1),
}
#: Cost of a wrong answer in units of a correct one, and of each component beyond the number of tasks.
WRONG_COST = 10.0
EXTRA_COMPONENT_COST = 0.02
OBJECTIVE = (f"score = (correct - {WRONG_COST:g} wrong) / held_out - {EXTRA_COMPONENT_COST:g} max(0, K - tasks), "
             f"mean over folds and orders (unknown and undecided count 0)")
STREAM_TUNE = 11
#: Makes a local Ray use the loopback address only (read when ray is first imported).
_RAY_LOCAL_ENV = ("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")


@dataclass(frozen=True, eq=False)
class TuneResult:
    """What :func:`tune` chose and why.

    Attributes
    ----------
    config : LibraryConfig
        The settings of the best trial (with the workspace the trials normalized with).
    trials : Table
        One row per trial: its settings, score, correct / wrong / unknown / undecided
        fractions of the held-out motions and mean components.
    best : int
        Index of the best trial (0 is the base config).
    objective : str
        The objective, as a formula.
    """

    config: LibraryConfig
    trials: Table
    best: int
    objective: str = OBJECTIVE

    def write_yaml(self, path) -> Path:
        """Write :attr:`config` as a YAML of LibraryConfig fields (``--config`` of learn, demo, eval)."""
        return write_config_yaml(self.config, path)


def write_config_yaml(config: LibraryConfig, path) -> Path:
    """A LibraryConfig as YAML that :func:`drake_skills.sim.config.load_config` reads back exactly."""
    from pydrake.common.yaml import yaml_dump_typed

    from drake_skills._io import atomic_write

    c = replace(config)  # a changeable copy (a library's config is sealed)
    if c.workspace is not None:
        c.workspace = WorkspaceBounds(c.workspace.lower.tolist(), c.workspace.upper.tolist(), c.workspace.scale)
    text = "# LibraryConfig chosen by drake-skills tune\n" + yaml_dump_typed(c)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda f: f.write(text.encode()))
    return path


# ------------------------------------------------------------------ search
def sample_configs(base: LibraryConfig, n_trials: int, seed: int) -> list[LibraryConfig]:
    """``n_trials`` configs: ``base``, then random draws of :data:`SEARCH_SPACE` around nothing (see the module)."""
    rng = stream_rng(seed, STREAM_TUNE, 0)
    out = [base]
    while len(out) < n_trials:
        kw = {}
        for name, (kind, lo, hi) in SEARCH_SPACE.items():
            if kind == "log":
                kw[name] = float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
            elif kind == "uniform":
                kw[name] = float(rng.uniform(lo, hi))
            elif kind == "int":
                kw[name] = int(rng.integers(lo, hi + 1))
            else:
                kw[name] = float(1.0 - 10.0 ** rng.uniform(np.log10(1 - hi), np.log10(1 - lo)))
        if kw["split_quantile"] <= kw["merge_quantile"]:
            continue  # invalid: a merge would be split again at once
        out.append(replace(base, **kw))
    return out[:n_trials]


def stratified_folds(tasks: Sequence[str], n_folds: int, seed: int) -> list[np.ndarray]:
    """Held-out index sets, one per fold, that together cover every item once, stratified by task."""
    rng = stream_rng(seed, STREAM_TUNE, 1)
    folds = [[] for _ in range(n_folds)]
    start = 0
    for task in dict.fromkeys(tasks):
        idx = rng.permutation([i for i, t in enumerate(tasks) if t == task])
        for k, i in enumerate(idx):
            folds[(start + k) % n_folds].append(int(i))
        start += len(idx)
    return [np.array(sorted(f), int) for f in folds if f]


@dataclass(frozen=True)
class TrialScore:
    """One config's cross-validated figures (fractions over all held-out motions of all folds and orders)."""

    score: float
    correct: float
    wrong: float
    unknown: float
    undecided: float
    components: float


def score_config(config: LibraryConfig, demos: Sequence[Demonstration], folds: Sequence[np.ndarray],
                 workspace: Workspace, *, n_orders: int = 2, seed: int = 0) -> TrialScore:
    """Cross-validate one config (the objective of the module docstring).

    Parameters
    ----------
    config : LibraryConfig
    demos : sequence of Demonstration
        Labeled (``task``), in raw units of ``workspace``.
    folds : sequence of int arrays
        Held-out indices per fold (:func:`stratified_folds`).
    workspace : Workspace
        Normalizes every demonstration (Eq. 14).
    n_orders : int
        Random presentation orders of each fold's training part.
    seed : int
        The orders are ``stream_rng(seed, STREAM_TUNE, 2, fold, order)``: the same for every config.
    """
    cfg = replace(config, workspace=workspace)
    scores, counts, ks = [], np.zeros(4), []
    for f, held in enumerate(folds):
        train = np.setdiff1d(np.arange(len(demos)), held)
        n_tasks = len({demos[i].task for i in train})
        for o in range(n_orders):
            order = stream_rng(seed, STREAM_TUNE, 2, f, o).permutation(train)
            lab = LabeledLibrary(cfg)
            for i in order:
                lab.teach(demos[i])
            outs = np.array([lab.classify(demos[i].human, demos[i].task)[0] for i in held])
            c, w = np.sum(outs == CORRECT), np.sum(outs == WRONG)
            K = lab.library.n_components
            scores.append((c - WRONG_COST * w) / len(held) - EXTRA_COMPONENT_COST * max(0, K - n_tasks))
            counts += [c, w, np.sum(outs == UNKNOWN), np.sum(outs == UNDECIDED)]
            ks.append(K)
    fr = counts / counts.sum()
    return TrialScore(float(np.mean(scores)), *map(float, fr), float(np.mean(ks)))


def _score_task(config_dict, demos, folds, ws_dict, n_orders, seed):
    # module-level so that Ray (and pickle) can ship it
    return score_config(LibraryConfig.from_dict(config_dict), demos, folds, Workspace.from_dict(ws_dict),
                        n_orders=n_orders, seed=seed)


# ------------------------------------------------------------------ ray
def _import_ray(address):
    local = address is None and os.environ.get(_RAY_LOCAL_ENV[0]) is None
    if local:
        os.environ[_RAY_LOCAL_ENV[0]] = _RAY_LOCAL_ENV[1]  # a local Ray listens on 127.0.0.1 only
    try:
        import ray
    except ImportError:
        raise ImportError("drake_skills.tuning needs Ray: pip install 'drake-skills[tune]' "
                          "(or pip install 'ray==2.60.0'); `make test` and `make demo` install it") from None
    if local:
        try:  # ray was imported before the variable was set: the constant it read
            from ray._private import ray_constants

            ray_constants.ENABLE_RAY_CLUSTER = False
        except (ImportError, AttributeError):  # pragma: no cover - another Ray version
            log.warning("could not keep the local Ray on the loopback interface")
    return ray


@contextlib.contextmanager
def ray_session(address: str | None = None, num_cpus: int | None = None):
    """A Ray connection for the duration of the block: local (loopback, no dashboard) unless ``address``.

    An already initialized Ray is used as it is and left running.
    """
    ray = _import_ray(address)
    if ray.is_initialized():
        yield ray
        return
    if address is None:
        ray.init(num_cpus=num_cpus, include_dashboard=False, log_to_driver=False, configure_logging=False)
    else:
        ray.init(address=address, log_to_driver=False, configure_logging=False)
    try:
        yield ray
    finally:
        ray.shutdown()


def tune(demos: Sequence[Demonstration], *, workspace: Workspace | None = None, n_trials: int = 64, seed: int = 0,
         address: str | None = None, n_folds: int = 4, n_orders: int = 2, base: LibraryConfig | None = None,
         num_cpus: int | None = None, progress: bool = False) -> TuneResult:
    """Choose the library settings by cross-validation on labeled demonstrations, on Ray.

    Parameters
    ----------
    demos : sequence of Demonstration
        Labeled (every ``task`` set, at least 2 demonstrations per task), raw units.
    workspace : Workspace, optional
        Normalizes every demonstration; default ``base.workspace``, else the bounding box
        of all the demonstrations' human positions.
    n_trials : int
        Configs tried (trial 0 is ``base``).
    seed : int
        Seeds the configs drawn, the folds and the orders.
    address : str, optional
        A running Ray cluster (e.g. ``"ray://head:10001"`` or ``"auto"``); default: start a
        local Ray for the call.
    n_folds, n_orders : int
        Cross-validation folds (at most the smallest number of demonstrations of a task)
        and presentation orders per fold.
    base : LibraryConfig, optional
        The settings outside :data:`SEARCH_SPACE`, and trial 0 (default ``LibraryConfig()``).
    num_cpus : int, optional
        CPUs of the local Ray (default: all).
    progress : bool
        tqdm progress bar on stderr.

    Returns
    -------
    TuneResult
    """
    demos = list(demos)
    if not demos or not all(isinstance(d, Demonstration) for d in demos):
        raise ValueError("tune takes a non-empty sequence of Demonstration")
    unlabeled = [d.name or i for i, d in enumerate(demos) if d.task is None]
    if unlabeled:
        raise ValueError(f"tune needs labeled demonstrations (task set); {unlabeled[:3]} have none")
    tasks = [d.task for d in demos]
    few = sorted(t for t in set(tasks) if tasks.count(t) < 2)
    if few:
        raise ValueError(f"tune needs at least 2 demonstrations per task to cross-validate; {few} have one")
    if isinstance(n_trials, bool) or int(n_trials) != n_trials or n_trials < 1:
        raise ValueError(f"n_trials must be an integer >= 1, got {n_trials!r}")
    n_folds = min(int(n_folds), min(tasks.count(t) for t in set(tasks)))
    if n_folds < 2:
        raise ValueError(f"n_folds must be >= 2, got {n_folds}")
    base = base if base is not None else LibraryConfig()
    if workspace is None:
        workspace = base.workspace
    if workspace is None:
        H = np.concatenate([d.human for d in demos])
        workspace = Workspace(H.min(axis=0), H.max(axis=0))
    configs = sample_configs(replace(base, workspace=None), int(n_trials), seed)
    folds = stratified_folds(tasks, n_folds, seed)
    from tqdm import tqdm

    with ray_session(address, num_cpus) as ray:
        remote = ray.remote(num_cpus=1)(_score_task)
        demos_ref = ray.put(demos)
        pending = {remote.remote(c.dict(), demos_ref, folds, workspace.dict(), n_orders, seed): i
                   for i, c in enumerate(configs)}
        results: list[TrialScore | None] = [None] * len(configs)
        with tqdm(total=len(configs), desc="tune: trials", disable=not progress, leave=False,
                  dynamic_ncols=True) as bar:
            while pending:
                done, _ = ray.wait(list(pending), num_returns=1)
                for ref in done:
                    results[pending.pop(ref)] = ray.get(ref)
                    bar.update()
    scores = np.array([r.score for r in results])
    best = int(np.argmax(scores))  # first of the best: the base config on a tie
    names = list(SEARCH_SPACE)
    rows = [[i, *[getattr(c, n) for n in names], r.score, r.correct, r.wrong, r.unknown, r.undecided, r.components]
            for i, (c, r) in enumerate(zip(configs, results))]
    table = Table(["trial", *names, "score", "correct", "wrong", "unknown", "undecided", "components"], rows,
                  fmt="{:.6g}", caption=(f"{len(configs)} trials (0 = the base config), {len(folds)}-fold cross-validation "
                           f"stratified by task over {len(demos)} demonstrations of {len(set(tasks))} tasks, "
                           f"{n_orders} orders per fold. {OBJECTIVE}. Best: trial {best}."))
    config = replace(configs[best], workspace=workspace)
    log.info("tune: best trial %d of %d, score %.3f (base %.3f)", best, len(configs), scores[best], scores[0])
    return TuneResult(config, table, best)

