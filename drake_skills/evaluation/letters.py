"""The letter experiment of Sec. 4.1 (Figs. 3-4) on LASA handwriting shapes.

Protocol (one *trial* = one random order of all demonstrations):

1. Draw a random permutation of the ``n_shapes x n_demos`` demonstrations.
2. For ``k = 1 .. n_demos`` samples per class, the stream is the permutation
   restricted to the first ``k`` demonstrations of each shape (in permutation
   order), so the streams are nested and each one is presented in random order.
3. Fold the stream into a fresh :class:`SkillLibrary` (``LettersSettings.library``,
   default :class:`LibraryConfig`; workspace = the bounding box of all letters).
4. Encode the same demonstrations with ``lib.encode`` (the library's own
   weight space) and fit the labeled maximum-likelihood baseline
   (:func:`labeled_ml`) and batch EM given the true number of shapes
   (:func:`batch_em`).
5. ``KL(baseline || model)`` by Monte Carlo (:func:`mc_kl_mixtures`) for the
   incremental library and for EM.

For letters the gating and expert spaces coincide (human-only data).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace

import numpy as np

from drake_skills.data.demonstration import Demonstration
from drake_skills.data.lasa import DEFAULT_LETTERS, lasa_workspace, load_lasa
from drake_skills.data.workspace import Workspace
from drake_skills.evaluation.common import (EvalReport, Table, count_distribution, fig_kl_vs_samples, nested_streams,
                                           run_trials, trial_rng)
from drake_skills.library.batch import batch_em, labeled_ml
from drake_skills.library.incremental import LibraryConfig, SkillLibrary
from drake_skills.promp.gaussian import mc_kl_mixtures

STREAM_LETTERS = 1


@dataclass
class LettersSettings:
    """Settings of the letter experiment (the paper: 5 letters, 7 demos each, 100 orders)."""

    #: LASA shape names (default: drake_skills.data.lasa.DEFAULT_LETTERS).
    shapes: tuple[str, ...] | None = None
    #: Demonstrations per shape (1..7).
    n_demos: int = 7
    #: Random orders (the paper: 100).
    trials: int = 100
    #: Monte-Carlo samples per KL estimate.
    kl_samples: int = 2000
    #: EM restarts per fit.
    em_n_init: int = 5
    #: Numbers of demonstrations after which Fig. 3 draws the library.
    snapshots: tuple[int, ...] = (1, 5, 15, 35)
    #: Experiment seed.
    seed: int = 0
    #: Settings of every library (its workspace is replaced by the letters' bounding box).
    library: LibraryConfig = field(default_factory=LibraryConfig)

    def __post_init__(self):
        for name, lo in (("trials", 1), ("kl_samples", 1), ("em_n_init", 1), ("n_demos", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or v < lo:
                raise ValueError(f"LettersSettings.{name} must be an integer >= {lo}, got {v!r}")
        if self.n_demos > 7:
            raise ValueError(f"LettersSettings.n_demos must be at most 7 (LASA has 7 per shape), got {self.n_demos}")
        if any(int(k) != k or k < 1 for k in self.snapshots):
            raise ValueError(f"LettersSettings.snapshots must be positive integers, got {self.snapshots!r}")
        if not isinstance(self.library, LibraryConfig):
            raise ValueError(f"LettersSettings.library must be a LibraryConfig, got {type(self.library).__name__}")


@dataclass(frozen=True, eq=False)
class LettersContext:
    """What every order reads: the letters, their bounding-box workspace, the shapes and the settings."""

    demos: tuple[Demonstration, ...]
    workspace: Workspace
    shapes: tuple[str, ...]
    settings: LettersSettings

    @classmethod
    def of(cls, settings: LettersSettings) -> "LettersContext":
        shapes = tuple(settings.shapes or DEFAULT_LETTERS)
        demos = load_lasa(shapes, n_demos=settings.n_demos)
        return cls(tuple(demos), lasa_workspace(demos), shapes, settings)


@dataclass(frozen=True, eq=False)
class LettersTrial:
    """One random order; arrays over k = 1..n_demos samples per class."""

    kl_incremental: np.ndarray
    kl_em: np.ndarray
    n_components: np.ndarray


def letters_trial(ctx: LettersContext, index: int) -> LettersTrial:
    """One random order: KL of the incremental library and of EM to the labeled baseline, per k."""
    s = ctx.settings
    demos, ws = ctx.demos, ctx.workspace
    n_shapes = len(ctx.shapes)
    rng = trial_rng(s.seed, index, STREAM_LETTERS)
    tasks = [d.task for d in demos]
    perm = rng.permutation(len(demos))
    kl_inc, kl_em, n_comp = [], [], []
    for stream in nested_streams(tasks, perm, s.n_demos):
        lib = SkillLibrary(replace(s.library, workspace=ws))
        for j in stream:
            lib.partial_fit(demos[j])
        W = np.stack([lib.encode(demos[j], ws) for j in stream])
        labels = [tasks[j] for j in stream]
        base = labeled_ml(W, labels).as_tuple()
        em = batch_em(W, n_shapes, random_state=int(rng.integers(2 ** 31 - 1)), n_init=s.em_n_init)
        kl_seed = int(rng.integers(2 ** 31 - 1))
        kl_inc.append(mc_kl_mixtures(base, lib.as_mixture("gating"), s.kl_samples, random_state=kl_seed))
        kl_em.append(mc_kl_mixtures(base, em.as_tuple(), s.kl_samples, random_state=kl_seed))
        n_comp.append(lib.n_components)
    return LettersTrial(np.array(kl_inc), np.array(kl_em), np.array(n_comp))


def _trajectory_band(lib, comp, dim: int, n: int = 100):
    """Mean and std over phase of dimension ``dim`` of a component's human trajectory."""
    cfg = lib.config
    N = cfg.n_basis_human
    Phi = cfg.basis_human.phi_uniform(n)  # (n, N)
    m = np.asarray(comp.mean_gating)[dim * N:(dim + 1) * N]
    S = np.asarray(comp.cov_gating)[dim * N:(dim + 1) * N, dim * N:(dim + 1) * N]
    var = np.einsum("ij,jk,ik->i", Phi, S, Phi)
    return Phi @ m, np.sqrt(np.maximum(var, 0.0))


def library_growth(ctx: LettersContext, order_seed: int) -> dict:
    """Learn one library in a random order and keep snapshots (Fig. 3).

    Returns
    -------
    dict: ``order`` (indices), ``snapshots`` {n_demos_seen: list of (mean_x, std_x, id)},
    ``samples`` (normalized resampled human paths of every demo, in order),
    ``n_components`` after each demonstration.
    """
    s = ctx.settings
    demos, ws = ctx.demos, ctx.workspace
    rng = trial_rng(order_seed, 0, STREAM_LETTERS + 100)
    order = rng.permutation(len(demos))
    lib = SkillLibrary(replace(s.library, workspace=ws))
    snaps, n_comp = {}, []
    wanted = set(min(k, len(demos)) for k in s.snapshots)
    for i, j in enumerate(order, start=1):
        lib.partial_fit(demos[j])
        n_comp.append(lib.n_components)
        if i in wanted:
            snaps[i] = [(*_trajectory_band(lib, c, 0), c.id) for c in lib.components]
    samples = [lib.human_samples(demos[j].human, workspace=ws) for j in order]
    return {"order": order, "snapshots": snaps, "samples": samples, "n_components": np.array(n_comp),
            "final": lib}


def _fig_growth(growth: dict):
    import matplotlib.pyplot as plt

    snaps = growth["snapshots"]
    keys = sorted(snaps)
    fig, axes = plt.subplots(2, len(keys), figsize=(3.2 * len(keys), 5.6), squeeze=False)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    z = np.linspace(0, 1, 100)
    for col, k in enumerate(keys):
        ax, ax2 = axes[0, col], axes[1, col]
        for y in growth["samples"][:k]:
            zz = np.linspace(0, 1, y.shape[0])
            ax.plot(zz, y[:, 0], color="0.6", lw=0.6)
            ax2.plot(y[:, 0], y[:, 1], color="0.4", lw=0.7)
        for mean, sd, cid in snaps[k]:
            c = colors[cid % len(colors)]
            ax.plot(z, mean, color=c, lw=1.6)
            ax.fill_between(z, mean - 2 * sd, mean + 2 * sd, color=c, alpha=0.25)
        ax.set_title(f"after {k} demos: {len(snaps[k])} components", fontsize=9)
        ax.set_xlabel("phase")
        ax2.set_xlabel("x (normalized, start at 0)")
        if col == 0:
            ax.set_ylabel("x (normalized)")
            ax2.set_ylabel("y (normalized)")
        ax2.set_aspect("equal", adjustable="datalim")
    fig.suptitle("Letters: library as it grows (x-dimension, mean ± 2 std; demos grey) - Fig. 3", fontsize=10)
    fig.tight_layout()
    return fig


def _fig_hist(counts, true_k):
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.5, 3.2))
    lo, hi = min(counts.min(), true_k) - 1, max(counts.max(), true_k) + 1
    ax.hist(counts, bins=np.arange(lo, hi + 1) + 0.5, color="tab:green", rwidth=0.85)
    ax.axvline(true_k, color="k", ls="--", lw=1, label=f"true K = {true_k}")
    ax.set_xlabel("components after all demonstrations")
    ax.set_ylabel("orders")
    ax.legend()
    fig.tight_layout()
    return fig


def evaluate_letters(settings: LettersSettings | None = None, *, workers: int = 1, progress: bool = True,
                     figures: bool = True) -> EvalReport:
    """Run the letter experiment and return its tables and figures.

    Parameters
    ----------
    settings : LettersSettings
    workers : int
        Processes for the trials (results do not depend on it).
    progress : bool
        tqdm progress bar on stderr.
    figures : bool
        Also draw the figures.

    Returns
    -------
    EvalReport
        Tables ``kl_vs_samples``, ``components`` and ``components_vs_samples``;
        figures ``kl_vs_samples`` (Fig. 4b), ``library_growth`` (Fig. 3),
        ``components_hist``.
    """
    s = settings if settings is not None else LettersSettings()
    ctx = LettersContext.of(s)
    n_shapes, n_total = len(ctx.shapes), len(ctx.demos)
    results = run_trials(letters_trial, range(s.trials), ctx, workers=workers, desc="letters: orders",
                         progress=progress)
    inc = np.stack([r.kl_incremental for r in results])  # (trials, n_demos)
    em = np.stack([r.kl_em for r in results])
    nc = np.stack([r.n_components for r in results])
    ks = np.arange(1, s.n_demos + 1)

    rows = []
    for i, k in enumerate(ks):
        rows.append([int(k), inc[:, i].mean(), inc[:, i].std(), np.median(inc[:, i]),
                     np.percentile(inc[:, i], 10), np.percentile(inc[:, i], 90),
                     em[:, i].mean(), em[:, i].std(), np.median(em[:, i]), nc[:, i].mean(),
                     float(np.mean(nc[:, i] == n_shapes))])
    kl_table = Table(
        ["samples per class", "KL inc mean", "KL inc std", "KL inc median", "KL inc p10", "KL inc p90",
         "KL EM mean", "KL EM std", "KL EM median", "components mean", f"P(K = {n_shapes})"],
        rows,
        caption=(f"KL(labeled ML || model) in nats (Monte Carlo, {s.kl_samples} samples from the baseline), "
                 f"in the library's weight space ({n_shapes} LASA shapes, {s.n_demos} demos each), over "
                 f"{s.trials} random orders. EM is given the true K = {n_shapes}."))
    final = nc[:, -1]
    bins = sorted(set(final.tolist()) | {n_shapes})
    comp_table = Table(["components"] + [str(b) for b in bins],
                       [["fraction of orders"] + count_distribution(final, bins)],
                       caption=f"Components found after all {n_total} demonstrations, over {s.trials} orders.")
    rep = EvalReport("Letters (Sec. 4.1)", {"kl_vs_samples": kl_table, "components": comp_table})
    rep.summary = {
        "settings": asdict(s) | {"shapes": list(ctx.shapes), "library": s.library.dict()},
        "kl_incremental_mean": inc.mean(axis=0).tolist(),
        "kl_em_mean": em.mean(axis=0).tolist(),
        "fraction_orders_true_K": float(np.mean(final == n_shapes)),
        "components_final_mean": float(final.mean()),
    }
    if figures:
        growth = library_growth(ctx, s.seed)
        kl = fig_kl_vs_samples(ks, inc, em, xlabel="samples per class",
                               title="Letters: KL to the labeled baseline (Fig. 4b)", std_bars=True)
        rep.figures = {"kl_vs_samples": kl, "library_growth": _fig_growth(growth),
                       "components_hist": _fig_hist(final, n_shapes)}
    return rep
