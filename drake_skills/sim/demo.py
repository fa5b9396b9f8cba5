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
from drake_skills.sim.diagram import DiagramHandles, build_diagram
from drake_skills.sim.models import FLANGE_FRAME, IIWA7_JOINT_LIMITS
from drake_skills.systems.wrist_source import WristTrial

log = logging.getLogger(__name__)

#: Trials start on multiples of this (s), so the 1/64 s updates keep their phase.
TRIAL_GRID = 1.0 / 64.0
#: ``TrialResult.component`` of an "unknown" answer (the JSON record keeps an int).
UNKNOWN = -1


@dataclass(frozen=True)
class TrialOutcome:
    """What the closed loop did in one trial (:meth:`CollaborationSim.run_trial`)."""

    #: The chosen component id, None for unknown.
    component: int | None
    #: Simulation time of the decision, relative to the trial start (s); NaN if none.
    decision_time: float
    #: Simulation time span of the trial (s).
    start_time: float
    end_time: float
    #: A conditioned trajectory was executed.
    executed: bool
    #: Simulation time at which it started (NaN if none).
    plan_start: float


@dataclass
class TrialResult:
    """What happened in one trial."""

    #: 0-based index in the stream.
    trial: int
    #: The task performed (the demonstration's label; the library never sees it).
    task: str
    #: Component id chosen by the gating, or -1 for unknown.
    component: int
    #: "skill <id>" or "unknown".
    decision: str
    #: The label the chosen component was taught with (None for unknown).
    recognized_task: str | None
    #: Had this task been taught before the trial?
    task_known: bool
    #: Unknown for a new task, or the right skill for a known one.
    correct: bool
    #: The demonstration was folded into the library after the trial.
    taught: bool
    #: Distance between the simulated flange at the end and the flange of the
    #: demonstration's final configuration (cm); NaN when the robot did not move.
    flange_error_cm: float
    #: RMS joint tracking error (rad) over the executed motion; NaN when unknown.
    tracking_rms_rad: float
    #: Largest joint displacement from the trial's start pose (rad).
    max_displacement_rad: float
    #: All logged joint positions were inside the joint limits.
    within_limits: bool
    #: Simulation time of the decision, relative to the trial start (s).
    decision_delay: float
    #: Simulation time span of the trial (s).
    start_time: float
    end_time: float


@dataclass
class TrialLog:
    """Joint samples of one trial (every ``log_period``)."""

    times: np.ndarray
    q: np.ndarray
    q_desired: np.ndarray


@dataclass
class DemoSummary:
    """Figures of a whole run."""

    trials: int
    #: Trials whose task had been taught before, and how many of them were recognized correctly.
    known_trials: int
    accuracy_after_teaching: float
    #: Trials answered "unknown" (and taught).
    unknown: int
    #: Trials that executed the skill of another task (for an untaught task too).
    wrong: int
    #: Flange error at handover over the trials that executed the right skill (cm).
    mean_flange_error_cm: float
    max_flange_error_cm: float
    mean_tracking_rms_rad: float
    components: int
    within_limits: bool
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
        self.simulator = Simulator(self.diagram)
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
        h.wrist_source.SetTrial(h.wrist_source.GetMyContextFromRoot(ctx), WristTrial(demo.t, demo.human, t0))
        self.simulator.Initialize()

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
        deadline = t0 + demo.duration + cfg.decision.timeout + cfg.unknown_hold_time
        times, qs, qds = [t0], [self.joint_positions()], [source_port.Eval(source_ctx)[:7].copy()]
        t = t0
        end_known = False
        while t < deadline - 1e-12:
            t = min(t + cfg.log_period, deadline)
            self.simulator.AdvanceTo(t)
            times.append(t)
            qs.append(self.joint_positions())
            qds.append(source_port.Eval(source_ctx)[:7].copy())
            if not end_known:
                end = status_port.Eval(monitor_ctx).end_time
                if end is not None:
                    deadline, end_known = end, True
        self.time = t
        decision = h.gating.decision(h.gating.GetMyContextFromRoot(ctx))
        traj = h.conditioner.trajectory(h.conditioner.GetMyContextFromRoot(ctx))
        outcome = TrialOutcome(component=decision.component if decision.decided else None,
                               decision_time=float(decision.time) - t0 if decision.decided else float("nan"),
                               start_time=t0, end_time=t, executed=traj is not None,
                               plan_start=traj.start_time if traj is not None else float("nan"))
        return outcome, TrialLog(np.array(times), np.array(qs), np.array(qds))

    def teach(self, demo: Demonstration) -> None:
        """Fold ``demo`` into the library (Algorithm 1) and keep the task labels of the components."""
        update = self.library.partial_fit(demo, workspace=self.workspace)
        self._votes.record(update, demo.task)
        log.info("taught %s: created %s updated %s merged %s deleted %s (K=%d)", demo.task, update.created,
                 update.updated, update.merged, update.deleted, self.library.n_components)

    def evaluate_trial(self, index: int, demo: Demonstration, outcome: TrialOutcome, trial_log: TrialLog,
                       task_known: bool) -> TrialResult:
        """Score one trial (before any teaching)."""
        lower, upper = IIWA7_JOINT_LIMITS
        k = UNKNOWN if outcome.component is None else outcome.component
        q = trial_log.q
        displacement = float(np.max(np.abs(q - q[0]))) if len(q) else 0.0
        within = bool(((q >= lower - 1e-6) & (q <= upper + 1e-6)).all())
        recognized_task = self.label_of(k) if k >= 0 else None
        correct = (k == UNKNOWN) if not task_known else (recognized_task == demo.task)
        flange_error = tracking = float("nan")
        if outcome.executed and demo.robot is not None:
            p_sim = self.simulated_flange_position()
            p_demo = self.flange_position(demo.robot[-1])
            flange_error = 100.0 * float(np.linalg.norm(p_sim - p_demo))
            mask = trial_log.times >= outcome.plan_start
            err = trial_log.q[mask] - trial_log.q_desired[mask]
            tracking = float(np.sqrt(np.mean(err ** 2))) if err.size else float("nan")
        return TrialResult(index, str(demo.task), k, "unknown" if k < 0 else f"skill {k}", recognized_task,
                           task_known, bool(correct), False, flange_error, tracking, displacement, within,
                           outcome.decision_time, outcome.start_time, outcome.end_time)


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
        Called with each :class:`TrialResult` as it is done (progress output).
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
        if result.component == UNKNOWN:
            sim.teach(demo)
            taught_tasks.add(str(demo.task))
            result.taught = True
        results.append(result)
        if on_trial is not None:
            on_trial(result)
    wall = _time.perf_counter() - wall0
    if meshcat is not None:
        meshcat.StopRecording()
        meshcat.PublishRecording()
    known = [r for r in results if r.task_known]
    flange = np.array([r.flange_error_cm for r in results if r.correct and math.isfinite(r.flange_error_cm)])
    rms = np.array([r.tracking_rms_rad for r in results if math.isfinite(r.tracking_rms_rad)])
    summary = DemoSummary(
        trials=len(results), known_trials=len(known),
        accuracy_after_teaching=float(np.mean([r.correct for r in known])) if known else float("nan"),
        unknown=sum(r.component == UNKNOWN for r in results),
        wrong=sum(r.component != UNKNOWN and not r.correct for r in results),
        mean_flange_error_cm=float(flange.mean()) if flange.size else float("nan"),
        max_flange_error_cm=float(flange.max()) if flange.size else float("nan"),
        mean_tracking_rms_rad=float(rms.mean()) if rms.size else float("nan"),
        components=library.n_components, within_limits=all(r.within_limits for r in results),
        simulated_seconds=float(sim.time), wall_seconds=wall, results=[asdict(r) for r in results])
    return summary, library
