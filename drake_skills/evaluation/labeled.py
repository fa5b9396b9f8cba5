"""Scoring an unlabeled library against task labels: correct, wrong or unknown.

A component's task label is the majority task of the training demonstrations it
absorbed (:class:`~drake_skills.library.labels.TaskVotes`, shared with
``CollaborationSim.teach``). A test motion is *correct* when the recognized
component's label is its task, *wrong* when it is another task, *unknown* when no
component explains it, *undecided* when more than one does and none clearly (the robot
does not act either way; the paper's tables have three columns, so
:func:`fractions_of` counts undecided with unknown and :func:`outcome_fractions`
keeps the four apart).
"""
from __future__ import annotations

from collections import Counter

import numpy as np

from drake_skills.library.incremental import LibraryConfig, SkillLibrary, Update
from drake_skills.library.labels import TaskVotes

#: Outcomes of one classification, in table order.
CORRECT, WRONG, UNKNOWN, UNDECIDED = 0, 1, 2, 3


class LabeledLibrary:
    """A :class:`SkillLibrary` that keeps the task votes of its components (as ``CollaborationSim.teach``)."""

    def __init__(self, config: LibraryConfig | None = None):
        self.library = SkillLibrary(config)
        self._votes = TaskVotes()

    @property
    def votes(self) -> dict[int, Counter]:
        """Component id -> task counts of the demonstrations it absorbed."""
        return self._votes.votes

    def teach(self, demo, workspace=None) -> Update:
        """Fold ``demo`` in and update the votes from the returned ``Update``."""
        update = self.library.partial_fit(demo, workspace=workspace)
        self._votes.record(update, demo.task)
        return update

    def label_of(self, component: int | None) -> str | None:
        """The majority task of the demonstrations ``component`` absorbed (None if none)."""
        return self._votes.label_of(component)

    def outcome(self, component: int | None, task: str, status: str | None = None) -> int:
        """CORRECT, WRONG, UNKNOWN or UNDECIDED for a recognition's component (and status) and the true task."""
        if component is None:
            return UNDECIDED if status == "undecided" else UNKNOWN
        return CORRECT if self.label_of(component) == task else WRONG

    def classify(self, human, task: str, workspace=None, observed_fraction: float | None = 1.0
                 ) -> tuple[int, int | None]:
        """The outcome and the recognized component (None: not executed) of a human motion (T, D_h)."""
        rec = self.library.recognize(human, observed_fraction=observed_fraction, workspace=workspace)
        return self.outcome(rec.component, task, rec.status), rec.component


def fractions_of(outcomes) -> list[float]:
    """Correct / wrong / unknown (undecided included) fractions of an array of outcomes (sum to 1)."""
    c, w, u, d = outcome_fractions(outcomes)
    return [c, w, u + d]


def outcome_fractions(outcomes) -> list[float]:
    """Correct / wrong / unknown / undecided fractions of an array of outcomes (sum to 1)."""
    o = np.asarray(outcomes).ravel()
    n = max(o.size, 1)
    return [float(np.sum(o == k)) / n for k in (CORRECT, WRONG, UNKNOWN, UNDECIDED)]
