"""Atomic file writes shared by demonstration files and library files."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path


def _umask() -> int:
    """The process umask (reading it means setting it, so set it straight back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write(path: Path, write, *, fsync: bool = False) -> None:
    """Write through ``write(file)`` to a temporary file beside ``path``, then rename it onto ``path``.

    Readers see the old file or the new one, never a partial one; on any error the
    temporary file is removed and ``path`` is untouched. The file gets the mode a plain
    ``open()`` would give it (``0666 & ~umask``), not ``mkstemp``'s owner-only 0600.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as f:
            write(f)
            if fsync:
                f.flush()
                os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
