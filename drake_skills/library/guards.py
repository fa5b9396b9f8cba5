"""The two slips the library cannot undo later, found in a motion's samples: a missing workspace, other units.

:meth:`SkillLibrary <drake_skills.library.incremental.SkillLibrary>` warns about them
(at most once per library object and kind) with the message :func:`data_warning`
composes; the library keeps working.
"""
from __future__ import annotations

import numpy as np

from drake_skills.data.workspace import Workspace
from drake_skills.library.views import DataWarning, UnitsWarning, WorkspaceWarning

__all__ = ["ROBOT_UNITS_FACTOR", "UNITS_RANGE", "data_warning", "robot_units_error", "seen_robot_rms",
           "units_error"]

#: The extent of a motion (its largest per-axis range after Eq. 14) as fractions of the
#: normalized workspace scale (10 without a workspace, as the settings assume): a whole
#: motion spanning less than the first, or any motion spanning more than the second, is
#: taken to be in other units (:class:`UnitsWarning`). Whole motions of our data sets
#: span 0.14-1.0 of the scale normalized (LASA 1.4-5.3 units with the letters' bounding
#: box, salad 2.0-7.0, buetepage_hr 4.7-9.9) and 0.03-0.06 given in metres without a
#: workspace (0.28-0.63 m); in millimetres, 28-63.
UNITS_RANGE = (0.1, 10.0)
#: A demonstration whose robot weights are this many times larger in RMS than those of all
#: the demonstrations the library has seen (pooled) is refused: degrees for radians
#: (57x) or millimetres for metres. The RMS of the robot weights of one data set's
#: demonstrations differs by at most 2.7x: buetepage_hr 1.05-2.30 rad (all 41), salad
#: subjects 1-10 0.67-1.07 rad, 100 synthetic skills 0.31-0.83.
ROBOT_UNITS_FACTOR = 30.0


def data_warning(y: np.ndarray, ws: Workspace | None, normalized: bool, *, whole: bool, query: bool,
                 where: str | None, trained_with_workspace: bool | None
                 ) -> tuple[str, type[DataWarning], str] | None:
    """The warning a motion calls for, as ``(kind, category, message)``, or None.

    Parameters
    ----------
    y : array, shape (n, D_h)
        The samples after Eq. (14).
    ws : Workspace or None
        The workspace that applied (the call's or the config's).
    normalized : bool
        The caller gave samples already in normalized units.
    whole : bool
        ``y`` covers a whole motion (a prefix may span little).
    query : bool
        The motion is asked about (recognition, prediction), not taught.
    where : str or None
        What to call the motion in the message (e.g. a file name).
    trained_with_workspace : bool or None
        Whether the library was trained with a workspace (None: not known, or not trained yet).
    """
    if ws is None and not normalized and trained_with_workspace:
        call = "recognize()/predict_robot()" if query else "partial_fit()"
        return ("workspace", WorkspaceWarning,
                f"{where + ': ' if where else ''}{call} without a workspace on a library trained with "
                f"one: the motion is taken in raw units and will likely be 'unknown'; give the subject's "
                f"workspace (workspace= in Python, --workspace or a workspace.json / calibration.npz beside the "
                f"files on the command line) or, for samples already in normalized units, normalized=True")
    if ws is not None and not normalized and trained_with_workspace is False:
        call = "recognize()/predict_robot()" if query else "partial_fit()"
        return ("workspace", WorkspaceWarning,
                f"{where + ': ' if where else ''}{call} with a workspace on a library trained without one (its "
                f"demonstrations were taken as they were: no workspace.json or calibration.npz beside them, or "
                f"partial_fit without workspace=): the motion is normalized into "
                f"other units than the library's and will likely be 'unknown'; leave out the workspace, or teach "
                f"a new library with workspaces")
    scale = ws.scale if ws is not None else 10.0
    extent = float(np.ptp(y, axis=0).max())
    low, high = UNITS_RANGE[0] * scale, UNITS_RANGE[1] * scale
    if (whole and extent < low) or extent > high:
        side = "below" if extent < low else "above"
        if ws is not None:
            fix = "are the workspace and the data in the same units?"
        elif normalized:
            fix = "normalized=True expects samples in the library's normalized units (Eq. 14 applied)."
        elif query and trained_with_workspace is False:
            fix = ("the library was trained without a workspace too: if its demonstrations were in these units, "
                   "its answers are consistent with them, but its settings (prior_floor) assume [0, %g]; a "
                   "library taught with workspaces (Workspace.from_calibration) needs no such care." % scale)
        else:
            fix = ("raw metres or millimetres? Pass the subject's workspace= (Workspace.from_calibration("
                   "motions), or the bounding box of the training data: Workspace.from_calibration([d.human "
                   "for d in demos])), or normalize the data to [0, %g] first." % scale)
        what = where or ("the motion" if query else "the demonstration")
        return ("units", UnitsWarning,
                f"{what} spans {extent:.3g} units, far {side} the normalized range [0, {scale:g}] the "
                f"library's settings assume (a whole motion spans {low:g} to {high:g} units in it): "
                f"{fix}")
    return None


def units_error(y: np.ndarray, ws: Workspace | None, where: str | None) -> str | None:
    """Why a demonstration taught with workspace ``ws`` must be refused, or None.

    A whole motion spanning more than ``UNITS_RANGE[1]`` times the workspace's scale after
    Eq. (14) (ten workspaces) is in other units than its workspace (millimetres against a
    workspace in metres): taught, it would become a component of its own, and queries near
    it would all be "undecided"; nothing can take it out of the library again. Motions that
    span little are only warned about (:func:`data_warning`): a small gesture is possible.
    Without a workspace the caller's units are unknown, and :func:`data_warning` warns.
    """
    if ws is None:
        return None
    extent = float(np.ptp(y, axis=0).max())
    limit = UNITS_RANGE[1] * ws.scale
    if not extent > limit:
        return None
    return (f"{where + ': ' if where else ''}the motion spans {extent:.3g} normalized units, more than "
            f"{UNITS_RANGE[1]:g} times its workspace's scale ({ws.scale:g}): the data and the workspace are in "
            f"different units (millimetres against metres?). The library is unchanged; give them in the same units")


def robot_units_error(w_r: np.ndarray, seen_rms: float | None, where: str | None) -> str | None:
    """Why a demonstration with robot weights ``w_r`` must be refused, or None.

    With the normalized basis a robot weight is a local average of the trajectory, so the
    weights' RMS is the trajectory's scale. ``seen_rms``: the RMS of the robot weights of
    every demonstration seen so far (None or 0: none seen, nothing to compare with; see
    :func:`seen_robot_rms`). Refused when this one's RMS is more than
    :data:`ROBOT_UNITS_FACTOR` times that: the same robot in other units (degrees for
    radians). A library trained on responses that barely moved before a large one would
    refuse it too: the caller can skip the check (``partial_fit(..., check_units=False)``,
    ``learn --raw-units``).
    """
    if not seen_rms or not np.isfinite(seen_rms):
        return None
    with np.errstate(over="ignore", invalid="ignore"):
        rms = float(np.sqrt(np.mean(np.square(w_r))))
    if not rms > ROBOT_UNITS_FACTOR * seen_rms:
        return None
    return (f"{where + ': ' if where else ''}the robot's values are {rms / seen_rms:.3g} times larger (RMS "
            f"{rms:.3g}) than the RMS of all demonstrations so far ({seen_rms:.3g}): other units (degrees for "
            f"radians, millimetres for metres)? The library is unchanged; convert them, or pass check_units=False "
            f"(learn --raw-units) if the earlier responses barely moved the robot")


def seen_robot_rms(total_mean: np.ndarray, total_m2: np.ndarray, n: int, n_human: int) -> float | None:
    """RMS of the robot weights over the ``n`` demonstrations of the running totals (``SharedScale``), or None."""
    if n < 1 or total_mean.shape[0] <= n_human:
        return None
    m, v = total_mean[n_human:], total_m2[n_human:] / n
    return float(np.sqrt(np.mean(m * m + v)))
