"""Library files: :class:`FileMixin` is the storage half of :class:`~drake_skills.library.incremental.SkillLibrary`.

``save`` and ``load`` hold the file's lock (:mod:`drake_skills._lock`) and check its
generation (:mod:`drake_skills.library.storage`, which knows the file format and the
state, never the library class), so two processes extending one file never silently
drop each other's demonstrations; ``update_file`` is the load-learn-save of one
process under the lock. The mixin reads the library through ``state()``,
``from_state()``, ``partial_fit()``, ``config`` and the attribute ``_origin`` (the
file and generation last loaded from or saved to) that ``SkillLibrary`` defines.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from drake_skills._lock import FileLock
from drake_skills.data.demonstration import Demonstration
from drake_skills.library import storage
from drake_skills.library.config import LibraryConfig
from drake_skills.library.views import Update


class FileMixin:
    """Saving, loading and locked updating of library files for :class:`~drake_skills.library.incremental.SkillLibrary`."""

    def save(self, path, *, expected_generation: int | None | str = "loaded",
             timeout: float | None = None) -> Path:
        """Write the library atomically to ``path`` (.npz, no pickle); returns the path written.

        ``.npz`` is appended to a path without it. The save holds the file's lock
        (:mod:`drake_skills._lock`) and refuses to replace a file that changed since
        this library last read or wrote it, so two processes extending one file never
        silently drop each other's demonstrations (to fold demonstrations into a file
        that others update too, use :meth:`update_file`).

        Parameters
        ----------
        path : path-like
        expected_generation : int, None or "loaded"
            The file generation (the count of its saves, in its metadata) the save
            expects to replace. "loaded" (default): the generation this library was
            loaded from or last saved to ``path`` with, and no check if it never was
            (a new library saved over a file replaces it). None: no check.
        timeout : float, optional
            Seconds to wait for another process's lock (None: as long as it takes).

        Raises
        ------
        LibraryChangedError
            The file changed since this library read it (nothing is written).
        """
        path = storage.library_path(path)
        if expected_generation == "loaded":
            origin = self._origin
            expected_generation = origin[1] if origin is not None and origin[0] == _key(path) else None
        elif expected_generation is not None and (isinstance(expected_generation, bool)
                                                  or not isinstance(expected_generation, int)):
            raise ValueError(f"expected_generation must be an int, None or 'loaded', got {expected_generation!r}")
        path, generation = storage.save_checked(self.state(), path, expected_generation, timeout=timeout)
        self._origin = (_key(path), generation)
        return path

    @property
    def generation(self) -> int | None:
        """The generation of the file this library was last loaded from or saved to (None if neither)."""
        return None if self._origin is None else self._origin[1]

    @classmethod
    def load(cls, path) -> "SkillLibrary":
        """Read a library written by :meth:`save`; corrupt or foreign files raise ValueError."""
        state, generation = storage.load_versioned(path)
        lib = cls.from_state(state)
        lib._origin = (_key(path), generation)
        return lib

    @classmethod
    def update_file(cls, path, demos: Sequence[Demonstration], *, workspace=None,
                    config: LibraryConfig | None = None, timeout: float | None = None,
                    on_update=None) -> tuple["SkillLibrary", list[Update]]:
        """Fold ``demos`` into the library file at ``path`` under its lock: load (or start), learn, save.

        While one process holds the lock, others wait (``timeout``), so any number of
        processes may extend one file at once and every demonstration ends up in it.
        Either every demonstration is folded in and saved, or (bad input, numerics) an
        exception is raised and the file is left as it was.

        Parameters
        ----------
        path : path-like
            The library file; created if missing (``.npz`` appended if missing).
        demos : sequence of Demonstration
        workspace : Workspace, or sequence of (Workspace or None), optional
            One workspace for all demonstrations, or one per demonstration.
        config : LibraryConfig, optional
            For a new file only; an existing library keeps its own (a different one
            is an error).
        timeout : float, optional
            Seconds to wait for the lock (None: as long as it takes).
        on_update : callable, optional
            Called as ``on_update(i, demo, update, library)`` after each demonstration.

        Returns
        -------
        library : SkillLibrary
            As saved.
        updates : list of Update
        """
        demos = list(demos)
        if isinstance(workspace, (list, tuple)):
            if len(workspace) != len(demos):
                raise ValueError(f"{len(workspace)} workspaces for {len(demos)} demonstrations")
            workspaces = list(workspace)
        else:
            workspaces = [workspace] * len(demos)
        path = storage.library_path(path)
        with FileLock(path, timeout=timeout):
            if path.exists():
                lib = cls.load(path)
                if config is not None and config.dict() != lib.config.dict():
                    raise ValueError(f"library file '{path}' exists with its own config; a config applies to a "
                                     f"new library only")
            else:
                lib = cls(config)
            updates = []
            for i, (d, ws) in enumerate(zip(demos, workspaces)):
                updates.append(lib.partial_fit(d, workspace=ws))
                if on_update is not None:
                    on_update(i, d, updates[-1], lib)
            lib.save(path, timeout=timeout)
        return lib, updates


def _key(path) -> str:
    """What identifies a library file across the names it is reached by."""
    return str(Path(path).resolve())
