"""``Shared``: the base of the immutable values the systems keep in abstract state and pass between ports."""
from __future__ import annotations


class Shared:
    """A value that is never modified after it is made, so copies may share it.

    Drake copies abstract state and port values (``copy.deepcopy`` for Python
    objects) at every update: for the gating's growing record of a trial (its
    samples and beliefs) that cost more than the rest of the simulation. Subclasses
    are frozen dataclasses whose arrays are never written, so a copy is the value
    itself.
    """

    __slots__ = ()

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self
