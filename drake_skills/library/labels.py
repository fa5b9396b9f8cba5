"""Task labels of the components of an (unlabeled) library, for scoring and display.

The library never sees labels; a caller that knows the task of each
demonstration it teaches can follow, from the returned ``Update``s, which
tasks each component absorbed: a creation starts a vote, an update adds one,
a merge moves the absorbed component's votes to the kept one, a deletion
drops them.
"""
from __future__ import annotations

from collections import Counter

from drake_skills.library.incremental import Update


class TaskVotes:
    """Per component id, how many taught demonstrations of each task it absorbed."""

    def __init__(self):
        self.votes: dict[int, Counter] = {}

    def record(self, update: Update, task) -> None:
        """Follow one ``partial_fit`` of a demonstration of ``task``."""
        for k in update.created:
            self.votes[k] = Counter({task: 1})
        for k in update.updated:
            self.votes.setdefault(k, Counter())[task] += 1
        for kept, gone in update.merged:
            self.votes.setdefault(kept, Counter()).update(self.votes.pop(gone, Counter()))
        for k in update.deleted:
            self.votes.pop(k, None)

    def label_of(self, component: int | None):
        """The majority task of the demonstrations ``component`` absorbed (None if none)."""
        c = self.votes.get(component) if component is not None else None
        return c.most_common(1)[0][0] if c else None
