"""Task labels of the components of an (unlabeled) library, for scoring and display.

The library keeps the task names of the demonstrations it absorbed with its clusters
(``Cluster.tasks``, weighted by responsibility), learns with them (``LibraryConfig.same_task_reach``,
``keep_tasks_apart``) and refuses to act on a skill taught as several tasks
(``mixed_task_share``), but it holds no label per component; a caller
that wants each component's label for scoring or display follows, from the returned
``Update``s, which tasks each component absorbed: a creation starts a vote, an update adds
one, a merge moves the absorbed component's votes to the kept one, a deletion drops them.
"""
from __future__ import annotations

from collections import Counter

from drake_skills.library.incremental import Update


class TaskVotes:
    """Per component id, how many taught demonstrations of each task its two sub-clusters absorbed.

    Votes are kept per sub-cluster so that they follow a split: the component that
    keeps its id keeps the first sub-cluster's votes, the new one takes the second's.
    """

    def __init__(self):
        self._votes: dict[int, list[Counter]] = {}

    @property
    def votes(self) -> dict[int, Counter]:
        """Component id -> task counts of all the demonstrations it absorbed."""
        return {k: v[0] + v[1] for k, v in self._votes.items()}

    def record(self, update: Update, task) -> None:
        """Follow one ``partial_fit`` of a demonstration of ``task``."""
        for k in update.created:
            self._votes[k] = [Counter({task: 1}), Counter()]
        for k in update.updated:
            j = update.subcluster.get(k, 0)
            self._votes.setdefault(k, [Counter(), Counter()])[j][task] += 1
        for kept, gone in update.merged:
            a = self._votes.get(kept, [Counter(), Counter()])
            b = self._votes.pop(gone, [Counter(), Counter()])
            self._votes[kept] = [a[0] + a[1], b[0] + b[1]]
        for kept, new in update.split:
            a, b = self._votes.get(kept, [Counter(), Counter()])
            self._votes[kept], self._votes[new] = [a, Counter()], [b, Counter()]
        for k in update.deleted:
            self._votes.pop(k, None)

    def to_dict(self) -> dict:
        """JSON-ready: ``{"<id>": [{task: count}, {task: count}]}`` (the votes of its two sub-clusters)."""
        return {str(k): [dict(v[0]), dict(v[1])] for k, v in sorted(self._votes.items())}

    @classmethod
    def from_dict(cls, d: dict) -> "TaskVotes":
        """The inverse of :meth:`to_dict`; a malformed entry raises ``ValueError``."""
        out = cls()
        try:
            for k, pair in d.items():
                a, b = pair
                out._votes[int(k)] = [Counter({str(t): int(n) for t, n in a.items()}),
                                      Counter({str(t): int(n) for t, n in b.items()})]
        except (AttributeError, TypeError, ValueError) as exc:
            raise ValueError(f"task votes must map component ids to two {{task: count}} objects ({exc})") from None
        return out

    def label_of(self, component: int | None):
        """The majority task of the demonstrations ``component`` absorbed (None if none)."""
        if component is None or component not in self._votes:
            return None
        c = self._votes[component][0] + self._votes[component][1]
        return c.most_common(1)[0][0] if c else None
