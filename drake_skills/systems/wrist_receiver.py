"""``WristSignalReceiver``: the wrist position p_WH out of a received ``lcmt_drake_signal``.

See :mod:`drake_skills.systems.wrist_sender` for the message: 3 values named
:data:`~drake_skills.systems.wrist_sender.WRIST_COORDS`, metres, world frame,
``timestamp`` in milliseconds.
"""
from __future__ import annotations

import numpy as np
from drake import lcmt_drake_signal
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from drake_skills.systems.wrist_sender import WRIST_COORDS


def wrist_from_message(msg: lcmt_drake_signal, *, channel: str = "the wrist channel") -> tuple[np.ndarray, float]:
    """Position p_WH (3,) in metres and timestamp (s) of a wrist message.

    Raises
    ------
    RuntimeError
        For the default message (nothing received yet).
    ValueError
        For a message that is not a wrist: another dimension or other coordinate
        names, or non-finite values; the message names the channel.
    """
    if msg.dim == 0 and msg.timestamp == 0:
        raise RuntimeError(f"no wrist message received on '{channel}' yet; the controller must not start "
                           f"before the tracker publishes")
    if msg.dim != 3 or len(msg.val) != 3:
        raise ValueError(f"'{channel}': a wrist message has dim 3, got dim {msg.dim} with {len(msg.val)} values")
    if tuple(msg.coord) != WRIST_COORDS:
        raise ValueError(f"'{channel}': a wrist message names its values {list(WRIST_COORDS)}, got {list(msg.coord)}")
    p = np.asarray(msg.val, float)
    if not np.isfinite(p).all():
        raise ValueError(f"'{channel}': wrist position is not finite: {p.tolist()}")
    return p, 1e-3 * float(msg.timestamp)


class WristSignalReceiver(LeafSystem):
    """Decodes the newest wrist message (:func:`wrist_from_message`).

    .. pydrake_system::

        name: WristSignalReceiver
        input_ports:
        - lcmt_drake_signal
        output_ports:
        - human_wrist
        - wrist_time

    ``human_wrist`` is p_WH (3,), metres; ``wrist_time`` (1,) the message's
    timestamp in seconds. Evaluating either before a wrist message has been
    received is an error (see :func:`wrist_from_message`).

    Parameters
    ----------
    channel : str
        Channel name, for error messages.
    """

    def __init__(self, *, channel: str = "DRAKE_SKILLS_WRIST"):
        super().__init__()
        self._channel = channel
        self._msg = self.DeclareAbstractInputPort("lcmt_drake_signal", AbstractValue.Make(lcmt_drake_signal()))
        deps = {self._msg.ticket()}
        self.DeclareVectorOutputPort("human_wrist", 3, self._calc_wrist, prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("wrist_time", 1, self._calc_time, prerequisites_of_calc=deps)

    def _calc_wrist(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(wrist_from_message(self._msg.Eval(context), channel=self._channel)[0])

    def _calc_time(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector([wrist_from_message(self._msg.Eval(context), channel=self._channel)[1]])
