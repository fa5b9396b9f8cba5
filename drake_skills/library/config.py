"""``LibraryConfig``: the hyperparameters of the skill library, named as in the paper.

A config dataclass is its YAML schema: Drake's ``yaml_load_typed`` reads it (alone, or
as ``SimConfig.library``), so this module does not use ``from __future__ import
annotations`` (the loader reads the real field types) and every field type is one the
loader knows (numbers, strings, lists, ``Optional`` of a plain dataclass).
"""
# No "from __future__ import annotations": yaml_load_typed reads the real field types.

from dataclasses import dataclass, field, fields
from typing import Optional

import numpy as np

from drake_skills.data.workspace import Workspace
from drake_skills.promp.basis import GaussianBasis

#: The two forms of the novelty, "unknown" and merge tests (see :mod:`drake_skills.library.novelty`).
NOVELTY_TESTS = ("chi2", "loglik")


@dataclass
class WorkspaceBounds:
    """The YAML form of a :class:`~drake_skills.data.workspace.Workspace` (per-axis bounds)."""

    # per-axis lower bounds of the raw human positions (e.g. metres)
    lower: list[float] = field(default_factory=list)
    # per-axis upper bounds, each above its lower bound
    upper: list[float] = field(default_factory=list)
    # the bounds map to [0, scale] (the paper uses 10)
    scale: float = 10.0


@dataclass
class LibraryConfig:
    """Hyperparameters of the skill library, named as in the paper.

    The defaults work unchanged on LASA letters (2-D, human only) and on the
    simulated salad scenario (3-D wrist + 7 joints): human positions are
    compared in normalized units (the workspace maps to [0, 10]), and the
    novelty and merge tests are chi-square quantiles, which carry one setting
    across dimensions.

    ``workspace`` accepts a :class:`~drake_skills.data.workspace.Workspace`, a
    :class:`WorkspaceBounds` (what YAML gives) or a dict with ``lower``,
    ``upper`` and ``scale``; it is stored as a ``Workspace``.
    """

    # --- representation (Eqs. 3-4, 14) ---
    #: Samples per resampled trajectory (arc length for the human, time for the robot).
    n_samples: int = 100
    #: N for the human (gating) trajectories.
    n_basis_human: int = 10
    #: N for the robot trajectories: 7 joints need more than a wrist path.
    n_basis_robot: int = 20
    #: Gaussian width as a multiple of the spacing between basis centres.
    basis_width: float = 1.0
    #: Normalize the basis (rows of Phi sum to 1), so weights live in the
    #: units of the trajectory and sigma_init, the floor and the noise mean
    #: the same thing for weights as for positions.
    basis_normalized: bool = True
    #: Ridge factor of the weight regression (the paper's beta in Eq. 3).
    ridge: float = 1e-6
    #: Subtract the normalized start position (Eq. 14).
    subtract_start: bool = True
    #: Arc length counts a human sample only once it lies this far (normalized
    #: units; 0.1 = 1 % of the workspace, ~1-2 cm for a seated person) from the
    #: last counted one (``promp.preprocessing.path_vertices``). 0 counts every
    #: sample that moves, as the paper's equidistant spatial interpolation.
    #: With a noisy tracker, 0 lets the noise add path length: on the simulated
    #: salad data (0.5 mm noise at 150 Hz) it adds 20-40 % to the length, the
    #: phase becomes partly time-like and the hold at the end of a reach takes
    #: ~20 % of it. 0.1 removes that, but then board, tomato and bowl come within
    #: 1.2-1.5 RMS units of each other and the default ``gating_floor`` (1.0)
    #: merges them; ``gating_floor=0.6, sigma_init_human=0.4`` separates the
    #: salad tasks (99 % correct) but splits a LASA letter in ~20 % of orders.
    #: The default stays 0 until one setting serves both (see RESULTS.md).
    resample_tolerance: float = 0.0
    #: Default workspace for human data (None: data is already normalized);
    #: a per-call ``workspace`` argument overrides it (one per subject).
    workspace: Optional[WorkspaceBounds] = None

    # --- gating and experts (Eqs. 6-9) ---
    #: Sigma_init = sigma_init_human^2 I for human weights (normalized units).
    #: With the gating floor, a new component's gating variance is 0.25 + 1.0
    #: per weight: wide enough that a second LASA letter of the same shape
    #: (~1.0 RMS away) joins it, tight enough that the salad tasks (1.7-3.2 RMS
    #: apart) start their own (chosen on both data sets; see RESULTS.md).
    sigma_init_human: float = 0.5
    #: Sigma_init = sigma_init_robot^2 I for robot weights (radians).
    sigma_init_robot: float = 0.1
    #: Variance added to the gating covariance whenever it is evaluated.
    gating_floor: float = 1.0
    #: Use gamma~ = gamma + exp(-s) lambda (Eq. 6) to forget Sigma_init faster;
    #: False gives the exact running covariance.
    fast_forgetting: bool = True

    # --- novelty: T_nov (Eq. 9, Algorithm 1) and "unknown" (Sec. 3.3) ---
    #: "chi2" (scale free, default) or "loglik" (threshold on log p(w|k)).
    novelty_test: str = "chi2"
    #: Chi-square quantile of the Mahalanobis distance beyond which a motion is novel.
    novelty_quantile: float = 0.999
    #: log T_nov for novelty_test="loglik".
    log_T_nov: float = -60.0

    # --- merging (Eqs. 10-11) ---
    #: v_min^merge: components older than this are checked for merging.
    merge_min_age: int = 5
    #: Chi-square quantile for T_merge: merge j into i when d^2(mu_j | i) is below
    #: chi2.ppf(merge_quantile, dof) / s_i^beta (scale-free form of Eq. 10).
    merge_quantile: float = 0.5
    #: log T_merge for novelty_test="loglik": merge when log p(mu_j|i) > log_T_merge + beta log s_i.
    log_T_merge: float = -20.0
    #: beta of Eq. (10): how fast a component consolidates with its support.
    consolidation: float = 0.5

    # --- deletion of outliers ---
    #: v_min^del: age after which a component must have reached s_min.
    delete_min_age: int = 30
    #: s_min: components with support <= s_min past their deletion age are deleted.
    delete_min_support: float = 1.5

    # --- conditioning (Eq. 13) ---
    #: sigma_o, variance of an observed human sample (normalized units^2).
    observation_noise: float = 0.05

    def __post_init__(self):
        ints = {"n_samples": 4, "n_basis_human": 2, "n_basis_robot": 2, "merge_min_age": 0, "delete_min_age": 0}
        for name, lo in ints.items():
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or v < lo:
                raise ValueError(f"LibraryConfig.{name} must be an integer >= {lo}, got {v!r}")
            setattr(self, name, int(v))
        positive = ["basis_width", "sigma_init_human", "sigma_init_robot", "gating_floor", "observation_noise"]
        for name in positive:
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"LibraryConfig.{name} must be positive, got {v!r}")
        for name in ("ridge", "consolidation", "delete_min_support", "resample_tolerance"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"LibraryConfig.{name} must be >= 0, got {v!r}")
        for name in ("novelty_quantile", "merge_quantile"):
            v = getattr(self, name)
            if not 0 < v < 1:
                raise ValueError(f"LibraryConfig.{name} must be in (0, 1), got {v!r}")
        if self.novelty_test not in NOVELTY_TESTS:
            raise ValueError(f"LibraryConfig.novelty_test must be one of {NOVELTY_TESTS}, got {self.novelty_test!r}")
        self.workspace = _as_workspace(self.workspace)

    def dict(self) -> dict:
        """The fields as JSON-ready values (the workspace as ``{"lower", "upper", "scale"}``)."""
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["workspace"] = None if self.workspace is None else self.workspace.dict()
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "LibraryConfig":
        """The inverse of :meth:`dict`; unknown keys raise ``ValueError`` naming them."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"unknown LibraryConfig fields: {unknown}")
        return cls(**d)

    @property
    def basis_human(self) -> GaussianBasis:
        return GaussianBasis(self.n_basis_human, self.basis_width, self.basis_normalized)

    @property
    def basis_robot(self) -> GaussianBasis:
        return GaussianBasis(self.n_basis_robot, self.basis_width, self.basis_normalized)


def _as_workspace(ws) -> Optional[Workspace]:
    if ws is None or isinstance(ws, Workspace):
        return ws
    if isinstance(ws, WorkspaceBounds):
        ws = {"lower": ws.lower, "upper": ws.upper, "scale": ws.scale}
    if isinstance(ws, dict):
        unknown = sorted(set(ws) - {"lower", "upper", "scale"})
        if unknown or not {"lower", "upper"} <= set(ws):
            raise ValueError(f"LibraryConfig.workspace needs 'lower' and 'upper' (and 'scale'), got keys {sorted(ws)}")
        return Workspace.from_dict(ws)
    raise ValueError(f"LibraryConfig.workspace must be a Workspace, WorkspaceBounds, dict or None, "
                     f"got {type(ws).__name__}")
