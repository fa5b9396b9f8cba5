"""Real human-robot interactions (``buetepage_hr.npz``): recognition, components, robot response, anticipation.

Protocol (one *order* = one random permutation of the training interactions):

1. Load the interactions with :func:`~drake_skills.data.interaction.load_interactions`
   (the hand by default, the whole arm with ``columns="arm"``) and keep the source's
   train/test split; the workspace is the bounding box of the training interactions'
   human columns (the wrists, by default), the same for every interaction.
2. Fold the training interactions into a fresh library (``InteractionSettings.library``,
   default :class:`LibraryConfig`) in the order's permutation, following the task votes
   of its components (:class:`~drake_skills.evaluation.labeled.LabeledLibrary`).
3. Recognize every whole test interaction (``observed_fraction=1``): correct, wrong,
   undecided or unknown against its task.
4. For every test interaction recognized as a skill, the robot response error: the RMS
   joint error (radians, over ``n_steps`` samples evenly spaced in time and all joints)
   of ``predict_robot`` against the recorded robot trajectory, beside two baselines
   evaluated on the same interactions: the recognized component's unconditioned mean,
   and the mean robot trajectory of the training interactions of the *true* task (an
   oracle on the label).
5. Anticipation: every test interaction cut at true fractions of its path length (the
   library's own arc length: normalized units, ``LibraryConfig.resample_tolerance``),
   recognized **without** ``observed_fraction`` (the library estimates the phase):
   correct / wrong / undecided / unknown and the estimated phase against the true
   fraction.
6. Commits: every test interaction replayed sample by sample through the Drake
   controller's decision logic (:func:`~drake_skills.systems.gating.gating_step` with
   the default :class:`~drake_skills.systems.decision_rule.DecisionRule`, the wrist
   sampled every ``GATING_PERIOD`` as the gating samples it; a recording that ends
   before the wrist rests is answered at the rule's time-out): the skill the robot
   would commit to first and at what share of the person's path, and the skill it
   would be executing at the end (a wrong commit the gating revised in time is not
   executed).
7. ipromps' protocol (table ``loo``, :func:`loo_trial`): every interaction of the file held
   out in turn, a library learned from all the others, and the held-out one cut at the
   first share of its *samples* (time, as chenlx92/ipromps cuts it); its forced choice
   (:func:`best_guess`, what a classifier that always answers would say) beside the
   library's own answers. Steps 5 and 7 report the forced choice for comparison with
   classifiers that never abstain; the robot acts only on the library's answers.
8. A new task (table ``untaught``, :func:`untaught_trial`): each task in turn left out of the
   training split, a library learned from the other tasks' training interactions (workspace:
   their bounding box), and every interaction of the left-out task (both splits) shown to it:
   as a whole motion (``observed_fraction=1``) and replayed through the controller's decision
   logic. The right answer is "unknown" (ask for a demonstration); a skill answer, a commit or a
   skill executed is a wrong one. An open-ended library meets new tasks all the time.

Figures are over orders x test interactions. Nothing here is tuned on the test split.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from drake_skills.data.demonstration import Demonstration
from drake_skills.data.interaction import column_selection, load_interactions
from drake_skills.data.workspace import Workspace
from drake_skills.evaluation.common import EvalReport, Table, run_trials, trial_rng
from drake_skills.evaluation.labeled import CORRECT, UNDECIDED, UNKNOWN, WRONG, LabeledLibrary, outcome_fractions
from drake_skills.library.incremental import LibraryConfig
from drake_skills.library.views import StillMotionError
from drake_skills.promp.preprocessing import prefix_samples, resample_in_time

STREAM_INTERACTION = 7
#: Recognition from the wrist alone in chenlx92/ipromps (Interaction ProMPs with phase
#: estimation, 4 real handover tasks, leave-one-out), by observed fraction (issue 12).
IPROMPS_WRIST = {0.1: 0.647, 0.3: 0.735, 0.5: 0.662}
#: The observation ratios of ipromps' leave-one-out evaluation (``scripts/loocv_full.py``): the
#: first ``int(ratio * T)`` of a recording's T samples, i.e. a share of its *time*.
IPROMPS_RATIOS = (0.1, 0.2, 0.3, 0.4, 0.5)
STREAM_LOO = 8
STREAM_UNTAUGHT = 9
OUTCOMES = ("correct", "wrong", "undecided", "unknown")
#: Teaching orders: interleaved, or task by task.
TEACHING = ("random", "row")


@dataclass
class InteractionSettings:
    """Settings of the interaction evaluation."""

    #: The interactions file (layout of ``buetepage_hr.npz``).
    data: str = ""
    #: Human columns: "hand" (the wrist, columns 6:9) or "arm" (shoulder, elbow, hand: 0:9) of the
    #: buetepage_hr layout, another name of ``data.interaction.COLUMNS``, or "START:STOP".
    columns: str = "hand"
    #: Random orders of the training interactions.
    orders: int = 20
    #: How each order teaches them: "random" (interleaved) or "row" (task by task, as a person
    #: shows a robot one skill several times before the next; tasks and repetitions in random order).
    teaching: str = "random"
    #: True observed fractions of the path for the anticipation table.
    fractions: tuple[float, ...] = tuple(np.round(np.arange(1, 11) / 10, 2).tolist())
    #: Samples (evenly spaced in time) on which the robot response error is measured.
    n_steps: int = 100
    #: Sampling rate assumed for the file (the source does not state it).
    rate_hz: float = 100.0
    #: Longest run of missing samples (NaN/inf) filled by interpolation, in seconds (``load_interactions``).
    max_gap_s: float = 0.5
    #: Units of the file's robot columns, for the response tables ("rad": the YuMi's joint angles;
    #: "m" for a second person's arm in metres).
    robot_units: str = "rad"
    #: Random orders per held-out interaction of the leave-one-out table (ipromps' protocol over
    #: every interaction of the file; 0 skips it).
    loo_orders: int = 3
    #: Random orders per held-out task of the table ``untaught`` (each task left out of the training split in
    #: turn, its interactions of both splits shown to the library as a new task; 0 skips it).
    untaught_orders: int = 5
    #: Experiment seed (the orders).
    seed: int = 0
    #: Settings of every library (its workspace is replaced by the training bounding box).
    library: LibraryConfig = field(default_factory=LibraryConfig)

    def __post_init__(self):
        column_selection(self.columns, "InteractionSettings.columns")
        if self.teaching not in TEACHING:
            raise ValueError(f"InteractionSettings.teaching must be one of {TEACHING}, got {self.teaching!r}")
        for name, lo in (("orders", 1), ("n_steps", 2), ("loo_orders", 0), ("untaught_orders", 0)):
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or v < lo:
                raise ValueError(f"InteractionSettings.{name} must be an integer >= {lo}, got {v!r}")
        f = np.asarray(self.fractions, float)
        if f.ndim != 1 or not f.size or (f <= 0).any() or (f > 1).any():
            raise ValueError(f"InteractionSettings.fractions must be in (0, 1], got {self.fractions!r}")
        self.fractions = tuple(float(x) for x in f)
        if not isinstance(self.library, LibraryConfig):
            raise ValueError(f"InteractionSettings.library must be a LibraryConfig, got {type(self.library).__name__}")
        if not isinstance(self.robot_units, str) or not self.robot_units.strip():
            raise ValueError(f"InteractionSettings.robot_units must be a name of units, got {self.robot_units!r}")


@dataclass(frozen=True, eq=False)
class InteractionContext:
    """What every order reads: the two splits, the workspace, the task-mean baseline, the settings."""

    train: tuple[Demonstration, ...]
    test: tuple[Demonstration, ...]
    workspace: Workspace
    #: Mean robot trajectory, shape (n_steps, D_r), of the training interactions of each task.
    task_mean: dict
    #: Each test interaction's robot trajectory at ``n_steps`` times, shape (n_steps, D_r).
    test_robot: tuple[np.ndarray, ...]
    settings: InteractionSettings

    @classmethod
    def of(cls, settings: InteractionSettings) -> "InteractionContext":
        demos = load_interactions(settings.data, columns=column_selection(settings.columns), rate_hz=settings.rate_hz,
                                  max_gap_s=settings.max_gap_s)
        return cls.from_splits(demos.train, demos.test, settings)

    @classmethod
    def from_splits(cls, train, test, settings: InteractionSettings) -> "InteractionContext":
        train, test = tuple(train), tuple(test)
        if not train or not test:
            raise ValueError(f"interactions '{settings.data}': need training and test interactions, got "
                             f"{len(train)} and {len(test)}")
        missing = [d.name for d in train + test if d.task is None or d.robot is None]
        if missing:
            raise ValueError(f"interactions '{settings.data}': every interaction needs a task and a robot "
                             f"trajectory; {missing[:3]} lack one")
        untaught = sorted({d.task for d in test} - {d.task for d in train})
        if untaught:
            raise ValueError(f"interactions '{settings.data}': test tasks {untaught} have no training interaction")
        ws = workspace_of(train)
        n = settings.n_steps
        task_mean = {}
        for task in dict.fromkeys(d.task for d in train):
            task_mean[task] = np.mean([resample_in_time(d.t, d.robot, n) for d in train if d.task == task], axis=0)
        return cls(train, test, ws, task_mean, tuple(resample_in_time(d.t, d.robot, n) for d in test), settings)


def development_splits(train, *, draws: int = 3, taught_per_task: int = 6, seed: int = 100):
    """Internal validation on the training interactions alone: ``draws`` (taught, held) splits.

    Settings are chosen on these and reported on the source's test split, which none of
    them touches. Draw ``i`` shuffles each task's interactions with
    ``numpy.random.default_rng(seed + i)`` and teaches the first ``taught_per_task`` (the
    rest are held out), tasks in sorted order, interactions in file order within the
    shuffle. Pass a split to :meth:`InteractionContext.from_splits`.

    Returns
    -------
    list of (taught, held) tuples of demonstrations, one per draw.

    Raises
    ------
    ValueError
        If an interaction has no task, or a task has no interaction left to hold out.
    """
    train = tuple(train)
    if any(d.task is None for d in train):
        raise ValueError("development_splits: every training interaction needs a task")
    if int(draws) < 1 or int(taught_per_task) < 1:
        raise ValueError(f"development_splits: draws and taught_per_task must be >= 1, got {draws}, {taught_per_task}")
    by_task = {t: [i for i, d in enumerate(train) if d.task == t] for t in sorted({d.task for d in train})}
    short = {t: len(ix) for t, ix in by_task.items() if len(ix) <= taught_per_task}
    if short:
        raise ValueError(f"development_splits: tasks {short} have no more than {taught_per_task} training "
                         "interactions, none would be held out")
    splits = []
    for draw in range(int(draws)):
        rng = np.random.default_rng(seed + draw)
        taught, held = [], []
        for ix in by_task.values():
            ix = list(ix)
            rng.shuffle(ix)
            taught += [train[i] for i in ix[:taught_per_task]]
            held += [train[i] for i in ix[taught_per_task:]]
        splits.append((tuple(taught), tuple(held)))
    return splits


def workspace_of(demos) -> Workspace:
    """The bounding box of the human positions of ``demos`` (the paper's normalization, Eq. 14)."""
    H = np.concatenate([d.human for d in demos])
    return Workspace(H.min(axis=0), H.max(axis=0))


def prefix_end(human: np.ndarray, workspace: Workspace, fraction: float, tolerance: float, *,
               adapt_to_noise: bool = True, average_holds: bool = True) -> int:
    """How many samples of ``human`` cover ``fraction`` of its path length, as the library measures it.

    The path is the library's: normalized by ``workspace`` (Eq. 14) and counted only
    between vertices more than ``tolerance`` apart, adapted to the tracker's noise as the
    library's ``adapt_to_noise`` and ``average_holds`` say (the defaults are the library's)
    (:func:`~drake_skills.promp.preprocessing.prefix_samples`: the leading samples up to
    and including the first vertex at or past ``fraction`` of the whole path; for a noisy
    motion, a prefix whose own walk reaches it, found by bisection). At least 2.
    """
    return prefix_samples(workspace.normalize(human), fraction, tolerance, adapt_to_noise=adapt_to_noise,
                          average_holds=average_holds)


@dataclass(frozen=True, eq=False)
class InteractionTrial:
    """One order's results, per test interaction (arrays over the test split in file order)."""

    n_components: int
    #: CORRECT, WRONG, UNKNOWN or UNDECIDED per test interaction.
    outcomes: np.ndarray
    #: Smallest squared Mahalanobis distance to a component, and its chi-square threshold.
    d2_min: np.ndarray
    d2_threshold: np.ndarray
    #: RMS joint error (rad) of the conditioned response, the component mean and the task mean
    #: (NaN where the interaction was not recognized as a skill).
    err_conditioned: np.ndarray
    err_component: np.ndarray
    err_task_mean: np.ndarray
    #: Anticipation, shape (n_test, n_fractions): outcomes and estimated phases (NaN when unknown).
    prefix_outcomes: np.ndarray
    prefix_phases: np.ndarray
    #: Label of every component (majority task of what it absorbed), in id order.
    component_tasks: tuple
    #: Commits (:func:`replay_commits`), per test interaction: outcome of the first commit
    #: (UNKNOWN if none), share of the path observed at it (NaN if none), outcome of the
    #: skill executed at the end (UNKNOWN / UNDECIDED if the robot holds).
    first_commit: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    commit_fraction: np.ndarray = field(default_factory=lambda: np.zeros(0))
    executed: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    #: Whether the gating's final answer came from the wrist resting (else: its time-out).
    at_rest: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    #: Anticipation's forced choice, shape (n_test, n_fractions): CORRECT or WRONG of :func:`best_guess`.
    prefix_guess: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), int))


def best_guess(rec) -> int | None:
    """The component a classifier that must always answer would name (ipromps' answer: its most likely model).

    The most probable of the components that explain the motion (``Recognition.best``) or,
    where none does ("unknown"), the most probable of all (``Recognition.responsibilities``).
    This is a measurement for comparison with classifiers that never abstain; the library's
    own answer is ``Recognition.status`` and the robot acts on nothing else. None for an
    empty library, and where no component has any responsibility (a pruned recognition
    that scored none): no guess, which the tables count as not correct.
    """
    if rec.best is not None:
        return rec.best
    r = np.asarray(rec.responsibilities, dtype=float)
    if not len(rec.ids) or not (r > 0).any():
        return None
    return rec.ids[int(np.argmax(r))]


def replay_commits(library, demo: Demonstration, workspace: Workspace, rule=None):
    """Replay a human motion through the gating's decision logic.

    The wrist is sampled every ``GATING_PERIOD`` seconds (linear interpolation of
    ``demo.human`` over ``demo.t``), normalized relative to its first sample (Eq. 14,
    as the normalizer system does) and fed to
    :func:`~drake_skills.systems.gating.gating_step` with ``rule`` (default
    :class:`~drake_skills.systems.decision_rule.DecisionRule`). A recording that ends
    before the wrist has rested is held at its last sample until the rule's
    ``timeout``, where the gating gives its final answer on the whole motion.

    Returns
    -------
    decision : GatingDecision
        The final state (commits, commit time, the skill executed at the end).
    at_rest : bool
        The gating's final answer came from the wrist resting (not the time-out).
    """
    from drake_skills.systems.decision_rule import DecisionRule
    from drake_skills.systems.gating import GATING_PERIOD, GatingDecision, gating_step

    rule = rule or DecisionRule()
    times = np.arange(demo.t[0], demo.t[-1] + 1e-12, GATING_PERIOD)
    raw = np.stack([np.interp(times, demo.t, demo.human[:, d]) for d in range(demo.human.shape[1])], axis=1)
    y = workspace.normalize(raw, subtract_start=library.config.subtract_start)
    state = GatingDecision()
    for t, sample in zip(times - times[0], y):
        state = gating_step(state, float(t), sample, library, rule)
        if state.final:
            return state, True
    t_end = max(float(times[-1] - times[0]) + GATING_PERIOD, rule.timeout)
    return gating_step(state, t_end, y[-1], library, rule), False


def replayed_commit(lab: LabeledLibrary, demo: Demonstration, workspace: Workspace) -> tuple[int, float, int, bool]:
    """:func:`replay_commits` on one labeled motion: the first commit's outcome (UNKNOWN: none), the share of the
    person's path done at it (:func:`commit_share`; NaN: none), the outcome of the skill executed at the end, and
    whether the final answer came from the wrist resting."""
    cfg = lab.library.config
    g, at_rest = replay_commits(lab.library, demo, workspace)
    if not g.commits:
        return UNKNOWN, float("nan"), lab.outcome(g.component, demo.task, g.status), at_rest
    share = commit_share(demo, workspace, cfg.resample_tolerance, g.commit_time, **cfg.walk_options())
    return lab.outcome(g.commits[0], demo.task), share, lab.outcome(g.component, demo.task, g.status), at_rest


def commit_share(demo: Demonstration, workspace: Workspace, tolerance: float, commit_time: float, *,
                 adapt_to_noise: bool = True, average_holds: bool = True) -> float:
    """Share of the person's whole path done at ``commit_time`` (s from the start), as the demo reports it.

    :func:`~drake_skills.sim.demo.path_progress` (the library's arc length) at that time;
    NaN when nothing was committed.
    """
    from drake_skills.sim.demo import path_progress

    if not np.isfinite(commit_time):
        return float("nan")
    t, share = path_progress(demo, workspace, tolerance, adapt_to_noise=adapt_to_noise, average_holds=average_holds)
    return float(np.interp(commit_time, t, share))


def _rms(a, b) -> float:
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


def teaching_order(tasks, rng, teaching: str = "random") -> list[int]:
    """Indices of demonstrations with labels ``tasks`` in a random order: interleaved (``"random"``), or task by
    task (``"row"``: the tasks in the order a random permutation first names them, each task's demonstrations in
    the order of that permutation)."""
    perm = rng.permutation(len(tasks)).tolist()
    if teaching == "random":
        return perm
    if teaching != "row":
        raise ValueError(f"teaching must be one of {TEACHING}, got {teaching!r}")
    first = list(dict.fromkeys(tasks[j] for j in perm))
    return [j for t in first for j in perm if tasks[j] == t]


def interaction_trial(ctx: InteractionContext, index: int) -> InteractionTrial:
    """One random order: learn the training split, then score the test split (see the module)."""
    from drake_skills.library.novelty import chi2_ppf

    s = ctx.settings
    cfg = replace(s.library, workspace=ctx.workspace)
    rng = trial_rng(s.seed, index, STREAM_INTERACTION)
    lab = LabeledLibrary(cfg)
    for j in teaching_order([d.task for d in ctx.train], rng, s.teaching):
        lab.teach(ctx.train[j])
    lib = lab.library
    n_test, n_f = len(ctx.test), len(s.fractions)
    outcomes = np.empty(n_test, int)
    d2_min, d2_thr = np.empty(n_test), np.empty(n_test)
    errs = np.full((3, n_test), np.nan)
    p_out, p_phase = np.empty((n_test, n_f), int), np.full((n_test, n_f), np.nan)
    p_guess = np.empty((n_test, n_f), int)
    Phi_r = cfg.basis_robot.phi_uniform(s.n_steps)
    first, share, executed = np.full(n_test, UNKNOWN), np.full(n_test, np.nan), np.empty(n_test, int)
    rest = np.zeros(n_test, bool)
    for i, d in enumerate(ctx.test):
        rec = lib.recognize(d.human, observed_fraction=1.0)
        outcomes[i] = lab.outcome(rec.component, d.task, rec.status)
        j = int(np.argmin(rec.mahalanobis_sq))
        d2_min[i], d2_thr[i] = rec.mahalanobis_sq[j], chi2_ppf(cfg.novelty_quantile, int(np.max(rec.dof)))
        if rec.status == "skill":
            mean, _ = lib.predict_robot(d.human, observed_fraction=1.0, component=rec.component, n_steps=s.n_steps,
                                        restart=rec.restart)
            c = lib.component(rec.component)
            prior = Phi_r @ np.asarray(c.mean[c.n_human:]).reshape(lib.dim_robot_, -1).T
            errs[:, i] = (_rms(mean, ctx.test_robot[i]), _rms(prior, ctx.test_robot[i]),
                          _rms(ctx.task_mean[d.task], ctx.test_robot[i]))
        for k, f in enumerate(s.fractions):
            end = prefix_end(d.human, ctx.workspace, f, cfg.resample_tolerance, **cfg.walk_options())
            r = lib.recognize(d.human[:end])
            p_out[i, k] = lab.outcome(r.component, d.task, r.status)
            p_guess[i, k] = lab.outcome(best_guess(r), d.task)
            if r.status == "skill":
                p_phase[i, k] = r.phase
        first[i], share[i], executed[i], rest[i] = replayed_commit(lab, d, ctx.workspace)
    labels = tuple(lab.label_of(c.id) for c in lib.components)
    return InteractionTrial(lib.n_components, outcomes, d2_min, d2_thr, errs[0], errs[1], errs[2], p_out, p_phase,
                            labels, first, share, executed, rest, p_guess)


@dataclass(frozen=True, eq=False)
class LooResult:
    """One held-out interaction and order of :func:`loo_trial`, per ratio of ``IPROMPS_RATIOS``."""

    #: CORRECT, WRONG, UNKNOWN or UNDECIDED: the library's answer on the first share of the samples.
    outcomes: np.ndarray
    #: CORRECT or WRONG: the forced choice (:func:`best_guess`).
    guess: np.ndarray
    #: Share of the person's path (the library's arc length) those samples cover.
    path_share: np.ndarray


def loo_trial(ctx: InteractionContext, item: tuple[int, int]) -> LooResult:
    """ipromps' protocol for one interaction: learn all the others, recognize its first shares of samples.

    ``item`` is (index into ``ctx.train + ctx.test``, order). The library (settings'
    ``library``, workspace the bounding box of the other interactions' human columns) learns
    every other interaction of both splits in a random order (the settings' ``teaching``); the
    held-out one is cut at the first ``int(r * T)`` of its ``T`` samples (at least 2) for each
    ratio ``r`` of :data:`IPROMPS_RATIOS` (a share of its time, as ipromps cuts it, not of its
    path) and recognized without a fraction. A beginning that has not moved yet (the library
    refuses it) counts as unknown, and its forced choice as wrong.
    """
    s = ctx.settings
    i, order = item
    demos = ctx.train + ctx.test
    held = demos[i]
    others = demos[:i] + demos[i + 1:]
    ws = workspace_of(others)
    cfg = replace(s.library, workspace=ws)
    rng = trial_rng(s.seed, i * 1000 + order, STREAM_LOO)
    lab = LabeledLibrary(cfg)
    for j in teaching_order([d.task for d in others], rng, s.teaching):
        lab.teach(others[j])
    lib = lab.library
    t_share, share = _path_share(held, ws, cfg)
    n = len(IPROMPS_RATIOS)
    out, guess, path = np.full(n, UNKNOWN), np.full(n, WRONG), np.empty(n)
    for k, ratio in enumerate(IPROMPS_RATIOS):
        end = max(2, int(ratio * len(held.t)))
        path[k] = float(np.interp(held.t[end - 1] - held.t[0], t_share, share))
        try:
            r = lib.recognize(held.human[:end])
        except StillMotionError:
            continue  # the wrist has not moved yet
        out[k] = lab.outcome(r.component, held.task, r.status)
        guess[k] = lab.outcome(best_guess(r), held.task)
    return LooResult(out, guess, path)


@dataclass(frozen=True, eq=False)
class UntaughtResult:
    """One left-out task and order of :func:`untaught_trial`, per interaction of that task (both splits)."""

    task: str
    #: The interactions shown (``Demonstration.name``), training split first.
    names: tuple
    #: WRONG, UNKNOWN or UNDECIDED: the whole motion recognized (``observed_fraction=1``).
    whole: np.ndarray
    #: WRONG (a skill was committed to while the motion went on) or UNKNOWN (none).
    first_commit: np.ndarray
    #: Share of the person's path done at the first commit (NaN: none).
    commit_fraction: np.ndarray
    #: The skill the robot executes at the end: WRONG, UNKNOWN or UNDECIDED.
    executed: np.ndarray


def untaught_trial(ctx: InteractionContext, item: tuple[int, int]) -> UntaughtResult:
    """A task the library was never taught: ``item`` is (index of the task in ``ctx.task_mean``, order).

    The library (settings' ``library``; workspace the bounding box of the taught interactions' human
    columns, as a robot deployed before the new task arrived would have it) learns the training
    interactions of every other task in a random order (the settings' ``teaching``); then every
    interaction of the left-out task, of both splits, is recognized as a whole motion and replayed through
    the controller's decision logic (:func:`replayed_commit`). No component carries the left-out task's name,
    so any skill answer is WRONG.
    """
    s = ctx.settings
    ti, order = item
    task = list(ctx.task_mean)[ti]
    taught = tuple(d for d in ctx.train if d.task != task)
    shown = tuple(d for d in ctx.train + ctx.test if d.task == task)
    ws = workspace_of(taught)
    lab = LabeledLibrary(replace(s.library, workspace=ws))
    rng = trial_rng(s.seed, ti * 1000 + order, STREAM_UNTAUGHT)
    for j in teaching_order([d.task for d in taught], rng, s.teaching):
        lab.teach(taught[j])
    n = len(shown)
    whole, first, share, executed = (np.empty(n, int), np.empty(n, int), np.full(n, np.nan), np.empty(n, int))
    for i, d in enumerate(shown):
        whole[i] = lab.classify(d.human, task)[0]
        first[i], share[i], executed[i], _ = replayed_commit(lab, d, ws)
    return UntaughtResult(task, tuple(d.name for d in shown), whole, first, share, executed)


def _path_share(demo: Demonstration, workspace: Workspace, cfg: LibraryConfig):
    from drake_skills.sim.demo import path_progress

    return path_progress(demo, workspace, cfg.resample_tolerance, **cfg.walk_options())


def _fractions(outcomes) -> list[float]:
    c, w, u, d = outcome_fractions(outcomes)
    return [c, w, d, u]  # in OUTCOMES order


def _fig(rep_rows, fractions, tasks, err_by_task, robot_units: str = "rad", forced=None):
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.4))
    a = np.array(rep_rows)  # (n_fractions, 4)
    colors = ("tab:green", "tab:red", "tab:orange", "0.6")
    bottom = np.zeros(len(fractions))
    width = 0.07
    for j, (name, c) in enumerate(zip(OUTCOMES, colors)):
        ax.bar(fractions, a[:, j], width, bottom=bottom, color=c, label=name)
        bottom += a[:, j]
    fx = sorted(IPROMPS_WRIST)
    ax.plot(fx, [IPROMPS_WRIST[f] for f in fx], "kD", label="ipromps, wrist only (correct)")
    if forced is not None:
        ax.plot(fractions, forced, "k--", marker=".", lw=1, label="forced choice (best_guess), correct")
    ax.set_xlabel("true fraction of the path observed")
    ax.set_ylabel("fraction of test interactions x orders")
    ax.set_title("Anticipation: recognize(prefix), phase estimated", fontsize=9)
    ax.set_ylim(0, 1.05)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=3)
    x = np.arange(len(tasks))
    for j, (name, c) in enumerate((("conditioned (predict_robot)", "tab:green"),
                                   ("recognized component's mean", "tab:blue"),
                                   ("task mean (oracle label)", "0.5"))):
        ax2.bar(x + (j - 1) * 0.27, [err_by_task[t][j] for t in tasks], 0.27, color=c, label=name)
    ax2.set_xticks(x, tasks, fontsize=8)
    ax2.set_ylabel(f"robot RMS error ({robot_units})")
    ax2.set_title("Robot response on recognized test interactions", fontsize=9)
    ax2.legend(fontsize=7)
    fig.tight_layout()
    return fig


def evaluate_interaction(settings: InteractionSettings, *, workers: int = 1, progress: bool = True,
                         figures: bool = True, context: InteractionContext | None = None) -> EvalReport:
    """Run the interaction evaluation and return its tables, figure and summary.

    Parameters
    ----------
    settings : InteractionSettings
    workers : int
        Processes for the orders (results do not depend on it).
    progress : bool
        tqdm progress bar on stderr.
    figures : bool
        Also draw the figure.
    context : InteractionContext, optional
        Already loaded splits (``settings.data`` is then only a label); default: load
        ``settings.data``.

    Returns
    -------
    EvalReport
        Tables ``recognition``, ``components``, ``response``, ``anticipation``,
        ``commits``, ``test_interactions``, ``loo`` (unless ``loo_orders`` is 0) and ``untaught``
        (unless ``untaught_orders`` is 0 or the file holds one task); figure ``interaction``.
    """
    s = settings
    ctx = context if context is not None else InteractionContext.of(s)
    trials = run_trials(interaction_trial, range(s.orders), ctx, workers=workers, desc="interaction: orders",
                        progress=progress)
    tasks = list(ctx.task_mean)
    test_tasks = np.array([d.task for d in ctx.test])
    out = np.stack([t.outcomes for t in trials])  # (orders, n_test)
    K = np.array([t.n_components for t in trials])

    rows = []
    for task in tasks + ["all"]:
        m = np.ones(len(ctx.test), bool) if task == "all" else test_tasks == task
        rows.append([task, int(m.sum()), *_fractions(out[:, m])])
    recognition = Table(["task", "test interactions", *OUTCOMES], rows,
                        caption=(f"Whole test interactions recognized (observed_fraction=1) by a library learned from "
                                 f"the {len(ctx.train)} training interactions, fractions over {s.orders} random "
                                 f"orders ({'task by task' if s.teaching == 'row' else 'interleaved'}) x test "
                                 f"interactions; human columns: {s.columns}."))
    ks = sorted(set(K.tolist()))
    components = Table(["components", *map(str, ks), "mean"],
                       [["fraction of orders", *[float(np.mean(K == k)) for k in ks], float(K.mean())]],
                       caption=f"Components after all {len(ctx.train)} training interactions "
                               f"({len(tasks)} tasks), over {s.orders} orders.")

    E = np.stack([np.stack([t.err_conditioned, t.err_component, t.err_task_mean]) for t in trials])  # (o, 3, n)
    rows, err_by_task = [], {}
    for task in tasks + ["all"]:
        m = np.ones(len(ctx.test), bool) if task == "all" else test_tasks == task
        e = E[:, :, m].transpose(1, 0, 2).reshape(3, -1)
        ok = np.isfinite(e[0])
        means = [float(e[j, ok].mean()) if ok.any() else float("nan") for j in range(3)]
        err_by_task[task] = means
        all_task_mean = [_rms(ctx.task_mean[d.task], r) for d, r in zip(ctx.test, ctx.test_robot) if
                         task in ("all", d.task)]
        rows.append([task, int(ok.sum()), *means, float(np.mean(all_task_mean))])
    u = s.robot_units
    response = Table(["task", "executed", f"conditioned ({u})", f"component mean ({u})", f"task mean, oracle ({u})",
                      f"task mean, all test ({u})"], rows,
                     caption=(f"Robot response error ({u}: the units of the file's robot columns): RMS error over "
                              "100 time steps and all robot columns against "
                              "the recorded robot, on the test interactions recognized as a skill (executed, "
                              "over orders); baselines on the same interactions: the recognized component's "
                              "unconditioned mean and the mean of the training interactions of the true task. "
                              "The last column is the task mean on every test interaction."))

    P = np.stack([t.prefix_outcomes for t in trials])  # (orders, n_test, n_f)
    Ph = np.stack([t.prefix_phases for t in trials])
    G = np.stack([t.prefix_guess for t in trials])
    rows, frac_rows = [], []
    for k, f in enumerate(s.fractions):
        fr = _fractions(P[:, :, k])
        frac_rows.append(fr)
        ph = Ph[:, :, k]
        ph = ph[np.isfinite(ph)]
        est = float(ph.mean()) if ph.size else float("nan")
        err = float(np.mean(np.abs(ph - f))) if ph.size else float("nan")
        ref = IPROMPS_WRIST.get(round(f, 2))
        rows.append([f, *fr, est, err, float(np.mean(G[:, :, k] == CORRECT)), "-" if ref is None else ref])
    anticipation = Table(["observed", *OUTCOMES, "estimated phase (mean)", "phase error (mean |est - true|)",
                          "forced choice correct", "ipromps wrist-only correct"], rows,
                         caption=("Each test interaction cut at a true fraction of its path length (the library's "
                                  "arc length: normalized units, resample_tolerance), recognized WITHOUT "
                                  "observed_fraction (the phase is estimated). Phase over 'skill' answers. "
                                  "Forced choice: the most probable component that explains the beginning, or of "
                                  "all where none does (best_guess; a measurement, the robot never acts on it). "
                                  "ipromps: chenlx92/ipromps, 4 real handover tasks, leave-one-out, wrist only, "
                                  "always answers; its fraction is a share of time (see the table loo)."))
    loo = _loo_table(ctx, s, workers, progress) if s.loo_orders else None
    untaught = _untaught_table(ctx, s, workers, progress) if s.untaught_orders and len(tasks) > 1 else None

    D2 = np.stack([t.d2_min for t in trials])
    thr = np.stack([t.d2_threshold for t in trials])
    rows = [[d.name, d.task, *_fractions(out[:, i]), float(np.median(D2[:, i])), float(np.median(thr[:, i]))]
            for i, d in enumerate(ctx.test)]
    per_test = Table(["interaction", "task", *OUTCOMES, "median smallest d^2", "threshold"],
                     rows, caption="Per test interaction, over orders: the squared Mahalanobis distance to the "
                                   "closest component against the novelty threshold (chi-square quantile).")

    F = np.stack([t.first_commit for t in trials])
    S = np.stack([t.commit_fraction for t in trials])
    X = np.stack([t.executed for t in trials])
    R = np.stack([t.at_rest for t in trials])
    n_all = F.size
    committed = np.isfinite(S)
    first_wrong = float(np.sum(F == WRONG)) / n_all
    rows = []
    for task in tasks + ["all"]:
        m = np.ones(len(ctx.test), bool) if task == "all" else test_tasks == task
        f_, s_, x_ = F[:, m], S[:, m], X[:, m]
        c_ = np.isfinite(s_)
        n_c = int(c_.sum())
        rows.append([task, f_.size, n_c / f_.size, float(np.sum(f_ == CORRECT)) / max(n_c, 1),
                     float(np.sum(f_ == WRONG)) / max(n_c, 1),
                     float(np.mean(s_[c_])) if n_c else float("nan"),
                     float(np.median(s_[c_])) if n_c else float("nan"), float(R[:, m].mean()), *_fractions(x_)])
    commits = Table(["task", "trials", "committed", "first commit correct", "first commit wrong",
                     "mean path share at commit", "median path share at commit", "final answer at rest",
                     *(f"executed {o}" for o in OUTCOMES)], rows,
                    caption=("Test interactions replayed through the Drake controller's decision logic "
                             "(gating_step, default DecisionRule: re-decide every 1/16 s, commit after 2 equal "
                             "answers, final answer on the whole motion when the wrist rests, or at the 10 s "
                             "time-out for a recording that ends before it rests): the first commit (correct / "
                             "wrong over commits) and the share of the person's path done at it; 'final answer at "
                             "rest' is the share of trials whose final answer came from the wrist resting; "
                             "'executed' is the skill the robot runs at the end (a wrong commit revised in time is "
                             "not executed), over all trials."))

    rep = EvalReport("Real human-robot interactions", {
        "recognition": recognition, "components": components, "response": response,
        "anticipation": anticipation, "commits": commits, "test_interactions": per_test}
                    | ({"loo": loo[0]} if loo else {}) | ({"untaught": untaught[0]} if untaught else {}))
    c, w, d_, u = _fractions(out)
    allr = err_by_task["all"]
    rep.summary = {
        "settings": asdict(s) | {"library": s.library.dict()},
        "n_train": len(ctx.train), "n_test": len(ctx.test), "tasks": tasks,
        "correct": c, "wrong": w, "undecided": d_, "unknown": u,
        "components_mean": float(K.mean()), "components": K.tolist(),
        "response_error_conditioned": allr[0], "response_error_component_mean": allr[1],
        "response_error_task_mean": allr[2],
        "anticipation": {str(f): dict(zip(OUTCOMES, fr)) for f, fr in zip(s.fractions, frac_rows)},
        "commits": {"committed": float(committed.mean()),
                    "first_commit_wrong_of_commits": float(np.sum(F == WRONG)) / max(int(committed.sum()), 1),
                    "first_commit_wrong_of_trials": first_wrong,
                    "median_path_share_at_commit": float(np.median(S[committed])) if committed.any() else None,
                    "mean_path_share_at_commit": float(np.mean(S[committed])) if committed.any() else None,
                    "final_answer_at_rest": float(R.mean()),
                    "executed": dict(zip(OUTCOMES, _fractions(X)))},
        "forced_choice": {str(f): float(np.mean(G[:, :, k] == CORRECT)) for k, f in enumerate(s.fractions)},
        **({"loo": loo[1]} if loo else {}),
        **({"untaught": untaught[1]} if untaught else {}),
        "goals": {"correct >= 0.95": c >= 0.95, "wrong <= 0.02": w <= 0.02,
                  "4 <= components <= 6": bool(4 <= K.mean() <= 6),
                  "conditioned response below task mean": bool(allr[0] < allr[2])},
    }
    if figures:
        forced = [float(np.mean(G[:, :, k] == CORRECT)) for k in range(len(s.fractions))]
        rep.figures = {"interaction": _fig(frac_rows, np.array(s.fractions), tasks, err_by_task, s.robot_units,
                                           forced)}
    return rep


def _loo_table(ctx: InteractionContext, s: InteractionSettings, workers: int, progress: bool):
    """The table ``loo`` (ipromps' protocol, :func:`loo_trial`) and its summary entry."""
    demos = ctx.train + ctx.test
    items = [(i, o) for i in range(len(demos)) for o in range(s.loo_orders)]
    res = run_trials(loo_trial, items, ctx, workers=workers, desc="interaction: leave one out", progress=progress)
    O = np.stack([r.outcomes for r in res])  # (items, n_ratios)
    Gs = np.stack([r.guess for r in res])
    S = np.stack([r.path_share for r in res])
    rows, summary = [], {}
    for k, ratio in enumerate(IPROMPS_RATIOS):
        fr = _fractions(O[:, k])
        guess = float(np.mean(Gs[:, k] == CORRECT))
        ref = IPROMPS_WRIST.get(round(ratio, 2))
        rows.append([ratio, float(np.median(S[:, k])), float(np.mean(S[:, k] < 0.02)), guess,
                     "-" if ref is None else ref, *fr])
        summary[str(ratio)] = {"forced_choice_correct": guess, **dict(zip(OUTCOMES, fr)),
                               "median_path_share": float(np.median(S[:, k]))}
    table = Table(["observed share of samples (time)", "median share of the path", "path share below 2 %",
                   "forced choice correct", "ipromps wrist-only correct", *OUTCOMES], rows,
                  caption=(f"ipromps' protocol (chenlx92/ipromps, scripts/loocv_full.py): leave one out over all "
                           f"{len(demos)} interactions of the evaluation (both splits), {s.loo_orders} random "
                           f"orders of the other "
                           f"{len(demos) - 1} each (workspace: their bounding box), the held-out one cut at the "
                           "first share of its samples (time, not path) and recognized without a fraction. "
                           "Forced choice: best_guess, what a classifier that always answers would say (ipromps "
                           "does); the last four columns are the library's own answers. A recording that "
                           "starts at rest has covered little of its path at a small share of its time."))
    return table, summary


def _untaught_table(ctx: InteractionContext, s: InteractionSettings, workers: int, progress: bool):
    """The table ``untaught`` (:func:`untaught_trial`, every task left out in turn) and its summary entry."""
    tasks = list(ctx.task_mean)
    items = [(t, o) for t in range(len(tasks)) for o in range(s.untaught_orders)]
    res = run_trials(untaught_trial, items, ctx, workers=workers, desc="interaction: untaught tasks",
                     progress=progress)
    rows, summary = [], {}
    for task in tasks + ["all"]:
        mine = [r for r in res if task in ("all", r.task)]
        W = np.concatenate([r.whole for r in mine])
        F = np.concatenate([r.first_commit for r in mine])
        S = np.concatenate([r.commit_fraction for r in mine])
        X = np.concatenate([r.executed for r in mine])
        started = float(np.mean(F == WRONG))
        entry = {"motions": int(W.size), "whole_wrong": float(np.mean(W == WRONG)),
                 "whole_unknown": float(np.mean(W == UNKNOWN)), "whole_undecided": float(np.mean(W == UNDECIDED)),
                 "started": started,
                 "median_path_share_at_start": float(np.median(S[F == WRONG])) if (F == WRONG).any() else None,
                 "executed_wrong": float(np.mean(X == WRONG)), "executed_none": float(np.mean(X != WRONG))}
        summary[task] = entry
        rows.append([task, entry["motions"], entry["whole_wrong"], entry["whole_undecided"], entry["whole_unknown"],
                     started, "-" if entry["median_path_share_at_start"] is None
                     else entry["median_path_share_at_start"], entry["executed_wrong"]])
    table = Table(["task left out", "motions (x orders)", "whole: wrong", "whole: undecided", "whole: unknown",
                   "controller started a response", "median path share at the start", "controller executed a skill"],
                  rows,
                  caption=(f"A new task: each task left out of the training split in turn (random orders of the other "
                           f"tasks' training interactions: {s.untaught_orders} per task; workspace: their bounding box), and every "
                           "interaction of the left-out task, of both splits, shown to the library. The right answer is "
                           "'unknown' (ask for a demonstration). Whole: recognized as a whole motion "
                           "(observed_fraction=1). Controller: replayed through the decision logic (as the table "
                           "commits): 'started' is a commit to some skill while the person moved (the robot begins "
                           "that skill's response), 'executed' the skill it runs at the end (a start revised in time "
                           "is not executed)."))
    return table, summary


def default_data_path() -> Path:
    """``buetepage_hr.npz`` in the shared data folder (see :func:`~drake_skills.data.interaction.shared_data_path`)."""
    from drake_skills.data.interaction import shared_data_path

    return shared_data_path("buetepage_hr.npz")
