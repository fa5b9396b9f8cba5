"""The open-ended collaboration loop of the paper's Fig. 2, simulated.

A stream of trials: the person performs a task; the controller recognizes the
skill and the IIWA7 executes the conditioned response, or it answers
"unknown", holds still, and the trial's demonstration (human + robot) is
folded into the library with ``partial_fit``.  One Diagram serves every
trial: its context is reset and the simulation clock keeps running, so one
meshcat recording covers the whole run.
"""
from __future__ import annotations

import logging
import math
from dataclasses import asdict, dataclass, field

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram

from drake_skills.data.demonstration import Demonstration
from drake_skills.library.incremental import SkillLibrary
from drake_skills.library.labels import TaskVotes
from drake_skills.data.workspace import Workspace
from drake_skills.sim.config import SimConfig
from drake_skills.sim.diagram import DiagramHandles, build_diagram, configure_simulator
from drake_skills.sim.models import FLANGE_FRAME, IIWA7_JOINT_LIMITS, IIWA7_VELOCITY_LIMITS
from drake_skills.systems.wrist_source import WristTrial

log = logging.getLogger(__name__)

#: Trials start on multiples of this (s), so the 1/64 s updates keep their phase.
TRIAL_GRID = 1.0 / 64.0
#: The person's motion counts as over once this share of its path is done (for the lead time).
MOTION_DONE = 0.99


def _final_time(decision) -> float:
    """When the gating gave its final answer: its last re-decision (the whole-motion test), or the loss.

    ``GatingDecision.time`` is when the current component was set, i.e. the commit for a skill
    committed while the person moved (a cold review found it reported as the final decision).
    """
    return float(decision.time if decision.status == "lost" else decision.last_check)


@dataclass(frozen=True)
class TrialOutcome:
    """What the closed loop did in one trial (:meth:`CollaborationSim.run_trial`)."""

    #: The skill executed at the end (the final decision), None if the robot did not act.
    component: int | None
    #: The final answer: "skill", "unknown" or "undecided".
    status: str
    #: Simulation time of the final decision, relative to the trial start (s); NaN if none.
    decision_time: float
    #: Simulation time span of the trial (s).
    start_time: float
    end_time: float
    #: A conditioned trajectory was executed to the end.
    executed: bool
    #: Simulation time at which the robot's response started (the first commit; NaN if none).
    plan_start: float
    #: The skills the gating committed to, in order (the last is executed unless given up).
    commits: tuple = ()
    #: How often the committed skill was changed or given up.
    revisions: int = 0
    #: The gating's re-decisions (:class:`~drake_skills.systems.gating.Belief`), for plots.
    beliefs: tuple = ()


@dataclass
class TrialResult:
    """What happened in one trial (``trial`` counts from 1, as the console does)."""

    #: 1-based index in the stream.
    trial: int
    #: The task performed (the demonstration's label; the library never sees it).
    task: str
    #: Component id executed, or None (JSON null) when the robot did not act.
    component: int | None
    #: The final answer: "skill", "unknown" or "undecided".
    status: str
    #: "skill <id>", "unknown" or "undecided".
    decision: str
    #: The label the executed component was taught with (None when the robot did not act).
    recognized_task: str | None
    #: Had this task been taught before the trial?
    task_known: bool
    #: "right" (the right skill executed, or no action for an untaught task), "wrong" (another task's
    #: skill executed) or "asked" (no action for a taught task: unknown or undecided).
    outcome: str
    #: outcome == "right".
    correct: bool
    #: The demonstration was folded into the library after the trial.
    taught: bool
    #: Distance between the simulated flange at the end and the flange of the
    #: demonstration's final configuration (cm); NaN when the robot did not act.
    flange_error_cm: float
    #: RMS joint tracking error (rad) over the executed motion; NaN when the robot did not act.
    tracking_rms_rad: float
    #: Largest joint displacement from the trial's start pose (rad).
    max_displacement_rad: float
    #: All logged joint positions were inside the joint limits.
    within_limits: bool
    #: Largest joint speed of the command over the joint's velocity limit (<= 1: within).
    peak_speed_ratio: float
    #: Simulation time of the final decision, relative to the trial start (s).
    decision_delay: float
    #: Share of the person's path observed when the robot committed (NaN if it never did).
    decision_fraction: float
    #: Seconds from the robot starting its response to the person's motion ending (positive: before).
    lead_s: float
    #: Skills committed during the trial (labels), in order.
    commits: list
    #: A skill of another task was committed at some point (revised or not).
    wrong_commit: bool
    #: Probability of the best candidate at the final answer (0 when nothing explained the motion).
    confidence: float
    #: How often the committed skill was changed or given up.
    revisions: int
    #: Simulation time span of the trial (s).
    start_time: float
    end_time: float


@dataclass
class TrialLog:
    """Joint samples of one trial (every ``log_period``)."""

    times: np.ndarray
    q: np.ndarray
    q_desired: np.ndarray
    qd_desired: np.ndarray = field(default_factory=lambda: np.zeros((0, 7)))


@dataclass
class DemoSummary:
    """Figures of a whole run (``results`` holds one :class:`TrialResult` per trial)."""

    trials: int
    #: Trials whose task had been taught before, and the share of them answered with the right skill.
    known_trials: int
    accuracy_after_teaching: float
    #: Trials per outcome over the whole run: right / wrong skill executed / asked (unknown or undecided).
    right: int
    wrong: int
    asked: int
    #: Trials whose final answer was "unknown", and "undecided" (the robot held; the demo was taught).
    unknown: int
    undecided_at_rest: int
    #: Trials in which a wrong skill was committed at some point (then revised, or executed: see wrong).
    wrong_commits: int
    #: Trials in which the committed skill was changed or given up.
    revised: int
    #: Trials of a task not yet taught in which the robot started a response (committed to a skill of
    #: another task) before the final "unknown" stopped it, and the largest joint displacement of a
    #: trial of a task not yet taught (rad): what "asking for a demonstration" cost in motion.
    untaught_started: int
    untaught_max_displacement_rad: float
    #: Mean share of the person's path observed when the robot committed.
    mean_decision_fraction: float
    #: Mean seconds from the robot starting its response to the person's motion ending (positive: before).
    mean_lead_s: float
    #: Flange error at handover over the trials that executed the right skill (cm).
    mean_flange_error_cm: float
    max_flange_error_cm: float
    mean_tracking_rms_rad: float
    components: int
    within_limits: bool
    #: Largest commanded joint speed over its limit, over the run (<= 1: within).
    peak_speed_ratio: float
    simulated_seconds: float
    wall_seconds: float = float("nan")
    results: list = field(default_factory=list)

    def dict(self) -> dict:
        d = asdict(self)
        return _jsonable(d)


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return None if not math.isfinite(float(x)) else round(float(x), 6)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def path_progress(demo: Demonstration, workspace: Workspace, tolerance: float, *,
                  adapt_to_noise: bool = True, average_holds: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The demonstration's share of its path done over time, as the library measures paths.

    Along the walk of the whole motion (``adapt_to_noise``, ``average_holds``: the library's,
    default its defaults). With ``average_holds`` on a noisy motion a vertex is the mean of its
    samples and its time here that of its first sample (a rest: when the hand got there).
    For a noisy motion the library's own walk of a prefix can differ from the start of this
    one by a few percent of the path (``promp.preprocessing.prefix_samples``).

    Returns
    -------
    t : array, shape (M,)
        Times of the path's vertices, relative to the demonstration's start (s).
    share : array, shape (M,)
        Arc length done by then over the whole path length (0 to 1, non-decreasing).
    """
    from drake_skills.promp.preprocessing import vertex_path

    y = workspace.normalize(demo.human, subtract_start=False)
    idx, _, s = vertex_path(y, tolerance, adapt_to_noise=adapt_to_noise, average_holds=average_holds)
    return demo.t[idx] - demo.t[0], s / max(s[-1], 1e-12)


class CollaborationSim:
    """One Diagram and Simulator that run any number of trials against a (growing) library.

    Parameters
    ----------
    config : SimConfig
    library : SkillLibrary
        Shared with the diagram's gating and conditioner; taught by :meth:`teach`.
    workspace : Workspace
        The subject's workspace (Eq. 14).
    meshcat : Meshcat, optional
    """

    def __init__(self, config: SimConfig, library: SkillLibrary, workspace: Workspace,
                 meshcat: Meshcat | None = None):
        self.config = config
        self.library = library
        self.workspace = workspace
        self.diagram, self.handles = self._build(meshcat)
        self.simulator = configure_simulator(Simulator(self.diagram), config)   # SimConfig.integrator
        self.context = self.simulator.get_mutable_context()
        h: DiagramHandles = self.handles
        self._plant_context = h.plant.GetMyContextFromRoot(self.context)
        self._fk_context = h.controller_plant.CreateDefaultContext()
        self._fk_flange = h.controller_plant.GetFrameByName(FLANGE_FRAME)
        self._votes = TaskVotes()
        self.time = 0.0

    def _build(self, meshcat: Meshcat | None) -> tuple[Diagram, DiagramHandles]:
        """The Diagram and its handles (the LCM transport overrides this)."""
        return build_diagram(self.config, library=self.library, workspace=self.workspace, meshcat=meshcat)

    def _start_trial(self, demo: Demonstration, t0: float) -> None:
        """Reset the whole Diagram to a new trial of ``demo`` at time ``t0`` and initialize."""
        h, ctx = self.handles, self.context
        self.diagram.SetDefaultContext(ctx)
        ctx.SetTime(t0)
        self._set_wrist(demo, t0)
        self.simulator.Initialize()

    def _set_wrist(self, demo: Demonstration, t0: float) -> None:
        """The wrist source replays ``demo`` from ``t0``, through ``config.faults``'s tracker if any."""
        h, ctx = self.handles, self.context
        trial = WristTrial(demo.t, demo.human, t0)
        source_ctx = h.wrist_source.GetMyContextFromRoot(ctx)
        h.wrist_source.SetTrial(source_ctx, trial)
        faults = self.config.faults
        self._n_started = getattr(self, "_n_started", 0) + 1
        if faults.any:  # the same faults for the same seed and trial number
            from drake_skills.systems.wrist_faults import tracker_feed

            rng = np.random.default_rng([self.config.seed, self._n_started])
            h.wrist_source.SetFeed(source_ctx, tracker_feed(trial, faults, rng, margin=self._feed_margin()))

    def _feed_margin(self) -> float:
        """Seconds of tracker feed after a demonstration's end (the longest a trial can go on)."""
        cfg = self.config
        return cfg.decision.timeout + cfg.unknown_hold_time + cfg.settle_time + 1.0

    # ------------------------------------------------------------ helpers
    def flange_position(self, q: np.ndarray) -> np.ndarray:
        """p_WE of the flange at joint positions ``q`` (forward kinematics)."""
        cp = self.handles.controller_plant
        cp.SetPositions(self._fk_context, q)
        return cp.CalcRelativeTransform(self._fk_context, cp.world_frame(), self._fk_flange).translation()

    def simulated_flange_position(self) -> np.ndarray:
        """p_WE of the simulated robot now."""
        h = self.handles
        return h.plant.CalcRelativeTransform(self._plant_context, h.plant.world_frame(), h.flange).translation()

    def joint_positions(self) -> np.ndarray:
        return self.handles.plant.GetPositions(self._plant_context, self.handles.iiwa).copy()

    def label_of(self, component: int) -> str | None:
        """The task most demonstrations taught into ``component`` had."""
        return self._votes.label_of(component)

    # ------------------------------------------------------------- trials
    def run_trial(self, demo: Demonstration) -> tuple[TrialOutcome, TrialLog]:
        """Replay ``demo``'s wrist and let the closed loop answer it.

        The simulation advances in steps of ``config.log_period`` (joints logged
        at each) until the Diagram's ``trial_status`` says the trial is over, or
        at the latest the demonstration's duration plus the decision timeout plus
        the hold time.
        """
        cfg = self.config
        h = self.handles
        ctx = self.context
        t0 = math.ceil(self.time / TRIAL_GRID) * TRIAL_GRID
        self._start_trial(demo, t0)
        status_port = h.trial_monitor.GetOutputPort("trial_status")
        monitor_ctx = h.trial_monitor.GetMyContextFromRoot(ctx)
        source_port = h.trajectory_source.GetOutputPort("desired_state")
        source_ctx = h.trajectory_source.GetMyContextFromRoot(ctx)
        deadline = t0 + demo.duration + cfg.decision.timeout + cfg.unknown_hold_time + cfg.settle_time
        desired = source_port.Eval(source_ctx)
        times, qs, qds, vds = [t0], [self.joint_positions()], [desired[:7].copy()], [desired[7:].copy()]
        t = t0
        end_known = False
        while t < deadline - 1e-12:
            t = min(t + cfg.log_period, deadline)
            self.simulator.AdvanceTo(t)
            desired = source_port.Eval(source_ctx)
            times.append(t)
            qs.append(self.joint_positions())
            qds.append(desired[:7].copy())
            vds.append(desired[7:].copy())
            if not end_known:
                end = status_port.Eval(monitor_ctx).end_time
                if end is not None:
                    deadline, end_known = max(end, t), True
        self.time = t
        decision = h.gating.decision(h.gating.GetMyContextFromRoot(ctx))
        traj = h.conditioner.trajectory(h.conditioner.GetMyContextFromRoot(ctx))
        executed = decision.final and decision.component is not None and traj is not None
        outcome = TrialOutcome(component=decision.component if executed else None,
                               status=decision.status if decision.final else "unknown",
                               decision_time=_final_time(decision) - t0 if decision.final else float("nan"),
                               start_time=t0, end_time=t, executed=executed,
                               plan_start=float(decision.commit_time), commits=tuple(decision.commits),
                               revisions=int(decision.revisions), beliefs=tuple(decision.beliefs))
        return outcome, TrialLog(np.array(times), np.array(qs), np.array(qds), np.array(vds))

    def teach(self, demo: Demonstration) -> None:
        """Fold ``demo`` into the library (Algorithm 1) and keep the task labels of the components."""
        update = self.library.partial_fit(demo, workspace=self.workspace)
        self._votes.record(update, demo.task)
        log.info("taught %s: created %s updated %s merged %s deleted %s (K=%d)", demo.task, update.created,
                 update.updated, update.merged, update.deleted, self.library.n_components)

    def evaluate_trial(self, index: int, demo: Demonstration, outcome: TrialOutcome, trial_log: TrialLog,
                       task_known: bool) -> TrialResult:
        """Score one trial (before any teaching); ``index`` counts from 0, the result's ``trial`` from 1."""
        lower, upper = IIWA7_JOINT_LIMITS
        k = outcome.component
        q = trial_log.q
        displacement = float(np.max(np.abs(q - q[0]))) if len(q) else 0.0
        within = bool(((q >= lower - 1e-6) & (q <= upper + 1e-6)).all())
        speed = float(np.max(np.abs(trial_log.qd_desired) / IIWA7_VELOCITY_LIMITS)) if trial_log.qd_desired.size \
            else 0.0
        recognized_task = self.label_of(k) if k is not None else None
        if k is None:
            result = "right" if not task_known else "asked"
        else:
            result = "right" if recognized_task == demo.task else "wrong"
        flange_error = tracking = float("nan")
        if outcome.executed and demo.robot is not None:
            p_sim = self.simulated_flange_position()
            p_demo = self.flange_position(demo.robot[-1])
            flange_error = 100.0 * float(np.linalg.norm(p_sim - p_demo))
            mask = trial_log.times >= outcome.plan_start
            err = trial_log.q[mask] - trial_log.q_desired[mask]
            tracking = float(np.sqrt(np.mean(err ** 2))) if err.size else float("nan")
        fraction = lead = float("nan")
        if math.isfinite(outcome.plan_start):
            lib_cfg = self.library.config
            tp, share = path_progress(demo, self.workspace, lib_cfg.resample_tolerance, **lib_cfg.walk_options())
            t_commit = outcome.plan_start - outcome.start_time
            fraction = float(np.interp(t_commit, tp, share))
            t_done = float(tp[np.searchsorted(share, MOTION_DONE)])
            lead = t_done - t_commit
        labels = [self.label_of(c) for c in outcome.commits]
        wrong_commit = any(lab != demo.task for lab in labels)
        decision = "unknown" if outcome.status == "unknown" else (
            "undecided" if outcome.status == "undecided" or k is None else f"skill {k}")
        confidence = float(outcome.beliefs[-1].confidence) if outcome.beliefs else 0.0
        return TrialResult(index + 1, str(demo.task), k, outcome.status, decision, recognized_task, task_known,
                           result, result == "right", False, flange_error, tracking, displacement, within, speed,
                           outcome.decision_time, fraction, lead, labels, bool(wrong_commit), confidence,
                           outcome.revisions, outcome.start_time, outcome.end_time)


def trial_stream(demos: list[Demonstration], n_trials: int, rng: np.random.Generator) -> list[Demonstration]:
    """``n_trials`` demonstrations: the tasks in shuffled rounds, each demo used at most once per pass."""
    by_task: dict[str, list[Demonstration]] = {}
    for d in demos:
        by_task.setdefault(str(d.task), []).append(d)
    tasks = sorted(by_task)
    if not tasks:
        raise ValueError("no demonstrations to make trials from")
    pools = {t: list(rng.permutation(len(by_task[t]))) for t in tasks}
    out = []
    while len(out) < n_trials:
        for t in rng.permutation(tasks):
            if not pools[t]:
                pools[t] = list(rng.permutation(len(by_task[t])))
            out.append(by_task[t][pools[t].pop()])
            if len(out) == n_trials:
                break
    return out


def run_collaboration(config: SimConfig, demos: list[Demonstration], workspace: Workspace, *,
                      library: SkillLibrary | None = None, meshcat: Meshcat | None = None,
                      on_trial=None, make_sim=None) -> tuple[DemoSummary, SkillLibrary]:
    """Run the stream of trials of the paper's Fig. 2 against an (initially empty) library.

    Parameters
    ----------
    config : SimConfig
        ``trials`` and ``seed`` set the stream.
    demos : list of Demonstration
        The subject's demonstrations (with ``task`` labels and robot trajectories).
    workspace : Workspace
    library : SkillLibrary, optional
        Default: a new, empty one with ``config.library``.
    meshcat : Meshcat, optional
        If given, the whole run is recorded into its animation (the caller publishes it).
    on_trial : callable, optional
        Called with each :class:`TrialResult` and its :class:`TrialOutcome` as it is done
        (progress output, plots).
    make_sim : callable, optional
        ``make_sim(config, library, workspace, meshcat)`` -> a :class:`CollaborationSim`;
        default the class itself (the direct Diagram), e.g.
        :class:`~drake_skills.sim.lcm_demo.LcmCollaborationSim` for the LCM transport.

    Returns
    -------
    summary : DemoSummary
    library : SkillLibrary
    """
    import time as _time

    library = library if library is not None else SkillLibrary(config.library)
    rng = np.random.default_rng(config.seed)
    stream = trial_stream(demos, config.trials, rng)
    sim = (make_sim or CollaborationSim)(config, library, workspace, meshcat)
    if meshcat is not None:
        meshcat.StartRecording(config.meshcat.frames_per_second, False)
    taught_tasks: set[str] = set()
    results: list[TrialResult] = []
    wall0 = _time.perf_counter()
    for i, demo in enumerate(stream):
        outcome, trial_log = sim.run_trial(demo)
        result = sim.evaluate_trial(i, demo, outcome, trial_log, demo.task in taught_tasks)
        if result.component is None:  # unknown or undecided: the robot asked, the person shows it
            sim.teach(demo)
            taught_tasks.add(str(demo.task))
            result.taught = True
        results.append(result)
        if on_trial is not None:
            on_trial(result, outcome)
    wall = _time.perf_counter() - wall0
    if meshcat is not None:
        meshcat.StopRecording()
        rec = meshcat.get_mutable_recording()
        rec.set_autoplay(True)  # the page plays the run once and stays at its end
        rec.set_loop_mode(rec.LoopMode.kLoopOnce)
        rec.set_clamp_when_finished(True)
        meshcat.PublishRecording()
    known = [r for r in results if r.task_known]
    flange = np.array([r.flange_error_cm for r in results if r.correct and math.isfinite(r.flange_error_cm)])
    rms = np.array([r.tracking_rms_rad for r in results if math.isfinite(r.tracking_rms_rad)])
    fractions = [r.decision_fraction for r in results if r.component is not None and math.isfinite(r.decision_fraction)]
    leads = [r.lead_s for r in results if r.component is not None and math.isfinite(r.lead_s)]
    summary = DemoSummary(
        trials=len(results), known_trials=len(known),
        accuracy_after_teaching=float(np.mean([r.correct for r in known])) if known else float("nan"),
        right=sum(r.outcome == "right" for r in results), wrong=sum(r.outcome == "wrong" for r in results),
        asked=sum(r.outcome == "asked" for r in results),
        unknown=sum(r.status == "unknown" for r in results),
        undecided_at_rest=sum(r.status == "undecided" for r in results),
        wrong_commits=sum(r.wrong_commit for r in results), revised=sum(r.revisions > 0 for r in results),
        untaught_started=sum(bool(r.commits) for r in results if not r.task_known),
        untaught_max_displacement_rad=max((r.max_displacement_rad for r in results if not r.task_known),
                                          default=0.0),
        mean_decision_fraction=float(np.mean(fractions)) if fractions else float("nan"),
        mean_lead_s=float(np.mean(leads)) if leads else float("nan"),
        mean_flange_error_cm=float(flange.mean()) if flange.size else float("nan"),
        max_flange_error_cm=float(flange.max()) if flange.size else float("nan"),
        mean_tracking_rms_rad=float(rms.mean()) if rms.size else float("nan"),
        components=library.n_components, within_limits=all(r.within_limits for r in results),
        peak_speed_ratio=max((r.peak_speed_ratio for r in results), default=0.0),
        simulated_seconds=float(sim.time), wall_seconds=wall, results=[asdict(r) for r in results])
    return summary, library
