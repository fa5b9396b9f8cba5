"""``WristSignalSender``: the person's wrist as an ``lcmt_drake_signal`` message (what a tracker publishes).

The wrist message of the LCM interface is Drake's generic vector message
``lcmt_drake_signal``: three values, the wrist position p_WH in metres, in the
frame the subject's calibration motions were recorded in (the world frame W of
the simulation), named by ``coord`` (:data:`WRIST_COORDS`) so that a wrong
publisher on the channel is caught, and a ``timestamp`` in milliseconds (the
tracker's clock; the controller only reports it).
"""
from __future__ import annotations

import numpy as np
from drake import lcmt_drake_signal
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem

#: ``coord`` names of the three values of a wrist message, in order.
WRIST_COORDS = ("wrist_x", "wrist_y", "wrist_z")


def wrist_message(p_WH: np.ndarray, time: float) -> lcmt_drake_signal:
    """The wrist message for position ``p_WH`` (3,) in metres at ``time`` (s).

    Raises
    ------
    ValueError
        If ``p_WH`` is not 3 finite numbers.
    """
    p = np.asarray(p_WH, float).reshape(-1)
    if p.shape != (3,) or not np.isfinite(p).all():
        raise ValueError(f"wrist position must be 3 finite numbers, got {p_WH!r}")
    msg = lcmt_drake_signal()
    msg.dim = 3
    msg.val = [float(x) for x in p]
    msg.coord = list(WRIST_COORDS)
    msg.timestamp = int(round(1000.0 * time))
    return msg


class WristSignalSender(LeafSystem):
    """Encodes p_WH as an ``lcmt_drake_signal`` (:func:`wrist_message`) for an ``LcmPublisherSystem``.

    .. pydrake_system::

        name: WristSignalSender
        input_ports:
        - human_wrist
        output_ports:
        - lcmt_drake_signal

    The timestamp is the context time.
    """

    def __init__(self):
        super().__init__()
        self._wrist = self.DeclareVectorInputPort("human_wrist", 3)
        self.DeclareAbstractOutputPort("lcmt_drake_signal", lambda: AbstractValue.Make(lcmt_drake_signal()),
                                       self._calc)

    def _calc(self, context: Context, output: AbstractValue) -> None:
        output.set_value(wrist_message(self._wrist.Eval(context), context.get_time()))
