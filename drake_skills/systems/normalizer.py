"""``WorkspaceNormalizer``: Eq. (14) applied on line to the observed wrist, once for the whole Diagram."""
from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from drake_skills.data.workspace import Workspace

#: Period of the start-position latch (s); exact in binary.
LATCH_PERIOD = 1.0 / 64.0


def normalized_relative(workspace: Workspace, p: np.ndarray, start_normalized: np.ndarray | None, *,
                        subtract_start: bool = True) -> np.ndarray:
    """Eq. (14) for one sample: ``workspace.normalize(p)`` minus the normalized start position.

    Parameters
    ----------
    workspace : Workspace
    p : array, shape (D,)
        Raw position.
    start_normalized : array, shape (D,), or None
        The normalized start; None (no start seen yet) makes ``p`` its own start,
        so the result is zero.
    subtract_start : bool
        False leaves the start in (a library with ``subtract_start=False``).

    Returns
    -------
    array, shape (D,)
    """
    pn = workspace.normalize(np.asarray(p, float).reshape(1, -1), subtract_start=False)[0]
    if not subtract_start:
        return pn
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

    The output is in the library's normalized units, so the systems downstream
    hand it to the library as is (``normalized=True``): the Diagram normalizes
    once. The start position is the first sample seen after a trial start (a
    context reset): it is latched into discrete state by an initialization
    event and, should the input only become valid later, by the first
    periodic update (every 1/64 s) that finds no start yet.

    Parameters
    ----------
    workspace : Workspace
        The subject's workspace (from calibration).
    subtract_start : bool
        Subtract the start position (the library's ``config.subtract_start``).
    """

    def __init__(self, workspace: Workspace, *, subtract_start: bool = True):
        super().__init__()
        if not isinstance(workspace, Workspace):
            raise ValueError(f"workspace must be a Workspace, got {type(workspace).__name__}")
        self._workspace = workspace
        self._subtract_start = bool(subtract_start)
        dim = workspace.dim
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
        p = np.asarray(self._wrist.Eval(context), float).reshape(1, -1)
        start = self._workspace.normalize(p, subtract_start=False)[0]
        discrete_state.get_mutable_vector(self._state).SetFromVector(np.concatenate([start, [1.0]]))

    def _calc_normalized(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(normalized_relative(self._workspace, self._wrist.Eval(context), self.start(context),
                                                 subtract_start=self._subtract_start))
