"""The incremental, open-ended skill library: the paper's Algorithm 1.

A mixture of Interaction ProMPs learned one demonstration at a time.  Each
component ``k`` holds a Gaussian over the stacked weights ``[w_h; w_r]`` (the
expert, Eq. 8), a support ``s_k``, an age ``v_k`` and a mean duration.  The
gating model of the paper (an incremental GMM on the human weights, Eq. 7) is
the human block of the experts: both are updated with the same
responsibilities, rates and initial covariance, so the paper's ``mu^g, Sigma^g``
equal ``mu^e[h], Sigma^e[h, h]`` exactly and are not stored twice.  For
human-only data (letters) the expert *is* the gating model (Sec. 4.1).

The algorithm itself is pure functions in :mod:`drake_skills.library.algorithm`
(novelty, update, merge, delete) and :mod:`drake_skills.library.novelty` (the
tests); this class encodes demonstrations, keeps the state and answers queries.
Deviations from the printed equations, each deliberate and tested:

* Eqs. (7)-(8) read literally shrink the new sample's scatter by ``(1 - gamma)``.
  We use ``C <- (1 - g~) C + g~ (1 - g) e e^T`` with ``e = w - mu_old``, which
  is the exact running (biased, responsibility-weighted) covariance when
  ``g~ = g`` and forgets the initial covariance faster when ``g~ > g``
  (:func:`incremental_update`).
* Eq. (11) as printed is garbled; merging uses the moment-matched Gaussian of
  the two support-weighted components (:func:`~drake_skills.promp.gaussian.merge_moments`).
* Novelty and "unknown" are the same likelihood test, in a scale-free chi-square
  form by default (:mod:`drake_skills.library.novelty`).
* A variance floor (``gating_floor``) is added to the gating covariance when it
  is evaluated, so a component does not become infinitely sure in directions
  it has not yet seen.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from drake_skills._checks import as_finite_array
from drake_skills.data.demonstration import Demonstration
from drake_skills.data.workspace import Workspace
from drake_skills.library import storage
from drake_skills.library.algorithm import ComponentModel, fold_in, gating_scores, incremental_update, \
    responsibilities
from drake_skills.library.config import NOVELTY_TESTS, LibraryConfig, WorkspaceBounds
from drake_skills.library.novelty import novelty_rule
from drake_skills.library.state import ComponentState, LibraryState
from drake_skills.library.views import Component, Recognition, UnknownSkillError, Update
from drake_skills.promp.basis import ridge_weights, trajectory_covariance
from drake_skills.promp.interaction import InteractionProMP, condition_on_observations, observation_log_likelihood
from drake_skills.promp.preprocessing import resample_by_arc_length, resample_in_time

__all__ = ["Component", "ComponentState", "LibraryConfig", "LibraryState", "NOVELTY_TESTS", "Recognition",
           "SkillLibrary", "UnknownSkillError", "Update", "WorkspaceBounds", "incremental_update"]


def _read_only(a: np.ndarray) -> np.ndarray:
    v = a.view()
    v.setflags(write=False)
    return v


class SkillLibrary:
    """An open-ended library of collaborative skills learned one demonstration at a time.

    Parameters
    ----------
    config : LibraryConfig, optional
        Hyperparameters; defaults work on letters and on the salad scenario.

    Examples
    --------
    >>> lib = SkillLibrary()
    >>> for demo in stream:                       # doctest: +SKIP
    ...     update = lib.partial_fit(demo)
    >>> rec = lib.recognize(human)                # doctest: +SKIP
    >>> mean, cov = lib.predict_robot(human)      # doctest: +SKIP
    """

    def __init__(self, config: LibraryConfig | None = None):
        self.config = config if config is not None else LibraryConfig()
        if not isinstance(self.config, LibraryConfig):
            raise ValueError(f"config must be a LibraryConfig, got {type(self.config).__name__}")
        self._reset()

    def _reset(self):
        self._components: tuple[ComponentModel, ...] = ()
        self._history: list[dict] = []
        self._next_id = 0
        self._n_seen = 0
        self.dim_human_: int | None = None
        self.dim_robot_: int | None = None

    # ------------------------------------------------------------------ state
    def state(self) -> LibraryState:
        """A snapshot of everything learned (arrays read-only; the library never writes them in place)."""
        comps = tuple(ComponentState(c.id, c.age, c.support, _read_only(c.mean), _read_only(c.cov), c.duration)
                      for c in self._components)
        return LibraryState(self.config, self.dim_human_, self.dim_robot_, self._next_id, self._n_seen, comps,
                            tuple(dict(e) for e in self._history))

    @classmethod
    def from_state(cls, state: LibraryState) -> "SkillLibrary":
        """The library of a :meth:`state` snapshot: it answers and keeps learning exactly as the original."""
        if not isinstance(state, LibraryState):
            raise ValueError(f"from_state takes a LibraryState, got {type(state).__name__}")
        lib = cls(state.config)
        h, floor = state.n_human, state.config.gating_floor
        lib._components = tuple(ComponentModel.of(ComponentState(c.id, c.age, c.support, np.array(c.mean, float),
                                                                 np.array(c.cov, float), c.duration), h, floor)
                                for c in state.components)
        lib._history = [dict(e) for e in state.history]
        lib._next_id, lib._n_seen = int(state.next_id), int(state.n_seen)
        if state.dim_human is not None:
            lib.dim_human_, lib.dim_robot_ = int(state.dim_human), int(state.dim_robot)
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
        """Read-only views of the components (arrays are not copied and not writable)."""
        total = sum(c.support for c in self._components) or 1.0
        h = self.n_human
        return tuple(Component(c.id, c.age, c.support, c.support / total, _read_only(c.mean), _read_only(c.cov), h,
                               c.duration) for c in self._components)

    @property
    def history(self) -> tuple[dict, ...]:
        """Creations, merges and deletions, in order."""
        return tuple(dict(e) for e in self._history)

    @property
    def n_human(self) -> int:
        self._check_fitted()
        return self.dim_human_ * self.config.n_basis_human

    @property
    def has_robot(self) -> bool:
        return bool(self.dim_robot_)

    def component(self, component_id: int) -> Component:
        """The component with this id (KeyError if there is none)."""
        for c in self.components:
            if c.id == component_id:
                return c
        raise KeyError(f"no component with id {component_id}; ids are {[c.id for c in self._components]}")

    def _model(self, component_id: int) -> ComponentModel:
        for c in self._components:
            if c.id == component_id:
                return c
        raise KeyError(f"no component with id {component_id}; ids are {[c.id for c in self._components]}")

    def as_mixture(self, part: str = "gating"):
        """The library as a Gaussian mixture ``(weights (K,), means (K, d), covs (K, d, d))``.

        ``part="gating"`` gives the mixture over human weights (Eq. 5, without
        the evaluation floor); ``"expert"`` the one over stacked weights (Eq. 2).
        """
        self._check_fitted()
        if part not in ("gating", "expert"):
            raise ValueError(f"part must be 'gating' or 'expert', got {part!r}")
        if not self._components:
            raise ValueError("the library has no components")
        d = self.n_human if part == "gating" else self._components[0].mean.shape[0]
        s = np.array([c.support for c in self._components])
        means = np.stack([c.mean[:d] for c in self._components])
        covs = np.stack([c.cov[:d, :d] for c in self._components])
        return s / s.sum(), means, covs

    def interaction_promp(self, component_id: int) -> InteractionProMP:
        """The Interaction ProMP of one component (a copy)."""
        c = self.component(component_id)
        cfg = self.config
        return InteractionProMP.from_moments(
            np.array(c.mean), np.array(c.cov), self.dim_human_, self.dim_robot_,
            basis_human=cfg.basis_human, basis_robot=cfg.basis_robot, ridge=cfg.ridge,
            observation_noise=cfg.observation_noise)

    def _check_fitted(self):
        if self.dim_human_ is None:
            raise ValueError("this SkillLibrary is not fitted yet: call partial_fit() with a demonstration first")

    def __repr__(self) -> str:
        return f"SkillLibrary(n_components={self.n_components}, n_seen={self.n_seen})"

    # --------------------------------------------------------- preprocessing
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
        human = as_finite_array(human, "human", ndim=2, min_rows=2, where=where)
        if self.dim_human_ is not None and human.shape[1] != self.dim_human_:
            raise ValueError(f"{where + ': ' if where else ''}human has {human.shape[1]} columns, "
                             f"the library was built on {self.dim_human_}")
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
        f = float(observed_fraction)
        if not 0 < f <= 1:
            raise ValueError(f"observed_fraction must be in (0, 1], got {observed_fraction!r}")
        n = cfg.n_samples if f == 1 else max(2, int(round(f * cfg.n_samples)))
        try:
            return resample_by_arc_length(human, n, cfg.resample_tolerance)
        except ValueError as exc:
            raise ValueError(f"{where + ': ' if where else ''}human {exc}") from None

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
        y_h = self.human_samples(demo.human, workspace=workspace, where=where)
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

    def partial_fit(self, demo: Demonstration, workspace: Workspace | None = None) -> Update:
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

        Returns
        -------
        Update
        """
        if not isinstance(demo, Demonstration):
            raise ValueError(f"partial_fit takes a Demonstration, got {type(demo).__name__}")
        self._check_dims(demo)
        w = self.encode(demo, workspace)
        if not np.isfinite(w).all():
            raise ValueError("demonstration gives non-finite weights")
        n = self._n_seen
        step = fold_in(self._components, w, demo.duration, n_human=demo.dim_human * self.config.n_basis_human,
                       config=self.config, next_id=self._next_id, demo_index=n)
        # commit: nothing above touched self
        self._components = step.components
        self._history.extend(step.history)
        self._next_id = step.next_id
        self._n_seen = n + 1
        if self.dim_human_ is None:
            self.dim_human_, self.dim_robot_ = demo.dim_human, demo.dim_robot
        return Update(n, step.recognized, step.created, step.updated, step.merged, step.deleted,
                      step.responsibilities)

    # ------------------------------------------------------------- run time
    def recognize(self, human, *, observed_fraction: float = 1.0, workspace: Workspace | None = None,
                  normalized: bool = False) -> Recognition:
        """Which skill is this human motion (Eq. 12), or None for unknown.

        Parameters
        ----------
        human : array, shape (T, D_h)
            The observed human positions (raw units if a workspace applies; see
            :meth:`human_samples` for ``normalized``).
        observed_fraction : float
            Fraction of the whole motion's path that ``human`` covers; below 1
            the motion is compared with each component's prefix through the
            marginal likelihood of the observed samples.
        workspace : Workspace, optional
        normalized : bool
            ``human`` is already in the library's normalized units (Eq. 14 applied).
        """
        self._check_fitted()
        y = self.human_samples(human, workspace=workspace, observed_fraction=observed_fraction,
                               normalized=normalized)
        return self._recognize_samples(y, float(observed_fraction))

    def _recognize_samples(self, y, observed_fraction: float) -> Recognition:
        """Eq. (12) on preprocessed human samples ``y`` (evenly spaced in phase)."""
        cfg = self.config
        comps = self._components
        h = self.n_human
        if not comps:
            return Recognition(None, (), np.zeros(0), np.zeros(0), np.zeros(0), h)
        if observed_fraction == 1:
            w_h = ridge_weights(y, cfg.basis_human, cfg.ridge)
            logp, d2 = gating_scores(w_h, comps)
            dof = h
        else:
            Phi_o = cfg.basis_human.phi(np.linspace(0.0, observed_fraction, y.shape[0]))
            logp, d2 = np.empty(len(comps)), np.empty(len(comps))
            floor = cfg.gating_floor * np.eye(h)
            for i, c in enumerate(comps):
                logp[i], d2[i], dof = observation_log_likelihood(
                    c.mean[:h], c.cov[:h, :h] + floor, Phi_o, y, cfg.observation_noise)
        resp = responsibilities(logp, comps)
        novel = novelty_rule(cfg).novel(logp, d2, dof)
        ids = tuple(c.id for c in comps)
        comp = None if novel.all() else ids[int(np.argmax(np.where(novel, -np.inf, np.log(resp + 1e-300))))]
        return Recognition(comp, ids, resp, logp, d2, int(dof))

    def predict_robot(self, human, observed_fraction: float = 1.0, *, workspace: Workspace | None = None,
                      component: int | None = None, n_steps: int | None = None, normalized: bool = False):
        """Robot trajectory for an observed human motion (Eqs. 12-13).

        Recognizes the skill (unless ``component`` is given), conditions its
        Interaction ProMP on the observed human samples and returns the robot
        trajectory distribution over the component's phase (normalized time).
        ``normalized=True``: ``human`` is already in the library's normalized
        units (see :meth:`human_samples`).

        Returns
        -------
        mean : array, shape (n_steps, D_r)
            Joint positions; play them over ``component(k).duration`` seconds.
        cov : array, shape (n_steps, D_r, D_r)
            Per-step covariance.

        Raises
        ------
        UnknownSkillError
            If the motion matches no component.
        ValueError
            For bad input, or a library without robot trajectories.
        KeyError
            If ``component`` is not a component id (e.g. it was deleted).
        """
        self._check_fitted()
        if not self.has_robot:
            raise ValueError("this library was learned from human-only demonstrations: it has no robot part")
        y = self.human_samples(human, workspace=workspace, observed_fraction=observed_fraction,
                               normalized=normalized)
        if component is None:
            component = self._recognize_samples(y, float(observed_fraction)).component
            if component is None:
                raise UnknownSkillError("the motion matches no skill in the library: ask for a demonstration")
        c = self._model(component)
        cfg = self.config
        Phi_o = cfg.basis_human.phi(np.linspace(0.0, float(observed_fraction), y.shape[0]))
        h, n = self.n_human, n_steps or cfg.n_samples
        # Eq. (13), keeping only the robot block of the posterior
        mean_w, cov_w = condition_on_observations(c.mean, c.cov, Phi_o, y, cfg.observation_noise, start=h)
        mean_r = cfg.basis_robot.phi_uniform(n) @ mean_w.reshape(self.dim_robot_, -1).T
        cov_r = trajectory_covariance(cov_w, cfg.basis_robot, self.dim_robot_, n_steps=n)
        return mean_r, cov_r

    # ---------------------------------------------------------------- storage
    def save(self, path) -> Path:
        """Write the library atomically to ``path`` (.npz, no pickle); returns the path written.

        ``.npz`` is appended to a path without it.
        """
        return storage.save_state(self.state(), path)

    @classmethod
    def load(cls, path) -> "SkillLibrary":
        """Read a library written by :meth:`save`; corrupt or foreign files raise ValueError."""
        return cls.from_state(storage.load_state(path))
