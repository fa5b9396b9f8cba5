"""The two slips the library cannot undo later, found in a motion's samples: a missing workspace, other units.

:meth:`SkillLibrary <drake_skills.library.incremental.SkillLibrary>` warns about them
(at most once per library object and kind) with the message :func:`data_warning`
composes; the library keeps working.
"""
from __future__ import annotations

import numpy as np

from drake_skills.data.workspace import Workspace
from drake_skills.library.views import DataWarning, UnitsWarning, WorkspaceWarning

__all__ = ["UNITS_RANGE", "data_warning"]

#: The extent of a motion (its largest per-axis range after Eq. 14) as fractions of the
#: normalized workspace scale (10 without a workspace, as the settings assume): a whole
#: motion spanning less than the first, or any motion spanning more than the second, is
#: taken to be in other units (:class:`UnitsWarning`). Whole motions of our data sets
#: span 0.14-1.0 of the scale normalized (LASA 1.4-5.3 units with the letters' bounding
#: box, salad 2.0-7.0, buetepage_hr 4.7-9.9) and 0.03-0.06 given in metres without a
#: workspace (0.28-0.63 m); in millimetres, 28-63.
UNITS_RANGE = (0.1, 10.0)


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
        Whether the library was trained with a workspace.
    """
    if ws is None and not normalized and trained_with_workspace:
        call = "recognize()/predict_robot()" if query else "partial_fit()"
        return ("workspace", WorkspaceWarning,
                f"{where + ': ' if where else ''}{call} without a workspace on a library trained with "
                f"one: the motion is taken in raw units and will likely be 'unknown'; give the subject's "
                f"workspace (workspace= in Python, --workspace or a workspace.json / calibration.npz beside the "
                f"files on the command line) or, for samples already in normalized units, normalized=True")
    scale = ws.scale if ws is not None else 10.0
    extent = float(np.ptp(y, axis=0).max())
    low, high = UNITS_RANGE[0] * scale, UNITS_RANGE[1] * scale
    if (whole and extent < low) or extent > high:
        side = "below" if extent < low else "above"
        if ws is not None:
            fix = "are the workspace and the data in the same units?"
        elif normalized:
            fix = "normalized=True expects samples in the library's normalized units (Eq. 14 applied)."
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
