"""drake-skills: an open-ended library of collaborative skills (Interaction ProMPs),
learned one demonstration at a time and run as a Drake controller.

Public names::

    from drake_skills import SkillLibrary, LibraryConfig, InteractionProMP, Demonstration
    from drake_skills import Workspace, TaskVotes   # a person's workspace; task labels of components

Importing the package does not import pydrake; only ``drake_skills.systems``
and ``drake_skills.sim`` do.
"""
from __future__ import annotations

__version__ = "0.1.0"

_LAZY = {
    "Demonstration": "drake_skills.data.demonstration",
    "InteractionProMP": "drake_skills.promp.interaction",
    "SkillLibrary": "drake_skills.library.incremental",
    "LibraryConfig": "drake_skills.library.incremental",
    "Workspace": "drake_skills.data.workspace",
    "TaskVotes": "drake_skills.library.labels",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'drake_skills' has no attribute {name!r}")
