"""What a :class:`~drake_skills.library.incremental.SkillLibrary` hands out.

Read-only component views, the record of one ``partial_fit`` (:class:`Update`), a
recognition (:class:`Recognition`) and the error of a motion that matches no skill.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Callable, Iterator

import numpy as np

#: The answers of :meth:`SkillLibrary.recognize`.
STATUSES = ("skill", "undecided", "unknown")


class UnknownSkillError(RuntimeError):
    """The observed motion matches no skill: the robot should ask for a demonstration."""


class StillMotionError(ValueError):
    """The human motion has no path: it never leaves the arc-length tolerance (of its mean, for a noisy one).

    A ``ValueError``; raised by learning and recognition alike. A caller that watches a live
    wrist (the gating) takes it for "no motion yet" rather than for bad data.
    """


class DataWarning(UserWarning):
    """Human data that the library can use but that is probably not what the caller meant.

    Issued with :func:`warnings.warn` (so it shows without any logging set up, points at
    the caller's line and can be filtered or turned into an error), at most once per
    library object and kind.
    """


class WorkspaceWarning(DataWarning):
    """A motion given without a workspace to a library that was trained with one."""


class UnitsWarning(DataWarning):
    """A motion far outside the normalized range the library's settings assume (raw metres, millimetres)."""


@dataclass(frozen=True, eq=False)
class Component:
    """A read-only view of one skill: an Interaction ProMP with its bookkeeping.

    Attributes
    ----------
    id : int
        Stable identifier (ids are never reused).
    age : int
        v_k, demonstrations processed since the component was created.
    support : float
        s_k, the responsibility mass it has absorbed.
    weight : float
        alpha_k = s_k / sum_j s_j.
    mean : array, shape (d,)
        Mean of the stacked weights [w_h; w_r] of its demonstrations (Eq. 8).
    n_human : int
        Number of leading human weights (the gating weights).
    duration : float
        Mean duration of its demonstrations in seconds.
    path_length : float
        Mean length of their normalized human paths (workspace units), by which a
        prefix's phase is estimated.
    cov : array, shape (d, d)
        The expert covariance ``(kappa Sigma + S_k) / (kappa + s_k - 1)``: its own
        scatter shrunk towards the shared within-skill covariance (computed on first use).
    cov_gating : array, shape (n_human, n_human)
        The covariance the gating judges a new motion with: the shared within-skill
        covariance times ``1 + 1/s_k`` (the uncertainty of the mean added).
    """

    id: int
    age: int
    support: float
    weight: float
    mean: np.ndarray
    n_human: int
    duration: float
    path_length: float
    _cov: Callable = field(repr=False, default=None)
    _cov_gating: Callable = field(repr=False, default=None)

    @property
    def mean_gating(self) -> np.ndarray:
        return self.mean[:self.n_human]

    @cached_property
    def cov(self) -> np.ndarray:
        c = self._cov()
        c.setflags(write=False)
        return c

    @cached_property
    def cov_gating(self) -> np.ndarray:
        c = self._cov_gating()
        c.setflags(write=False)
        return c


class Responsibilities(Mapping):
    """Component id -> responsibility, read-only, for every component (a ``dict`` in all but type).

    Held as the two arrays it was made from; the dictionary is built when it is
    first read, so a step of a library of a thousand components does not pay for
    one it may never look at.

    Parameters
    ----------
    ids : array of int, shape (K,)
    values : array, shape (K,)
    """

    def __init__(self, ids: np.ndarray, values: np.ndarray):
        self._ids, self._values = ids, values
        self._dict: dict | None = None

    def _as_dict(self) -> dict:
        if self._dict is None:
            self._dict = dict(zip(self._ids.tolist(), self._values.tolist()))
        return self._dict

    def __getitem__(self, component_id: int) -> float:
        return self._as_dict()[component_id]

    def __iter__(self) -> Iterator[int]:
        return iter(self._as_dict())

    def __len__(self) -> int:
        return len(self._ids)

    def __repr__(self) -> str:
        return repr(self._as_dict())


@dataclass(frozen=True)
class Update:
    """What ``partial_fit`` did with one demonstration."""

    #: Index of the demonstration in the stream (0-based).
    demo_index: int
    #: Component that explained it best before the update (None if it was novel).
    recognized: int | None
    created: tuple[int, ...] = ()
    #: Components whose responsibility was at least 1e-3.
    updated: tuple[int, ...] = ()
    #: (kept, absorbed) pairs.
    merged: tuple[tuple[int, int], ...] = ()
    deleted: tuple[int, ...] = ()
    #: Component id -> p(k | w_h) for every component before the update (empty if it was novel).
    responsibilities: Mapping = field(default_factory=dict)
    #: (kept, new) pairs: component ``kept`` split in two and ``new`` is its other half.
    split: tuple[tuple[int, int], ...] = ()
    #: Updated component id -> index (0, 1) of its sub-cluster the demonstration joined.
    subcluster: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Recognition:
    """Result of :meth:`SkillLibrary.recognize` (Eq. 12).

    ``status`` is "skill" (``component`` is its id), "undecided" (more than one skill
    explains the motion and none is ``1 - decision_risk`` probable, or, for a beginning
    recognized without a fraction, a skill that would answer differently cannot be ruled
    out because it misses its own beginnings there (``blind``): wait for more of it) or
    "unknown" (no skill explains it: ask for a demonstration).

    A motion's beginning recognized without a fraction in a library of more than
    ``PRUNE_MIN_COMPONENTS`` (16) components is scored only against the components a
    lower bound does not rule out (:func:`~drake_skills.library.prefix_bound.prefix_candidates`);
    the others have log-likelihood -inf, distance inf and responsibility 0 (they
    cannot explain the motion, so the answer is the one scoring all of them gives).
    """

    #: k* when ``status == "skill"``, else None.
    component: int | None
    #: Component ids, aligned with the arrays below.
    ids: tuple[int, ...]
    #: p(k | w_h) (Eq. 5) over all components; all zero when the library is empty.
    responsibilities: np.ndarray
    #: log p(w_h | k) under each component's predictive gating covariance.
    log_likelihoods: np.ndarray
    #: Squared Mahalanobis distance to each component.
    mahalanobis_sq: np.ndarray
    #: Degrees of freedom of the chi-square test (per component for a prefix: D times the directions
    #: of the weights its samples see well at the component's phase; ``n_human`` for a component the
    #: pruning bound ruled out).
    dof: int | np.ndarray
    #: "skill", "undecided" or "unknown".
    status: str = "unknown"
    #: Estimated fraction of each component's motion the observation covers, shape (K,).
    phases: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: p(k | motion) among the components that explain it (zero for the others). "Explain" is the
    #: novelty test: a component seen once that lies beyond ``single_demo_quantile`` but within it keeps
    #: its share here although it cannot be the answer (``RecognitionMixin._decide``); when no component
    #: can be the answer all entries are zero.
    posterior: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: Ids of the components that could not be ruled out because they miss too many of their own
    #: demonstrations' beginnings at the share of their path this beginning covers, and would
    #: answer differently from the best candidate: the reason a beginning that one skill explains
    #: is "undecided" (empty for whole motions and beginnings of a given fraction; the record of
    #: beginnings: ``Cluster.tested`` / ``Cluster.missed``, ``RecognitionMixin._decide``).
    blind: tuple[int, ...] = ()
    #: Ids of the components seen once that explain the motion (the novelty test) but lie beyond
    #: ``single_demo_quantile`` while the library's scale is more prior than data: they keep their share
    #: of ``posterior`` but cannot be the answer. The reason a motion whose most probable component is
    #: one of them is "undecided" (``RecognitionMixin._decide``): demonstrate that skill again.
    seen_once: tuple[int, ...] = ()
    #: None: the motion was read whole. An int ``i``: the motion as a whole was unknown, and it is read
    #: from its sample ``i`` on, where it last set off from its start (a false start before it;
    #: ``LibraryConfig.skip_false_starts``); pass it on to :meth:`SkillLibrary.predict_robot` and
    #: ``estimate_phase`` with a component of your choice (``restart=i``).
    restart: int | None = None
    #: Why a motion one skill explains is "undecided" by the task names it was taught under
    #: (``Cluster.tasks``): ``(best,)`` when that skill was taught under more than one task name
    #: (``LibraryConfig.mixed_task_share``), else the ids of the skills taught as another task that lie
    #: near it (``LibraryConfig.other_task_reach``; for a whole motion or one at a given fraction, only those
    #: within that many times their novelty limit of it; a beginning keeps them all). The teacher called these
    #: motions different tasks, so acting on one could be the wrong one. Empty otherwise.
    contested: tuple[int, ...] = ()
    #: For a beginning (the phase estimated): the posterior probability that it begins a skill the library was
    #: never taught (``LibraryConfig.new_skill_weight``; the population of all demonstrations as that skill's
    #: model). At or above ``decision_risk`` a beginning one skill explains is "undecided": wait for more of it.
    #: Computed only for a beginning the components alone would answer as a skill, short of
    #: ``recognition.NEW_SKILL_PHASE`` (0.9) of its path; 0 otherwise (and for whole motions, beginnings of a
    #: given fraction, and with the setting off).
    new_skill: float = 0.0

    @property
    def unknown(self) -> bool:
        """No skill explains the motion (not merely undecided)."""
        return self.status == "unknown"

    @property
    def best(self) -> int | None:
        """The most probable component among those that explain the motion (None if unknown); when "undecided",
        possibly one seen once that is beyond ``single_demo_quantile`` and so cannot be the answer."""
        if self.status == "unknown" or not len(self.ids):
            return None
        return self.ids[int(np.argmax(self.posterior))]

    @property
    def confidence(self) -> float:
        """Posterior of the best candidate (0 when unknown)."""
        return float(np.max(self.posterior)) if self.posterior.size and self.status != "unknown" else 0.0

    @property
    def phase(self) -> float:
        """Estimated fraction observed of the best candidate's motion (NaN when unknown)."""
        b = self.best
        return float(self.phases[self.ids.index(b)]) if b is not None and self.phases.size else float("nan")
