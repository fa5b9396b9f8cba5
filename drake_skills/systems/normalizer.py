"""``WorkspaceNormalizer``: Eq. (14) applied on line to the observed wrist."""
from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from drake_skills.data.workspace import Workspace

#: Period of the start-position latch (s); exact in binary.
LATCH_PERIOD = 1.0 / 64.0


def normalize_point(workspace: Workspace, p: np.ndarray) -> np.ndarray:
    """``scale (p - lower) / (upper - lower)`` for one point (Eq. 14 without the start offset).

    Parameters
    ----------
    workspace : Workspace
    p : array, shape (D,)

    Returns
    -------
    array, shape (D,)
    """
    return workspace.scale * (np.asarray(p, float) - workspace.lower) / (workspace.upper - workspace.lower)


def normalized_relative(workspace: Workspace, p: np.ndarray, start_normalized: np.ndarray | None) -> np.ndarray:
    """Eq. (14): normalized ``p`` minus the normalized start position.

    With ``start_normalized=None`` (no start seen yet) ``p`` is its own start
    and the result is zero.
    """
    pn = normalize_point(workspace, p)
    if start_normalized is None:
        return np.zeros_like(pn)
    return pn - start_normalized


class WorkspaceNormalizer(LeafSystem):
    """The wrist in the subject's normalized workspace, relative to its start position (Eq. 14).

    .. pydrake_system::

        name: WorkspaceNormalizer
        input_ports:
        - human_wrist
        output_ports:
        - normalized_wrist

    The start position is the first sample seen after a trial start (a
    context reset): it is latched into discrete state by an initialization
    event and, should the input only become valid later, by the first
    periodic update (every 1/64 s) that finds no start yet.

    Parameters
    ----------
    workspace : Workspace
        The subject's workspace (from calibration).
    """

    def __init__(self, workspace: Workspace):
        super().__init__()
        if not isinstance(workspace, Workspace):
            raise ValueError(f"workspace must be a Workspace, got {type(workspace).__name__}")
        self._workspace = workspace
        dim = workspace.dim
        self._dim = dim
        self._wrist = self.DeclareVectorInputPort("human_wrist", dim)
        # [start_normalized (dim); latched (1)]
        self._state = self.DeclareDiscreteState(dim + 1)
        self.DeclareInitializationDiscreteUpdateEvent(self._latch)
        self.DeclarePeriodicDiscreteUpdateEvent(LATCH_PERIOD, 0.0, self._latch)
        self.DeclareForcedDiscreteUpdateEvent(self._latch)
        self._out = self.DeclareVectorOutputPort("normalized_wrist", dim, self._calc_normalized,
                                                 prerequisites_of_calc={self.all_sources_ticket()})

    @property
    def workspace(self) -> Workspace:
        return self._workspace

    def start(self, context: Context) -> np.ndarray | None:
        """The latched normalized start position, or None before the first sample."""
        x = context.get_discrete_state(self._state).get_value()
        return None if x[-1] < 0.5 else np.array(x[:-1])

    def _latch(self, context: Context, discrete_state: DiscreteValues) -> None:
        x = context.get_discrete_state(self._state).get_value()
        if x[-1] >= 0.5:
            return
        p = self._wrist.Eval(context)
        discrete_state.get_mutable_vector(self._state).SetFromVector(
            np.concatenate([normalize_point(self._workspace, p), [1.0]]))

    def _calc_normalized(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(normalized_relative(self._workspace, self._wrist.Eval(context), self.start(context)))
