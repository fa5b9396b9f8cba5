"""Open-ended at scale (issue 19): one library for all 30 LASA shapes, and synthetic skills from 10 to 1000.

Two experiments, every library with the default :class:`LibraryConfig`:

* **LASA-30 in one library.** For each of ``lasa_orders`` orders: a random
  ``lasa_train`` of the 7 demonstrations of every shape are taught in one random
  order (components labeled by the majority task of the demonstrations they absorbed,
  :class:`~drake_skills.evaluation.labeled.LabeledLibrary`), the other demonstrations
  are recognized as whole motions (``observed_fraction=1``): correct / wrong /
  undecided / unknown, and the number of components against the 30 shapes.
* **Synthetic skills at K = 10 ... 1000** (:mod:`drake_skills.data.synthetic`: 3-D
  wrist paths at least ``separation`` apart with ``scatter`` within-skill deviation,
  7-joint robots), ``demos_per_skill`` demonstrations of each skill taught either
  interleaved (random order) or skill by skill (in a row); then one new demonstration
  of every skill recognized as a whole motion. Timed in the same process: the median
  ``partial_fit`` over the last third of the stream (the library at its full size),
  the median whole-motion recognition, and the median recognition of
  ``prefix_probes`` motion beginnings without a fraction (the phase estimated).

Timings are CPU time of the process (``time.process_time``) on one BLAS thread: on a
machine shared with other work the wall clock mostly measures the scheduler. Compare
them across K within one run (``drake-skills bench --suite scale`` gives the ratios the
goals are stated in, by wall clock and CPU time).
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from drake_skills.data.demonstration import Demonstration
from drake_skills.data.lasa import LASA_SHAPES, N_DEMOS, lasa_motions, lasa_workspace, load_lasa
from drake_skills.data.synthetic import skill_bank
from drake_skills.evaluation.common import EvalReport, Table, run_trials, stream_rng
from drake_skills.evaluation.labeled import CORRECT, UNDECIDED, UNKNOWN, WRONG, LabeledLibrary
from drake_skills.library.config import LibraryConfig

STREAM_LASA, STREAM_SYNTHETIC = 41, 42
#: The orders of the synthetic streams.
ORDERS = ("random", "row")
OUTCOMES = ("correct", "wrong", "undecided", "unknown")
#: What made or removed components while a synthetic library learned (columns of the synthetic table).
EVENTS = ("novel firsts", "novel repeats", "splits", "merges", "deletions")
_EVENTS_CAPTION = ("Where the components came from: a {}'s first demonstration novel, a later one novel, splits, "
                   "merges, deletions.")


@dataclass
class ScaleSettings:
    """Settings of the scale experiment (defaults: the issue's protocol)."""

    #: Random orders (and train/test splits) of LASA-30.
    lasa_orders: int = 3
    #: Demonstrations of each shape taught (the other ``7 - lasa_train`` are recognized).
    lasa_train: int = 4
    #: LASA shapes (None: all 30).
    lasa_shapes: tuple[str, ...] | None = None
    #: Keep every n-th LASA sample (1: all 1000).
    lasa_subsample: int = 1
    #: Numbers of synthetic skills.
    sizes: tuple[int, ...] = (10, 30, 100, 300, 1000)
    #: Orders of the synthetic streams: "random" (interleaved) and/or "row" (skill by skill).
    orders: tuple[str, ...] = ORDERS
    #: Demonstrations taught per synthetic skill.
    demos_per_skill: int = 3
    #: Smallest RMS distance between two synthetic skills' mean paths (normalized units).
    separation: float = 1.5
    #: Within-skill deviation of a synthetic demonstration (normalized units).
    scatter: float = 0.03
    #: Motion beginnings (fractions 0.3-0.9 of a taught skill) timed per synthetic library.
    prefix_probes: int = 100
    #: Experiment seed.
    seed: int = 0
    #: Settings of every library (LASA's workspace is set to the bounding box of each order's taught letters).
    library: LibraryConfig = field(default_factory=LibraryConfig)

    def __post_init__(self):
        for name, lo in (("lasa_orders", 0), ("lasa_train", 1), ("lasa_subsample", 1), ("demos_per_skill", 1),
                         ("prefix_probes", 0)):
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or v < lo:
                raise ValueError(f"ScaleSettings.{name} must be an integer >= {lo}, got {v!r}")
        if self.lasa_train >= N_DEMOS:
            raise ValueError(f"ScaleSettings.lasa_train must leave demonstrations to recognize (< {N_DEMOS}), "
                             f"got {self.lasa_train}")
        if not self.sizes or any(int(k) != k or k < 2 for k in self.sizes):
            raise ValueError(f"ScaleSettings.sizes must be integers >= 2, got {self.sizes!r}")
        unknown = [o for o in self.orders if o not in ORDERS]
        if unknown or not self.orders:
            raise ValueError(f"ScaleSettings.orders must be some of {ORDERS}, got {self.orders!r}")
        if not (self.separation > 0 and self.scatter >= 0):
            raise ValueError(f"ScaleSettings.separation must be > 0 and scatter >= 0, got {self.separation}, "
                             f"{self.scatter}")
        if not isinstance(self.library, LibraryConfig):
            raise ValueError(f"ScaleSettings.library must be a LibraryConfig, got {type(self.library).__name__}")
        self.sizes = tuple(int(k) for k in self.sizes)
        self.orders = tuple(self.orders)

    @classmethod
    def quick(cls, seed: int = 0) -> "ScaleSettings":
        """A reduced run (what the tests use): 6 shapes, 1 order, K = 10 and 30."""
        return cls(lasa_orders=1, lasa_shapes=tuple(LASA_SHAPES[:6]), lasa_subsample=4, sizes=(10, 30),
                   prefix_probes=10, seed=seed)


@dataclass(frozen=True, eq=False)
class LasaContext:
    """The letters every LASA order reads (each order's workspace is the box of the ones it teaches)."""

    demos: tuple[Demonstration, ...]
    settings: ScaleSettings
    #: Each demonstration's motion (:func:`~drake_skills.data.lasa.lasa_motions`).
    motions: tuple[str, ...] = ()

    def __post_init__(self):
        if not self.motions:
            object.__setattr__(self, "motions", lasa_motions(self.demos))


@dataclass(frozen=True)
class LasaTrial:
    """One order of LASA-30: components and the outcome counts of the held-out demonstrations."""

    components: int
    #: correct, wrong, undecided, unknown
    counts: tuple[int, int, int, int]
    #: What made or removed components (:data:`EVENTS`, as for the synthetic libraries).
    events: dict = field(default_factory=dict)
    #: Shape -> components whose demonstrations are mostly of that shape (0: it has none of its own).
    per_shape: dict = field(default_factory=dict)
    #: Shape -> outcome counts (correct, wrong, undecided, unknown) of its held-out demonstrations.
    per_shape_counts: dict = field(default_factory=dict)
    #: Motions (:func:`~drake_skills.data.lasa.lasa_motions`) among the taught demonstrations.
    motions_taught: int = 0
    #: ``counts`` by motion: "unknown" for a held-out demonstration whose motion no taught one draws counts as
    #: correct (the library was not shown it; a Multi_Models shape's motion can be held out whole).
    counts_by_motion: tuple[int, int, int, int] = (0, 0, 0, 0)
    #: Shape -> its motions among the taught demonstrations.
    per_shape_motions: dict = field(default_factory=dict)


def is_multi_model(shape: str) -> bool:
    """A LASA ``Multi_Models_*`` shape: several motions under one name, some of them other shapes' patterns."""
    return shape.startswith("Multi_Models")


def _count(outcomes) -> tuple[int, int, int, int]:
    o = np.asarray(outcomes)
    return tuple(int(np.sum(o == k)) for k in (CORRECT, WRONG, UNDECIDED, UNKNOWN))


def lasa_trial(ctx: LasaContext, index: int) -> LasaTrial:
    """Teach a random ``lasa_train`` of every shape in one random order, recognize the rest."""
    s = ctx.settings
    rng = stream_rng(s.seed, STREAM_LASA, index)
    by_shape: dict[str, list[int]] = {}
    for i, d in enumerate(ctx.demos):
        by_shape.setdefault(d.task, []).append(i)
    train, test = [], []
    for idx in by_shape.values():
        perm = rng.permutation(idx)
        train += perm[:s.lasa_train].tolist()
        test += perm[s.lasa_train:].tolist()
    # the bounding box of the taught demonstrations only: the held-out ones must not set the units
    # (an audit found the box of all 210 used; it moved by at most 2 mm of ~98 mm)
    ws = lasa_workspace([ctx.demos[j] for j in train])
    lab = LabeledLibrary(replace(s.library, workspace=ws))
    events, seen = dict.fromkeys(EVENTS, 0), set()
    for j in rng.permutation(train):
        tally_events(events, lab.teach(ctx.demos[j]), repeat=ctx.demos[j].task in seen)
        seen.add(ctx.demos[j].task)
    outcomes = [lab.classify(ctx.demos[j].human, ctx.demos[j].task)[0] for j in test]
    taught = {ctx.motions[j] for j in train}
    by_motion = [CORRECT if o == UNKNOWN and ctx.motions[j] not in taught else o for o, j in zip(outcomes, test)]
    per_shape = dict.fromkeys(by_shape, 0)
    for c in lab.library.components:
        per_shape[lab.label_of(c.id)] += 1
    per_counts = {k: _count([o for o, j in zip(outcomes, test) if ctx.demos[j].task == k]) for k in by_shape}
    per_motions = {k: len({ctx.motions[j] for j in train if ctx.demos[j].task == k}) for k in by_shape}
    return LasaTrial(lab.library.n_components, _count(outcomes), events, per_shape, per_counts, len(taught),
                     _count(by_motion), per_motions)


@dataclass(frozen=True)
class SyntheticTrial:
    """One synthetic library: components found, outcomes of one new demonstration per skill, timings (ms)."""

    n_skills: int
    order: str
    components: int
    counts: tuple[int, int, int, int]
    ms_update: float
    ms_recognize: float
    ms_prefix: float
    #: Where the components came from: first demonstrations of a skill that made a component, later
    #: ones that did (novel repeats), splits and merges (components = first + repeats + splits - merges
    #: - deletions).
    events: dict = field(default_factory=dict)


def tally_events(events: dict, update, *, repeat: bool) -> dict:
    """Add what one ``partial_fit`` (an :class:`~drake_skills.library.views.Update`) did to ``events`` (keys
    :data:`EVENTS`): components it created (a skill's first demonstration or a later one), splits, merges and
    deletions."""
    events["novel repeats" if repeat else "novel firsts"] += len(update.created)
    events["splits"] += len(update.split)
    events["merges"] += len(update.merged)
    events["deletions"] += len(update.deleted)
    return events


def synthetic_trial(settings: ScaleSettings, item: tuple[int, str]) -> SyntheticTrial:
    """Teach ``demos_per_skill`` demonstrations of ``K`` synthetic skills in ``order``, then recognize and time."""
    K, order = item
    s = settings
    rng = stream_rng(s.seed, STREAM_SYNTHETIC, K, ORDERS.index(order))
    bank = skill_bank(K, rng, separation=s.separation)
    labels = np.repeat(np.arange(K), s.demos_per_skill)
    if order == "random":
        labels = rng.permutation(labels)
    lab = LabeledLibrary(s.library)
    times = []
    seen = np.zeros(K, bool)
    events = dict.fromkeys(EVENTS, 0)
    for k in labels:
        demo = bank.demo(int(k), rng, scatter=s.scatter)
        t0 = time.process_time()
        update = lab.teach(demo)
        times.append(time.process_time() - t0)
        tally_events(events, update, repeat=bool(seen[k]))
        seen[k] = True
    lib = lab.library
    outcomes, rec_times = [], []
    for k in range(K):
        demo = bank.demo(k, rng, scatter=s.scatter)
        t0 = time.process_time()
        rec = lib.recognize(demo.human, observed_fraction=1.0)
        rec_times.append(time.process_time() - t0)
        outcomes.append(lab.outcome(rec.component, demo.task, rec.status))
    prefix_times = []
    for _ in range(s.prefix_probes):
        human = bank.demo(int(rng.integers(K)), rng, scatter=s.scatter).human
        part = human[: max(5, int(rng.uniform(0.3, 0.9) * len(human)))]
        t0 = time.process_time()
        lib.recognize(part)
        prefix_times.append(time.process_time() - t0)
    tail = times[-max(1, len(times) // 3):]
    return SyntheticTrial(K, order, lib.n_components, _count(outcomes), 1e3 * float(np.median(tail)),
                          1e3 * float(np.median(rec_times)),
                          1e3 * float(np.median(prefix_times)) if prefix_times else float("nan"), events)


def _fractions(counts) -> list[float]:
    c = np.asarray(counts, float)
    return (c / max(c.sum(), 1.0)).tolist()


def _fig(synth: list[SyntheticTrial], lasa_components: float | None, n_shapes: int):
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(14, 4.0))
    styles = {"random": ("o-", "interleaved (random order)"), "row": ("s--", "in a row")}
    sizes = sorted({t.n_skills for t in synth})
    ax = axes[0]
    for order, (st, label) in styles.items():
        rows = sorted((t for t in synth if t.order == order), key=lambda t: t.n_skills)
        if rows:
            ax.plot([t.n_skills for t in rows], [t.components for t in rows], st, label=label)
    ax.plot(sizes, sizes, color="0.5", lw=0.8, label="components = skills")
    if lasa_components is not None:
        ax.plot([n_shapes], [lasa_components], "*", ms=12, color="tab:red", label=f"LASA-{n_shapes} (mean)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("skills taught")
    ax.set_ylabel("components found")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, which="both")
    ax = axes[1]
    colors = dict(zip(OUTCOMES, ("tab:green", "tab:red", "tab:orange", "tab:gray")))
    for order, (st, _) in styles.items():
        rows = sorted((t for t in synth if t.order == order), key=lambda t: t.n_skills)
        if not rows:
            continue
        fr = np.array([_fractions(t.counts) for t in rows])
        for j, name in enumerate(OUTCOMES):
            ax.plot([t.n_skills for t in rows], fr[:, j], st, color=colors[name],
                    label=f"{name} ({order})" if order == "random" or j == 0 else None)
    ax.set_xscale("log")
    ax.set_ylim(-0.03, 1.03)
    ax.set_xlabel("skills taught")
    ax.set_ylabel("fraction of new demonstrations")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, which="both")
    ax = axes[2]
    for key, label, c in (("ms_update", "partial_fit", "tab:blue"), ("ms_recognize", "recognize (whole motion)",
                                                                     "tab:green"),
                          ("ms_prefix", "recognize (beginning, phase estimated)", "tab:purple")):
        for order, (st, _) in styles.items():
            rows = sorted((t for t in synth if t.order == order), key=lambda t: t.n_skills)
            if rows:
                ax.plot([t.n_skills for t in rows], [getattr(t, key) for t in rows], st, color=c,
                        label=label if order == "random" else None)
    ax.set_xscale("log")
    ax.set_ylim(bottom=0)
    ax.set_xlabel("skills taught")
    ax.set_ylabel("CPU ms per call (median)")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, which="both")
    fig.suptitle("One library for many skills (default LibraryConfig): components, answers, cost", fontsize=10)
    fig.tight_layout()
    return fig


def evaluate_scale(settings: ScaleSettings | None = None, *, progress: bool = True, figures: bool = True) -> EvalReport:
    """Run both experiments (sequentially, in this process, on one BLAS thread, so the timings compare).

    Returns
    -------
    EvalReport
        Tables ``lasa`` (one row per order and their mean) and ``synthetic`` (one
        row per K and order); figure ``scale``; summary with the headline numbers.
    """
    s = settings if settings is not None else ScaleSettings()
    shapes = tuple(s.lasa_shapes or LASA_SHAPES)
    rep = EvalReport("Scale: many skills in one library (issue 19)")
    summary: dict = {"settings": asdict(s) | {"library": s.library.dict(), "lasa_shapes": list(shapes)}}
    lasa_components = None
    if s.lasa_orders:
        demos = tuple(load_lasa(shapes, subsample=s.lasa_subsample))
        ctx = LasaContext(demos, s)
        trials = run_trials(lasa_trial, range(s.lasa_orders), ctx, desc="scale: LASA orders", progress=progress)
        rows = [[f"order {i}", t.components, t.motions_taught, *_fractions(t.counts),
                 _fractions(t.counts_by_motion)[0], *(t.events[e] for e in EVENTS)] for i, t in enumerate(trials)]
        comps = np.array([t.components for t in trials], float)
        motions = np.array([t.motions_taught for t in trials], float)
        fr = np.array([_fractions(t.counts) for t in trials])
        fm = np.array([_fractions(t.counts_by_motion) for t in trials])
        ev = np.array([[t.events[e] for e in EVENTS] for t in trials], float)
        rows.append(["mean", float(comps.mean()), float(motions.mean()), *fr.mean(axis=0).tolist(),
                     float(fm[:, 0].mean()), *ev.mean(axis=0).tolist()])
        lasa_components = float(comps.mean())
        rep.tables["lasa"] = Table(
            ["order", "components", "motions taught"] + list(OUTCOMES) + ["correct by motion"] + list(EVENTS), rows,
            caption=(f"LASA-{len(shapes)} in one library: {s.lasa_train} of the {N_DEMOS} demonstrations of every "
                     f"shape taught in one random order, the other {N_DEMOS - s.lasa_train} recognized as whole "
                     f"motions (fractions of {len(shapes) * (N_DEMOS - s.lasa_train)}); {len(shapes)} shapes. "
                     "Motions taught: the distinct motions among the taught demonstrations (a Multi_Models shape is "
                     "two or three motions from different starting points, drake_skills.data.lasa.lasa_motions; "
                     "one of them may be held out whole). Correct by motion: correct, or \"unknown\" for a "
                     "held-out demonstration of a motion no taught demonstration draws. "
                     + _EVENTS_CAPTION.format("shape")))
        counts = {k: [t.per_shape[k] for t in trials] for k in shapes}
        held = {k: np.sum([t.per_shape_counts[k] for t in trials], axis=0) for k in shapes}
        motions_of = {k: [t.per_shape_motions[k] for t in trials] for k in shapes}
        rep.tables["lasa_shapes"] = Table(
            ["shape", "components (mean over orders)", "orders with exactly 1", "orders with 1 per motion taught"]
            + list(OUTCOMES),
            [[k, float(np.mean(v)), sum(x == 1 for x in v), sum(x == m for x, m in zip(v, motions_of[k])),
              *_fractions(held[k])] for k, v in counts.items()],
            caption=("Components per LASA shape: those whose taught demonstrations are mostly of the shape. The "
                     "Multi_Models shapes are multi-model motions, not single patterns (the dataset's naming), so "
                     "more than one component is a fair answer for them; 0: the shape's demonstrations joined another "
                     "shape's component. 1 per motion taught: as many components as the order taught the shape "
                     "motions (lasa_motions). Outcomes: the shape's held-out demonstrations over all orders (a "
                     "Multi_Models shape reuses other shapes' patterns, e.g. a trapezoid: its motion is then taught "
                     "under two names)."))
        single = [k for k in shapes if not is_multi_model(k)]
        single_fr = _fractions(np.sum([held[k] for k in single], axis=0)) if single else [None] * len(OUTCOMES)
        if single and len(single) < len(shapes):
            rep.tables["lasa"].caption += (
                f" The {len(single)} single-pattern shapes (all but Multi_Models) over all orders: "
                + ", ".join(f"{o} {v:.3f}" for o, v in zip(OUTCOMES, single_fr)) + ".")
        summary["lasa"] = {"shapes": len(shapes), "components_mean": lasa_components,
                           "components_per_shape": counts, "motions_per_shape": motions_of,
                           **{f"{k}_mean": float(v) for k, v in zip(OUTCOMES, fr.mean(axis=0))},
                           "motions_taught_mean": float(motions.mean()),
                           **{f"by_motion_{k}_mean": float(v) for k, v in zip(OUTCOMES, fm.mean(axis=0))},
                           "single_pattern_shapes": len(single),
                           **{f"single_pattern_{k}": v for k, v in zip(OUTCOMES, single_fr)},
                           "components_per_order": comps.tolist(),
                           "events_per_order": [dict(t.events) for t in trials]}
    items = [(K, order) for K in s.sizes for order in s.orders]
    synth = run_trials(synthetic_trial, items, s, desc="scale: synthetic libraries", progress=progress)
    rows = [[t.n_skills, t.order, t.components, *_fractions(t.counts), t.ms_update, t.ms_recognize, t.ms_prefix,
             *(t.events[e] for e in EVENTS)] for t in synth]
    rep.tables["synthetic"] = Table(
        ["skills", "order", "components"] + list(OUTCOMES) + ["CPU ms per update", "CPU ms per recognition",
                                                               "CPU ms per prefix recognition"] + list(EVENTS), rows,
        caption=(f"Synthetic 3-D wrist skills with 7-joint robots (paths >= {s.separation} apart, scatter "
                 f"{s.scatter}), {s.demos_per_skill} demonstrations each, interleaved (random) or in a row; one new "
                 f"demonstration per skill recognized as a whole motion. Median CPU ms of partial_fit over the "
                 f"last third of the stream, of whole-motion recognition, and of {s.prefix_probes} beginnings "
                 f"(30-90 %) recognized without a fraction (one process, one BLAS thread). "
                 + _EVENTS_CAPTION.format("skill")))
    summary["synthetic"] = [{"skills": t.n_skills, "order": t.order, "components": t.components,
                             **dict(zip(OUTCOMES, _fractions(t.counts))), "ms_update": t.ms_update,
                             "ms_recognize": t.ms_recognize, "ms_prefix": t.ms_prefix,
                             "events": dict(t.events)} for t in synth]
    rep.summary = summary
    if figures:
        rep.figures["scale"] = _fig(synth, lasa_components, len(shapes))
    return rep
