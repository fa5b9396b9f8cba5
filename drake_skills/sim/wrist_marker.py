"""``WristMarker``: draws the person's wrist in meshcat, coloured by the gating's decision."""
from __future__ import annotations

import numpy as np
from pydrake.geometry import Box, Meshcat, Rgba, Sphere
from pydrake.math import RigidTransform
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem

from drake_skills.systems.gating import GatingDecision

#: Meshcat path of the wrist sphere.
WRIST_PATH = "/drake_skills/human_wrist"
#: Meshcat path of the status lamp (a box above the robot base, same colour).
LAMP_PATH = "/drake_skills/decision_lamp"
#: Colour while the motion is observed (grey) and for "unknown" (red).
PENDING_RGBA = (0.6, 0.6, 0.6, 1.0)
UNKNOWN_RGBA = (0.9, 0.05, 0.05, 1.0)
#: Colours of recognized skills, by component id modulo the palette (never red or grey).
PALETTE = ((0.10, 0.45, 0.85, 1.0), (0.15, 0.70, 0.25, 1.0), (0.60, 0.25, 0.75, 1.0),
           (0.95, 0.80, 0.10, 1.0), (0.10, 0.75, 0.75, 1.0), (0.55, 0.35, 0.15, 1.0),
           (0.95, 0.45, 0.70, 1.0), (0.30, 0.30, 0.90, 1.0))


def decision_rgba(decision: GatingDecision) -> tuple[float, float, float, float]:
    """Colour of a decision: grey pending, red unknown, a palette colour per component id."""
    if decision.status == "pending":
        return PENDING_RGBA
    if decision.status == "unknown":
        return UNKNOWN_RGBA
    return PALETTE[decision.component % len(PALETTE)]


class WristMarker(LeafSystem):
    """Publishes the wrist sphere and the decision colour to meshcat (and its recording).

    .. pydrake_system::

        name: WristMarker
        input_ports:
        - human_wrist
        - decision
        output_ports: []

    Parameters
    ----------
    meshcat : Meshcat
    publish_period : float
        Seconds between drawings (exact in binary).
    radius : float
        Sphere radius (m).
    p_WL : array, shape (3,)
        Where the status lamp stands (world frame).
    """

    def __init__(self, meshcat: Meshcat, publish_period: float = 1.0 / 32.0, radius: float = 0.035,
                 p_WL=(0.0, 0.6, 1.5)):
        super().__init__()
        self._meshcat = meshcat
        self._wrist = self.DeclareVectorInputPort("human_wrist", 3)
        self._decision = self.DeclareAbstractInputPort("decision", AbstractValue.Make(GatingDecision()))
        meshcat.SetObject(WRIST_PATH, Sphere(radius), Rgba(*PENDING_RGBA))
        meshcat.SetObject(LAMP_PATH, Box(0.08, 0.08, 0.08), Rgba(*PENDING_RGBA))
        meshcat.SetTransform(LAMP_PATH, RigidTransform(np.asarray(p_WL, float)))
        self.DeclarePeriodicPublishEvent(publish_period, 0.0, self._draw)
        self.DeclareInitializationPublishEvent(self._draw)

    def _draw(self, context: Context) -> None:
        # Without an active recording meshcat ignores time_in_recording and draws live.
        t = context.get_time()
        self._meshcat.SetTransform(WRIST_PATH, RigidTransform(self._wrist.Eval(context)), time_in_recording=t)
        rgba = list(decision_rgba(self._decision.Eval(context)))
        # every frame, so the recording's colour track steps instead of blending between decisions
        self._meshcat.SetProperty(WRIST_PATH, "color", rgba, time_in_recording=t)
        self._meshcat.SetProperty(LAMP_PATH, "color", rgba, time_in_recording=t)
