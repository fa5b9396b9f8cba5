"""The state of a :class:`~drake_skills.library.incremental.SkillLibrary` as plain, immutable data.

:meth:`SkillLibrary.state` returns a :class:`LibraryState` and
:meth:`SkillLibrary.from_state` builds a library from one; storage writes and reads
nothing else (it never touches the library's private fields), and a state is what an
experiment keeps when it needs a library as it was.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake_skills.library.config import LibraryConfig


@dataclass(frozen=True, eq=False)
class ComponentState:
    """One component: an Interaction ProMP over the stacked weights and its bookkeeping.

    Attributes
    ----------
    id : int
        Stable identifier (ids are never reused).
    age : int
        v_k, demonstrations processed since the component was created.
    support : float
        s_k, the responsibility mass it has absorbed (> 0).
    mean : array, shape (d,)
        Mean of the stacked weights ``[w_h; w_r]`` (Eq. 8).
    cov : array, shape (d, d)
        Their covariance, symmetric positive definite.
    duration : float
        Mean duration of its demonstrations in seconds.
    """

    id: int
    age: int
    support: float
    mean: np.ndarray
    cov: np.ndarray
    duration: float


@dataclass(frozen=True, eq=False)
class LibraryState:
    """Everything a library has learned, enough to rebuild it exactly.

    Attributes
    ----------
    config : LibraryConfig
    dim_human, dim_robot : int or None
        D_h and D_r (0 for human-only data); None before the first demonstration.
    next_id : int
        The id the next created component gets.
    n_seen : int
        Demonstrations folded in so far.
    components : tuple of ComponentState
        In the library's order (the order of responsibilities and recognitions).
    history : tuple of dict
        Creations, merges and deletions, in order (JSON-ready dicts).
    """

    config: LibraryConfig
    dim_human: int | None
    dim_robot: int | None
    next_id: int
    n_seen: int
    components: tuple[ComponentState, ...] = ()
    history: tuple[dict, ...] = ()

    def __post_init__(self):
        if not isinstance(self.config, LibraryConfig):
            raise ValueError(f"config must be a LibraryConfig, got {type(self.config).__name__}")
        if (self.dim_human is None) != (self.dim_robot is None):
            raise ValueError(f"dim_human and dim_robot are both None or both set, got "
                             f"{self.dim_human!r} and {self.dim_robot!r}")
        if self.components and self.dim_human is None:
            raise ValueError("components but no dimensions")
        d = self.n_weights
        ids = set()
        for c in self.components:
            if c.id in ids or not 0 <= c.id < self.next_id:
                raise ValueError(f"component id {c.id} is duplicated or out of range (next id {self.next_id})")
            ids.add(c.id)
            if not (c.support > 0 and c.age >= 0 and np.isfinite(c.duration)):
                raise ValueError(f"component {c.id} has support {c.support}, age {c.age}, duration {c.duration}")
            if np.shape(c.mean) != (d,) or np.shape(c.cov) != (d, d):
                raise ValueError(f"component {c.id} has mean and covariance shapes {np.shape(c.mean)}, "
                                 f"{np.shape(c.cov)}; the dimensions say {d} weights")
            if not (np.isfinite(c.mean).all() and np.isfinite(c.cov).all()):
                raise ValueError(f"component {c.id} has NaN or inf in its mean or covariance")
            if not np.allclose(c.cov, c.cov.T, rtol=1e-9, atol=1e-12):
                raise ValueError(f"covariance of component {c.id} is not symmetric")
            try:
                np.linalg.cholesky(c.cov + 1e-12 * np.trace(c.cov) / d * np.eye(d))
            except np.linalg.LinAlgError:
                raise ValueError(f"covariance of component {c.id} is not positive definite") from None

    @property
    def n_human(self) -> int:
        """Number of human (gating) weights, D_h N_h (0 before the first demonstration)."""
        return 0 if self.dim_human is None else int(self.dim_human) * self.config.n_basis_human

    @property
    def n_weights(self) -> int:
        """Number of stacked weights d = D_h N_h + D_r N_r."""
        return 0 if self.dim_human is None else self.n_human + int(self.dim_robot) * self.config.n_basis_robot
