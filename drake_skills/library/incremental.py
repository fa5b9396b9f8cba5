"""The incremental, open-ended skill library: the paper's Algorithm 1 on a learned scale.

A mixture of Interaction ProMPs learned one demonstration at a time. Each component
``k`` holds the exact moments of the stacked weights ``[w_h; w_r]`` of the
demonstrations it absorbed (support ``s_k``, mean, scatter), its age ``v_k``, the mean
duration and path length of its motions, and the same moments for two sub-clusters of
them. The algorithm is pure functions in :mod:`drake_skills.library.algorithm`, the
scale in :mod:`drake_skills.library.scale`, the tests in
:mod:`drake_skills.library.novelty`; this class encodes demonstrations, keeps the
state and answers queries.

Where it departs from the paper, and why (RESULTS.md has the measurements):

* **One learned scale instead of a fixed Sigma_init.** The paper's gating model gives
  each component its own covariance, started at a hand-set ``Sigma_init``; no fixed
  setting serves real data (every real demonstration became its own component, while
  30 letters merged). Here the gating judges every component with one within-skill
  covariance ``Sigma`` pooled from all components' scatter and borrowed by a component
  seen once (a hierarchical, Normal-inverse-Wishart-like prior whose scale matrix is
  learned online), with the uncertainty of the component's mean added:
  ``Sigma (1 + 1/s_k)``. Each expert (Eq. 8) keeps its own covariance, its scatter
  shrunk towards the shared one: ``(kappa Sigma + S_k) / (kappa + s_k - 1)``.
* **Exact running moments** (Eqs. 6-8): the printed Eqs. 7-8 drop a factor
  ``(1 - gamma)`` of the new scatter; ``gamma~`` (fast forgetting of ``Sigma_init``) is
  not needed once the initial covariance is the learned shared one.
* **Merging** (Eqs. 10-11): the moment-matched union (the printed Eq. 11 is garbled),
  when the two-sample distance of the means under ``Sigma`` is below a chi-square
  quantile; a merged component remembers the two it came from and **splits** again if
  they drift apart as the scale is learned (a merge made on an early, too-wide scale is
  not final).
* **Novelty and "unknown"** are one likelihood test, a chi-square quantile by default;
  recognition also answers **"undecided"** when more than one skill explains the
  motion and none is ``1 - decision_risk`` probable, and estimates from a prefix how
  much of each skill's motion it covers (its phase).
* **Deletion** by age and support, with the age limit growing with the number of
  components (``delete_min_age K / 5``), so that a library of many skills, each
  shown rarely, does not delete them before their second demonstration.

Two slips the library cannot undo later are warned about with :func:`warnings.warn`
(a :class:`~drake_skills.library.views.DataWarning`, at most once per library object
and kind; the library keeps working): a motion given without a workspace to a
library trained with one (:class:`~drake_skills.library.views.WorkspaceWarning`:
it is then compared in raw units and comes out "unknown"), and a motion far outside
the normalized range the settings assume (:class:`~drake_skills.library.views.UnitsWarning`,
see :data:`UNITS_RANGE`: metres or millimetres given without a workspace would
otherwise merge or split silently). Whether the library was trained with a workspace
is part of its state and of its file.

Cost against the number of components K (issue 19; ``drake-skills bench --suite
scale``): a step and a whole-motion recognition are a few matrix products over the
K whitened means plus work on the components that change. The queries (recognition,
prediction, the phase of a beginning) are in :mod:`drake_skills.library.recognition`.
"""
from __future__ import annotations

import logging
import warnings
from collections import OrderedDict
from functools import lru_cache
from typing import Sequence

import numpy as np

from drake_skills._checks import as_finite_array, check_fraction
from drake_skills.data.demonstration import Demonstration
from drake_skills.data.workspace import Workspace
from drake_skills.library.algorithm import ComponentModel, Components, Metric, fold_in, gating_metric
from drake_skills.library.bounded import put_bounded
from drake_skills.library.config import NOVELTY_TESTS, LibraryConfig, WorkspaceBounds
from drake_skills.library.gain import ConditioningGain
from drake_skills.library.guards import UNITS_RANGE, data_warning, robot_units_error, seen_robot_rms, units_error
from drake_skills.library.novelty import Chi2Rule, novelty_rule
from drake_skills.library.files import FileMixin
from drake_skills.library.recognition import RecognitionMixin, _Path
from drake_skills.library.scale import SharedScale, shared_covariance
from drake_skills.library.state import ComponentState, LibraryState
from drake_skills.library.storage import LibraryChangedError
from drake_skills.library.views import (Component, DataWarning, Recognition, StillMotionError, UnitsWarning,
                                        UnknownSkillError, Update, WorkspaceWarning)
from drake_skills.promp.basis import GaussianBasis, ridge_weights
from drake_skills.promp.interaction import InteractionProMP
from drake_skills.promp.preprocessing import (arc_length, despiked, noise_level, resample_in_time, restart_vertex,
                                              spike_samples, vertex_path)

#: Normalized motions (Eq. 14 and their path) a library keeps for queries about the same
#: samples: the gating, the conditioner and ``predict_robot`` ask about one prefix each tick.
PATH_MEMO = 4

__all__ = ["Component", "ComponentState", "DataWarning", "LibraryChangedError", "LibraryConfig", "LibraryState",
           "NOVELTY_TESTS", "Recognition", "SkillLibrary", "UNITS_RANGE", "UnitsWarning", "UnknownSkillError", "Update",
           "WorkspaceBounds", "WorkspaceWarning"]

log = logging.getLogger(__name__)


def _check_finite_step(step, w: np.ndarray, where: str) -> None:
    """Refuse an update whose arithmetic overflowed (finite but huge values): the library is not touched."""
    sc = step.scale
    ok = np.isfinite(sc.fit_m2) and all(np.isfinite(a).all() for a in (sc.total_mean, sc.total_m2, sc.pooled))
    if ok:
        comps = step.components
        touched = set(step.created) | set(step.updated) | {k for pair in step.merged for k in pair} | \
            {k for pair in step.split for k in pair}
        rows = np.flatnonzero(np.isin(comps.id_array, list(touched)))   # merged-away ids are gone: not found
        ok = all(np.isfinite(comps.items[i].cluster.mean).all() and np.isfinite(comps.items[i].cluster.factor).all()
                 for i in rows)
    if not ok:
        raise ValueError(f"{where}: its values are too large for the library's arithmetic (the update overflows; "
                         f"largest |weight| {np.abs(w).max():.3g}); check the units. The library is unchanged")


def _noise_note(human: np.ndarray, cfg: LibraryConfig) -> str:
    """Why a motion that moves has no path under ``adapt_to_noise``: it reads as tracker noise (else '')."""
    if not (cfg.adapt_to_noise and cfg.resample_tolerance > 0):
        return ""
    plain = arc_length(human, cfg.resample_tolerance)[1][-1]
    if not plain > 0:
        return ""
    return (f" once the walk adapts to tracker noise: its samples read as noise of {noise_level(human):.3g} "
            f"normalized units per axis, the plain path is {plain:.3g} ({human.shape[0]} samples: too few or too "
            f"far apart to tell motion from noise; give more samples per motion, or adapt_to_noise=False)")


@lru_cache(maxsize=8)
def _robot_gram(basis: GaussianBasis, n_samples: int) -> np.ndarray:
    """``Phi_r^T Phi_r`` over ``n_samples`` phases: the robot trajectory's metric of the gain fit (cached, read-only)."""
    Phi = basis.phi_uniform(n_samples)
    G = Phi.T @ Phi
    G.setflags(write=False)
    return G


def _read_only(a: np.ndarray) -> np.ndarray:
    v = a.view()
    v.setflags(write=False)
    return v


class SkillLibrary(RecognitionMixin, FileMixin):
    """An open-ended library of collaborative skills learned one demonstration at a time.

    Parameters
    ----------
    config : LibraryConfig, optional
        Hyperparameters; the defaults serve letters, the salad scenario and real
        human-robot interactions alike (nothing in them is a length in your units: human
        data are normalized by a workspace, Eq. 14). The library
        keeps a copy that cannot change (:meth:`LibraryConfig.sealed`): later changes
        to ``config`` do not reach it, and ``lib.config.ridge = ...`` raises.

    Threads: queries (``recognize``, ``estimate_phase``, ``predict_robot``) may run from
    several threads at once. Learning (``fit``, ``partial_fit``) replaces the
    components, the scale and the conditioning gain one after the other, so it must not overlap a query on the
    same library: hold a lock, or query a copy (``SkillLibrary.from_state(lib.state())``).

    Examples
    --------
    >>> lib = SkillLibrary()
    >>> for demo in stream:                       # doctest: +SKIP
    ...     update = lib.partial_fit(demo)
    >>> rec = lib.recognize(human)                # doctest: +SKIP
    >>> mean, cov = lib.predict_robot(human)      # doctest: +SKIP
    """

    def __init__(self, config: LibraryConfig | None = None):
        config = config if config is not None else LibraryConfig()
        if not isinstance(config, LibraryConfig):
            raise ValueError(f"config must be a LibraryConfig, got {type(config).__name__}")
        # a copy that cannot change: the novelty rule and the caches below are built from it
        self._config = config.sealed()
        self._rule = novelty_rule(self.config)
        self._origin: tuple[str, int] | None = None  # (file, generation) last loaded from or saved to
        self._reset()

    def _reset(self):
        self._components = Components()
        self._scale: SharedScale | None = None
        self._gain = ConditioningGain.empty(self.config.n_basis_robot)  # the fit of Eq. (13)'s gains (library.gain)
        self._history: list[dict] = []
        self._next_id = 0
        self._n_seen = 0
        self._shared = None  # cache: shared stacked covariance of the current scale
        self._with_workspace: bool | None = False  # None: unknown (a file written before it was kept)
        self._warned: set[str] = set()  # DataWarning kinds already issued by this object
        self._memo: dict = {}  # caches of one library version: name -> ((components, scale), value)
        self._paths: tuple = ()  # the last PATH_MEMO motions normalized: ((key, _Path), ...)
        self.dim_human_: int | None = None
        self.dim_robot_: int | None = None

    @property
    def config(self) -> LibraryConfig:
        """The library's settings, fixed when it was made (assigning a field raises ``AttributeError``)."""
        return self._config

    # ------------------------------------------------------------------ state
    def state(self) -> LibraryState:
        """A snapshot of everything learned (the library never writes its arrays in place)."""
        comps = tuple(ComponentState(c.id, self._n_seen - c.created, c.cluster, c.subclusters)
                      for c in self._components.items)
        return LibraryState(self.config, self.dim_human_, self.dim_robot_, self._next_id, self._n_seen, comps,
                            tuple(dict(e) for e in self._history), self._scale, self._with_workspace, self._gain)

    @classmethod
    def from_state(cls, state: LibraryState) -> "SkillLibrary":
        """The library of a :meth:`state` snapshot: it answers and keeps learning exactly as the original."""
        if not isinstance(state, LibraryState):
            raise ValueError(f"from_state takes a LibraryState, got {type(state).__name__}")
        lib = cls(state.config)
        lib._history = [dict(e) for e in state.history]
        lib._next_id, lib._n_seen = int(state.next_id), int(state.n_seen)
        lib._with_workspace = state.trained_with_workspace
        if state.gain is not None:
            lib._gain = state.gain
        if state.dim_human is not None:
            lib.dim_human_, lib.dim_robot_ = int(state.dim_human), int(state.dim_robot)
            lib._scale = state.scale
            lib._components = Components.of(
                [ComponentModel(c.id, lib._n_seen - int(c.age), c.cluster, tuple(c.subclusters))
                 for c in state.components], lib.n_human)
        return lib

    # ------------------------------------------------------------------ views
    @property
    def n_components(self) -> int:
        return len(self._components)

    @property
    def n_seen(self) -> int:
        """Number of demonstrations folded in so far."""
        return self._n_seen

    @property
    def components(self) -> tuple[Component, ...]:
        """Read-only views of the components (covariances are computed when first asked for)."""
        items = self._components.items
        if not items:
            return ()
        total = float(self._components.support.sum())
        h = self.n_human
        return tuple(self._view(c, total, h) for c in items)

    def _view(self, c: ComponentModel, total: float, h: int) -> Component:
        return Component(c.id, self._n_seen - c.created, c.support, c.support / total, _read_only(c.mean), h,
                         c.cluster.duration, c.cluster.path_length,
                         lambda: self._expert_cov(c), lambda: self._gating_cov() * (1.0 + 1.0 / c.support))

    @property
    def history(self) -> tuple[dict, ...]:
        """Creations, merges, splits and deletions, in order."""
        return tuple(dict(e) for e in self._history)

    @property
    def n_human(self) -> int:
        self._check_fitted()
        return self.dim_human_ * self.config.n_basis_human

    @property
    def has_robot(self) -> bool:
        return bool(self.dim_robot_)

    @property
    def trained_with_workspace(self) -> bool | None:
        """Whether a demonstration was folded in with a workspace (None: not known, an older file)."""
        return self._with_workspace

    def component(self, component_id: int) -> Component:
        """The component with this id (KeyError if there is none)."""
        c = self._model(component_id)
        return self._view(c, float(self._components.support.sum()), self.n_human)

    def _model(self, component_id: int) -> ComponentModel:
        if isinstance(component_id, (bool, np.bool_)) or not isinstance(component_id, (int, np.integer)):
            raise KeyError(f"component ids are integers, got {component_id!r}; ids are {list(self._components.ids)}")
        try:
            return self._components.items[self._components.index(component_id)]
        except (KeyError, TypeError):
            raise KeyError(f"no component with id {component_id}; ids are {list(self._components.ids)}") from None

    def shared_covariance(self, part: str = "gating") -> np.ndarray:
        """The learned within-skill covariance: of the gating weights (h, h) or the stacked weights (d, d).

        This is the scale of every novelty, merge and split decision
        (:mod:`drake_skills.library.scale`); a new component's expert starts from it.
        """
        self._check_fitted()
        if part == "gating":
            return self._gating_cov().copy()
        if part == "expert":
            return self._shared_cov().copy()
        raise ValueError(f"part must be 'gating' or 'expert', got {part!r}")

    def _shared_cov(self) -> np.ndarray:
        if self._shared is None or self._shared[0] is not self._scale:
            cfg = self.config
            S = shared_covariance(self._scale, self.n_human, prior_scale=cfg.prior_scale,
                                  prior_strength=cfg.prior_strength, shrinkage=cfg.shrinkage,
                                  prior_floor=cfg.prior_floor)
            S.setflags(write=False)
            self._shared = (self._scale, S)
        return self._shared[1]

    def _gating_cov(self) -> np.ndarray:
        h = self.n_human
        return self._shared_cov()[:h, :h]

    def _per_cluster(self, attr: str, c: ComponentModel, compute):
        """``compute()`` for component ``c``, kept in ``self.<attr>`` until the library learns (its scale changes).

        At most 64 entries (a few d x d matrices, not one per component of a large library), keyed by
        ``id(c.cluster)`` with the cluster itself kept beside the value: a freed cluster's id reused by a
        new one is not a hit. The entry is read once: another thread may evict it between two reads.
        """
        held = getattr(self, attr, (None,))
        if held[0] is not self._scale:
            held = (self._scale, OrderedDict())
            setattr(self, attr, held)
        cache = held[1]
        key = id(c.cluster)
        hit = cache.get(key)
        if hit is not None and hit[0] is c.cluster:
            return hit[1]
        value = compute()
        put_bounded(cache, key, (c.cluster, value), 64)
        return value

    def _expert_cov(self, c: ComponentModel) -> np.ndarray:
        """``(kappa Sigma + S_k) / (kappa + s_k - 1)``, kept until the library learns (a d x d product each)."""
        def compute():
            k = self.config.expert_prior
            C = (k * self._shared_cov() + c.cluster.scatter) / (k + c.support - 1.0)
            C = 0.5 * (C + C.T)
            C.setflags(write=False)
            return C
        return self._per_cluster("_expert_cache", c, compute)

    def _seen_blocks(self, c: ComponentModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Component ``c``'s human mean and covariance blocks as observed samples see them (through ``U = S^-1``,
        ``_unshrink_human``, see ``_prefix_model``): ``U mu_h``, ``U E_hh U^T``, ``E_rh U^T`` of its expert covariance ``E`` (read-only),
        kept as :meth:`_expert_cov` keeps ``E`` (every re-conditioning of a prefix asks for them again)."""
        def compute():
            h = self.n_human
            U = self._unshrink_human()
            E = self._expert_cov(c)
            blocks = (U @ c.mean[:h], U @ E[:h, :h] @ U.T, E[h:, :h] @ U.T)
            for a in blocks:
                a.setflags(write=False)
            return blocks
        return self._per_cluster("_seen_cache", c, compute)

    def _cached(self, name: str, compute):
        """``compute()`` once per version of the library (components and scale are immutable, so identity is version)."""
        key = (self._components, self._scale)
        hit = self._memo.get(name)
        if hit is not None and hit[0][0] is key[0] and hit[0][1] is key[1]:
            return hit[1]
        value = compute()
        self._memo[name] = (key, value)
        return value

    def _metric(self) -> Metric:
        """The gating metric of the current scale."""
        return self._cached("metric", lambda: gating_metric(self._scale, self.n_human, self.config))

    def _whitened_means(self) -> np.ndarray:
        """``L^{-1} mu_k`` of every component (K, h): a whole motion's distances are one product away."""
        return self._cached("whitened", lambda: self._metric().whiten(self._components.means_h))

    def as_mixture(self, part: str = "gating"):
        """The library as a Gaussian mixture ``(weights (K,), means (K, d), covs (K, d, d))``.

        ``part="gating"`` gives the mixture over human weights the gating judges with
        (Eq. 5: the shared covariance times ``1 + 1/s_k``); ``"expert"`` the one over
        stacked weights (Eq. 2).
        """
        self._check_fitted()
        if part not in ("gating", "expert"):
            raise ValueError(f"part must be 'gating' or 'expert', got {part!r}")
        items = self._components.items
        if not items:
            raise ValueError("the library has no components")
        s = self._components.support
        if part == "gating":
            G = self._gating_cov()
            covs = np.stack([G * (1.0 + 1.0 / c.support) for c in items])
            return s / s.sum(), self._components.means_h.copy(), covs
        return s / s.sum(), np.stack([c.mean for c in items]), np.stack([self._expert_cov(c) for c in items])

    def interaction_promp(self, component_id: int) -> InteractionProMP:
        """The Interaction ProMP of one component (a copy), with the library's moments as they are.

        Its weights are the ridge estimates the library keeps; :meth:`predict_robot` of
        the library compares a beginning's samples with the least-squares weights instead
        (the ridge's shrinkage undone, :meth:`_prefix_model`), so the two robot means
        differ by that shrinkage (about 1 % of the mean on synthetic skills). The library
        also scales Eq. (13)'s correction by its learned gains (:mod:`~drake_skills.library.gain`,
        ``config.conditioning_gain``); this ProMP conditions as the paper's Eq. (13).
        """
        c = self._model(component_id)
        cfg = self.config
        return InteractionProMP.from_moments(
            np.array(c.mean), self._expert_cov(c), self.dim_human_, self.dim_robot_,
            basis_human=cfg.basis_human, basis_robot=cfg.basis_robot, ridge=cfg.ridge,
            observation_noise=self._noise())

    def _check_fitted(self):
        if self.dim_human_ is None:
            raise ValueError("this SkillLibrary is not fitted yet: call partial_fit() with a demonstration first")

    def __repr__(self) -> str:
        return f"SkillLibrary(n_components={self.n_components}, n_seen={self.n_seen})"

    # --------------------------------------------------------- preprocessing
    def _normalized(self, human, workspace=None, normalized: bool = False, where: str | None = None) -> "_Path":
        """Eq. (14): the motion in normalized units relative to its start, with its path (see :class:`_Path`)."""
        cfg = self.config
        human = as_finite_array(human, "human", ndim=2, min_rows=2, where=where)
        if self.dim_human_ is not None and human.shape[1] != self.dim_human_:
            raise ValueError(f"{where + ': ' if where else ''}human has {human.shape[1]} columns, "
                             f"the library was built on {self.dim_human_}")
        key = (bool(normalized), workspace, human.shape, human.tobytes())
        for k, hit in self._paths:  # the gating, the conditioner and predict_robot ask about the same samples
            if k[0] == key[0] and k[1] is key[1] and k[2] == key[2] and k[3] == key[3]:
                return hit
        if normalized:
            if workspace is not None:
                raise ValueError("normalized samples take no workspace: Eq. (14) is already applied")
        else:
            ws = workspace if workspace is not None else cfg.workspace
            if ws is not None and not isinstance(ws, Workspace):
                raise ValueError(f"workspace must be a Workspace, got {type(ws).__name__}")
            if ws is not None:
                if ws.dim != human.shape[1]:
                    raise ValueError(f"workspace is {ws.dim}-D but human has {human.shape[1]} columns")
                human = ws.normalize(human, subtract_start=cfg.subtract_start)
            elif cfg.subtract_start:
                human = human - human[0]
        adapt = cfg.adapt_to_noise and cfg.resample_tolerance > 0
        if adapt:
            with np.errstate(over="ignore", invalid="ignore"):  # an overflowing path is refused in _walked
                glitches = spike_samples(human, cfg.resample_tolerance)
            if glitches.any():
                human = despiked(human, cfg.resample_tolerance, glitches=glitches)
                if glitches[0] and cfg.subtract_start:  # a glitch on the first sample would offset the
                    human = human - human[0]            # whole motion (Eq. 14's start)
        path = self._walked(np.array(human, dtype=float), where)  # a copy: the caller's array may change later
        self._paths = ((key, path),) + self._paths[:PATH_MEMO - 1]  # one assignment: safe across threads
        return path

    def _walked(self, human: np.ndarray, where: str | None, offset: int = 0) -> "_Path":
        """The path of normalized (and despiked) samples ``human`` (T, D): the walk and its checks."""
        cfg = self.config
        with np.errstate(over="ignore", invalid="ignore"):  # an overflowing path is refused just below
            indices, vertices, s = vertex_path(human, cfg.resample_tolerance,
                                               glitches_removed=cfg.adapt_to_noise and cfg.resample_tolerance > 0,
                                               **cfg.walk_options())
        if not np.isfinite(s[-1]):
            raise ValueError(f"{where + ': ' if where else ''}human positions are too large: their path length "
                             f"overflows (largest |value| {np.abs(human).max():.3g}); check the units and the workspace")
        if not s[-1] > 0:
            raise StillMotionError(f"{where + ': ' if where else ''}human trajectory does not move: its path length "
                                   f"is 0" + _noise_note(human, cfg))
        return _Path(human, vertices, s, indices, offset)

    def _restarted(self, path: "_Path", at: int | None = None) -> "_Path | None":
        """The reading of ``path`` from where it last set off from its start (``promp.preprocessing.restart_vertex``),
        or from its sample ``at``: the samples from there on, moved to begin where the motion began (Eq. 14 on them).
        None when the motion set off only once (or ``at`` is 0)."""
        if at is None:
            j = restart_vertex(path.vertices, self.config.resample_tolerance)
            at = int(path.indices[j]) if j else 0
        if not at:
            return None
        y = path.y[at:] - path.y[at] + path.y[0]
        return self._walked(y, None, path.offset + at)

    def path_length(self, human, *, workspace: Workspace | None = None, normalized: bool = False,
                    where: str | None = None) -> float:
        """Length of the human path in normalized units (the measure of a prefix's phase)."""
        return self._normalized(human, workspace, normalized, where).length

    # ----------------------------------------------------------- data guards
    def _warn_once(self, kind: str, category: type[DataWarning], message: str, stacklevel: int) -> None:
        if kind in self._warned:
            return
        self._warned.add(kind)
        warnings.warn(message + " (warned once per library)", category, stacklevel=stacklevel + 1)

    def _guard(self, y: np.ndarray, workspace, normalized: bool, *, whole: bool, query: bool,
               where: str | None, stacklevel: int = 3) -> None:
        """Warn about a missing workspace or data in other units (:func:`~drake_skills.library.guards.data_warning`)."""
        ws = workspace if workspace is not None else self.config.workspace
        found = data_warning(y, ws, normalized, whole=whole, query=query, where=where,
                             trained_with_workspace=self._with_workspace if self._n_seen else None)
        if found is not None:
            kind, category, message = found
            # once per kind for queries and once for teaching: a query's warning must not silence the
            # warning about a demonstration in other units, the one slip the library keeps
            self._warn_once(f"{kind}:{'query' if query else 'teach'}", category, message, stacklevel)

    def human_samples(self, human, *, workspace: Workspace | None = None, observed_fraction: float = 1.0,
                      normalized: bool = False, where: str | None = None) -> np.ndarray:
        """The human motion as the library sees it: Eq. (14), then resampled by arc length.

        Parameters
        ----------
        human : array, shape (T, D_h)
            Raw positions, or with ``normalized=True`` positions already in the
            library's normalized units (Eq. 14 applied: workspace normalization and,
            if ``config.subtract_start``, the start subtracted).
        workspace : Workspace, optional
            Overrides ``config.workspace``; not with ``normalized=True``.
        observed_fraction : float in (0, 1]
            The fraction of the whole motion's path that ``human`` covers.
        normalized : bool
            Only resample.
        where : str, optional
            Prefix of error messages (e.g. the demonstration's name).

        Returns
        -------
        samples : array, shape (n, D_h)
            Evenly spaced in phase over ``[0, observed_fraction]``; ``n = n_samples``
            for a whole motion, ``round(observed_fraction n_samples)`` (>= 2) for a prefix.
        """
        cfg = self.config
        f = check_fraction(observed_fraction)
        n = cfg.n_samples if f == 1 else max(2, int(round(f * cfg.n_samples)))
        return self._normalized(human, workspace, normalized, where).resample(n)

    def encode(self, demo: Demonstration, workspace: Workspace | None = None) -> np.ndarray:
        """The stacked weights of a demonstration in the library's weight space (Eqs. 3-4, 14).

        Parameters
        ----------
        demo : Demonstration
        workspace : Workspace, optional
            The demonstrator's workspace (overrides ``config.workspace``).

        Returns
        -------
        w : array, shape (D_h N_h + D_r N_r,)
            ``[w_h; w_r]``: the human weights (the gating space, the first
            ``n_human``) then the robot weights (none for a human-only
            demonstration), each block dimension-major (``w_h[i N_h:(i + 1) N_h]``
            are the weights of human dimension ``i``).
        """
        if not isinstance(demo, Demonstration):
            raise ValueError(f"encode takes a Demonstration, got {type(demo).__name__}")
        cfg = self.config
        where = f"demo {demo.name!r}" if demo.name else "demonstration"
        return self._weights(demo, self.human_samples(demo.human, workspace=workspace, where=where))

    def _weights(self, demo: Demonstration, y_h: np.ndarray) -> np.ndarray:
        """:meth:`encode` of ``demo`` whose human samples (Eq. 14, resampled by arc length) are ``y_h``."""
        cfg = self.config
        parts = [ridge_weights(y_h, cfg.basis_human, cfg.ridge)]
        if demo.robot is not None:
            y_r = resample_in_time(demo.t, demo.robot, cfg.n_samples)
            parts.append(ridge_weights(y_r, cfg.basis_robot, cfg.ridge))
        return np.concatenate(parts)

    def _check_dims(self, demo: Demonstration):
        if self.dim_human_ is None:
            return
        where = f"demo {demo.name!r}" if demo.name else "demonstration"
        if demo.dim_human != self.dim_human_:
            raise ValueError(f"{where}: human has {demo.dim_human} columns, the library has {self.dim_human_}")
        if demo.dim_robot != self.dim_robot_:
            have = "no robot" if not self.dim_robot_ else f"{self.dim_robot_} robot joints"
            got = "no robot" if demo.robot is None else f"{demo.dim_robot} robot columns"
            raise ValueError(f"{where}: has {got}, the library has {have}")

    # --------------------------------------------------------------- learning
    def fit(self, demos: Sequence[Demonstration], workspace=None) -> "SkillLibrary":
        """Reset, then fold in ``demos`` one at a time in the given order."""
        self._reset()
        for d in demos:
            self.partial_fit(d, workspace=workspace)
        return self

    def partial_fit(self, demo: Demonstration, workspace: Workspace | None = None, *,
                    check_units: bool = True) -> Update:
        """Fold one demonstration into the library (Algorithm 1, :func:`~drake_skills.library.algorithm.fold_in`).

        Either the whole update happens or, if anything fails (bad input,
        numerics), an exception is raised and the library is unchanged.

        Parameters
        ----------
        demo : Demonstration
            With a robot trajectory, or human-only (then every demonstration
            must be human-only).
        workspace : Workspace, optional
            The demonstrator's workspace (overrides ``config.workspace``).
        check_units : bool
            Refuse a demonstration whose units are plainly not the library's
            (:func:`~drake_skills.library.guards.units_error`: a motion spanning more
            than ten workspaces; :func:`~drake_skills.library.guards.robot_units_error`:
            robot values 30 times larger than all so far, degrees for radians). False
            teaches it anyway.

        Returns
        -------
        Update

        Raises
        ------
        ValueError
            For bad input or plainly wrong units (the library is unchanged).
        """
        if not isinstance(demo, Demonstration):
            raise ValueError(f"partial_fit takes a Demonstration, got {type(demo).__name__}")
        self._check_dims(demo)
        cfg = self.config
        where = f"demo {demo.name!r}" if demo.name else "demonstration"
        normalized_path = self._normalized(demo.human, workspace, False, where)
        y_h = normalized_path.resample(cfg.n_samples)   # what encode() would compute, computed once
        w = self._weights(demo, y_h)
        if not np.isfinite(w).all():
            raise ValueError("demonstration gives non-finite weights")
        h = demo.dim_human * self.config.n_basis_human
        if check_units:
            message = units_error(normalized_path.y, workspace if workspace is not None else cfg.workspace, where)
            if message is None and demo.robot is not None and self._scale is not None:
                s = self._scale
                message = robot_units_error(w[h:], seen_robot_rms(s.total_mean, s.total_m2, s.n, h), where)
            if message is not None:
                raise ValueError(message)
        self._guard(normalized_path.y, workspace, False, whole=True, query=False, where=where)
        path = normalized_path.length
        n = self._n_seen
        fit = cfg.basis_human.phi_uniform(y_h.shape[0]) @ w[:h].reshape(demo.dim_human, -1).T
        fit_residual = float(np.mean((y_h - fit) ** 2))
        comps = self._components if self._scale is not None else Components.of([], h)
        scale = self._scale if self._scale is not None else SharedScale.empty(w.shape[0])
        with np.errstate(over="ignore", invalid="ignore"):  # an overflowing update is refused below
            beginnings = None
            if len(comps) and isinstance(self._rule, Chi2Rule):
                def beginnings(k):  # the record of beginnings (RecognitionMixin._beginnings_missed)
                    return self._beginnings_missed(normalized_path, k)
            step = fold_in(comps, scale, w, demo.duration, path, n_human=h, config=self.config, rule=self._rule,
                           next_id=self._next_id, demo_index=n, fit_residual=fit_residual, beginnings=beginnings,
                           task=None if demo.task is None else str(demo.task))
        _check_finite_step(step, w, where)
        gain = self._gain
        if cfg.conditioning_gain and step.recognized is not None and demo.robot is not None:
            # Eq. (13) of the component that explained it, before it learns from it (library.gain)
            try:
                with np.errstate(over="ignore", invalid="ignore"):  # gain.add refuses what overflowed
                    prior_w, shift = self._correction(self._model(step.recognized), y_h)
                    gain = gain.add(shift.reshape(demo.dim_robot, -1), (w[h:] - prior_w).reshape(demo.dim_robot, -1),
                                    _robot_gram(cfg.basis_robot, cfg.n_samples))
            except ValueError as exc:
                raise ValueError(f"{where}: {exc}; the library is unchanged") from None
        # commit: nothing above touched self
        self._components, self._scale, self._gain = step.components, step.scale, gain
        if step.metric is not None:  # the metric of this version, already factored by the step
            self._memo["metric"] = ((self._components, self._scale), step.metric)
        self._history.extend(step.history)
        self._next_id = step.next_id
        self._n_seen = n + 1
        if workspace is not None or self.config.workspace is not None:
            self._with_workspace = True
        if self.dim_human_ is None:
            self.dim_human_, self.dim_robot_ = demo.dim_human, demo.dim_robot
        return Update(n, step.recognized, step.created, step.updated, step.merged, step.deleted,
                      step.responsibilities, step.split, step.subcluster)
