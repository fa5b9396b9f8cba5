"""What a :class:`~drake_skills.library.incremental.SkillLibrary` hands out.

Read-only component views, the record of one ``partial_fit`` (:class:`Update`), a
recognition (:class:`Recognition`) and the error of a motion that matches no skill.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


class UnknownSkillError(RuntimeError):
    """The observed motion matches no skill: the robot should ask for a demonstration."""


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
    mean, cov : arrays, shapes (d,), (d, d)
        The expert Gaussian over [w_h; w_r] (Eq. 8).
    n_human : int
        Number of leading human weights; the gating Gaussian (Eq. 7) is the
        human block ``mean[:n_human], cov[:n_human, :n_human]``.
    duration : float
        Mean duration of its demonstrations in seconds.
    """

    id: int
    age: int
    support: float
    weight: float
    mean: np.ndarray
    cov: np.ndarray
    n_human: int
    duration: float

    @property
    def mean_gating(self) -> np.ndarray:
        return self.mean[:self.n_human]

    @property
    def cov_gating(self) -> np.ndarray:
        return self.cov[:self.n_human, :self.n_human]


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
    responsibilities: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Recognition:
    """Result of :meth:`SkillLibrary.recognize` (Eq. 12)."""

    #: k*, or None when no component explains the motion ("unknown").
    component: int | None
    #: Component ids, aligned with the arrays below.
    ids: tuple[int, ...]
    #: p(k | w_h) (Eq. 5); all zero when the library is empty.
    responsibilities: np.ndarray
    #: log p(w_h | k) under the floored gating covariance.
    log_likelihoods: np.ndarray
    #: Squared Mahalanobis distance to each component.
    mahalanobis_sq: np.ndarray
    #: Degrees of freedom of the chi-square test.
    dof: int

    @property
    def unknown(self) -> bool:
        return self.component is None
