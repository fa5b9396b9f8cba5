"""``WristMarker``: draws the person's wrist, its trail and the gating's belief in meshcat.

What a person watching the recording sees:

* the wrist as a sphere and its trail over the last ``TRAIL_SECONDS`` (small spheres);
* the decision colour, on the wrist sphere and on a lamp above the robot: grey while
  nothing is committed, the committed skill's colour (one per component id) while the
  robot acts, magenta for "unknown" and amber for "undecided" at rest, for as long as the
  robot waits (magenta rather than red: nothing in the scene has that colour, while the
  tomato is red);
* a confidence bar beside the lamp: its height is the probability of the most
  probable skill so far, its colour that skill's.

Meshcat puts an object's geometry one level below the path given to ``SetObject``
(``<path>/<object>``), and a colour is a property of the geometry's material: the
recording animates ``material.color`` of ``<path>/<object>`` (a track on ``color`` of
``<path>`` animates nothing: the browser logs "PropertyBinding ... undefined.color
... wasn't found", which is how the colours stayed grey before).
"""
from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import Box, Meshcat, Rgba, Sphere
from pydrake.math import RigidTransform
from pydrake.systems.framework import Context, LeafSystem

from drake_skills.systems.gating import GatingDecision

#: Meshcat path of the wrist sphere.
WRIST_PATH = "/drake_skills/human_wrist"
#: Meshcat path of the status lamp (a box above the robot base, same colour).
LAMP_PATH = "/drake_skills/decision_lamp"
#: Meshcat path of the confidence bar beside the lamp.
BAR_PATH = "/drake_skills/confidence_bar"
#: Meshcat folder of the trail spheres.
TRAIL_PATH = "/drake_skills/wrist_trail"
#: Length of the trail (s) and the number of spheres in it.
TRAIL_SECONDS = 1.5
TRAIL_POINTS = 24
#: Height of the confidence bar at probability 1 (m).
BAR_HEIGHT = 0.3
#: Colour while nothing is committed (grey), for "unknown" (magenta) and "undecided" (amber).
PENDING_RGBA = (0.6, 0.6, 0.6, 1.0)
UNKNOWN_RGBA = (0.85, 0.05, 0.75, 1.0)
UNDECIDED_RGBA = (1.0, 0.65, 0.0, 1.0)
TRAIL_RGBA = (0.35, 0.35, 0.35, 0.6)
#: Colours of skills, by component id modulo the palette (never magenta, amber or grey).
PALETTE = ((0.10, 0.45, 0.85, 1.0), (0.15, 0.70, 0.25, 1.0), (0.60, 0.25, 0.75, 1.0),
           (0.10, 0.75, 0.75, 1.0), (0.55, 0.35, 0.15, 1.0), (0.90, 0.35, 0.25, 1.0),
           (0.30, 0.30, 0.90, 1.0), (0.50, 0.80, 0.10, 1.0))


def skill_rgba(component: int) -> tuple[float, float, float, float]:
    """The colour of a component id."""
    return PALETTE[int(component) % len(PALETTE)]


def decision_rgba(decision: GatingDecision) -> tuple[float, float, float, float]:
    """Colour of a decision: the committed skill's, or grey pending, red unknown, amber undecided."""
    if decision.component is not None:
        return skill_rgba(decision.component)
    if decision.final and decision.status == "unknown":
        return UNKNOWN_RGBA
    if decision.final and decision.status == "undecided":
        return UNDECIDED_RGBA
    return PENDING_RGBA


def geometry_path(path: str) -> str:
    """Where meshcat keeps the geometry (and so its material) of an object set at ``path``."""
    return path + "/<object>"


def set_color(meshcat: Meshcat, path: str, rgba, time: float) -> None:
    """Animate the colour of the object at ``path`` (its material's, see the module docstring)."""
    meshcat.SetProperty(geometry_path(path), "material.color", [float(c) for c in rgba[:3]], time_in_recording=time)


class WristMarker(LeafSystem):
    """Publishes the wrist, its trail, the decision colour and the confidence to meshcat (and its recording).

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
        Where the status lamp stands (world frame); the bar stands beside it.
    """

    def __init__(self, meshcat: Meshcat, publish_period: float = 1.0 / 32.0, radius: float = 0.035,
                 p_WL=(0.0, 0.6, 1.5)):
        super().__init__()
        self._meshcat = meshcat
        self._period = float(publish_period)
        self._wrist = self.DeclareVectorInputPort("human_wrist", 3)
        self._decision = self.DeclareAbstractInputPort("decision", AbstractValue.Make(GatingDecision()))
        self._p_WL = np.asarray(p_WL, float)
        meshcat.SetObject(WRIST_PATH, Sphere(radius), Rgba(*PENDING_RGBA))
        meshcat.SetObject(LAMP_PATH, Box(0.12, 0.12, 0.12), Rgba(*PENDING_RGBA))
        meshcat.SetTransform(LAMP_PATH, RigidTransform(self._p_WL))
        meshcat.SetObject(BAR_PATH, Box(0.04, 0.04, BAR_HEIGHT), Rgba(*PENDING_RGBA))
        for i in range(TRAIL_POINTS):
            meshcat.SetObject(f"{TRAIL_PATH}/{i}", Sphere(0.4 * radius), Rgba(*TRAIL_RGBA))
        self._trail: list[np.ndarray] = []
        self._last_trail = -np.inf
        self.DeclarePeriodicPublishEvent(publish_period, 0.0, self._draw)
        self.DeclareInitializationPublishEvent(self._start)

    def _start(self, context: Context) -> None:
        self._trail, self._last_trail = [], -np.inf  # a new trial: a new trail
        self._draw(context)

    def _draw(self, context: Context) -> None:
        # Without an active recording meshcat ignores time_in_recording and draws live.
        t = context.get_time()
        mc = self._meshcat
        p = np.array(self._wrist.Eval(context))
        mc.SetTransform(WRIST_PATH, RigidTransform(p), time_in_recording=t)
        decision = self._decision.Eval(context)
        rgba = list(decision_rgba(decision))
        # every frame, so the recording's colour track steps instead of blending between decisions
        set_color(mc, WRIST_PATH, rgba, t)
        set_color(mc, LAMP_PATH, rgba, t)
        belief = decision.belief
        conf = 0.0 if belief is None else float(belief.confidence)
        best = None if belief is None else belief.best
        height = max(conf, 0.02) * BAR_HEIGHT
        mc.SetTransform(BAR_PATH, RigidTransform(self._p_WL + [0.0, 0.12, height / 2 - 0.04]), time_in_recording=t)
        mc.SetProperty(BAR_PATH, "scale", [1.0, 1.0, max(conf, 0.02)], time_in_recording=t)
        set_color(mc, BAR_PATH, PENDING_RGBA if best is None else skill_rgba(best), t)
        if t - self._last_trail >= TRAIL_SECONDS / TRAIL_POINTS - 1e-9:
            self._trail = (self._trail + [p])[-TRAIL_POINTS:]
            self._last_trail = t
        for i in range(TRAIL_POINTS):
            q = self._trail[i] if i < len(self._trail) else p
            mc.SetTransform(f"{TRAIL_PATH}/{i}", RigidTransform(q), time_in_recording=t)
