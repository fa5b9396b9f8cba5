"""An exclusive lock on a file, held across processes (``fcntl.flock`` on a sidecar lock file).

Every process that updates a library file takes :class:`FileLock` on it first, so a
load-extend-save of one process never interleaves with another's (the lost update of
"last writer wins"). The lock is on a sidecar ``.NAME.lock`` beside the file, never on
the file itself: an atomic save replaces the file (a new inode), and a lock on the old
inode would protect nothing. The sidecar is never deleted (deleting a lock file lets
two processes lock two different files of the same name).

The operating system releases the lock when its holder dies, SIGKILL included, so a
killed writer never leaves the file locked. The lock is reentrant within a process
(``update_file`` holds it while ``save`` takes it again) and serializes threads of one
process too. ``flock`` is advisory: a program that writes the file without taking the
lock is not stopped; on network file systems it is only as good as their ``flock``.
"""
from __future__ import annotations

import errno
import fcntl
import logging
import os
import threading
import time
from pathlib import Path

log = logging.getLogger(__name__)

_guard = threading.Lock()
#: lock path -> [thread lock, holding count, fd] of the locks this process holds or waits for
_held: dict[str, list] = {}


class LockTimeout(TimeoutError):
    """The file stayed locked by another process for longer than the timeout."""


def lock_path(path) -> Path:
    """The sidecar lock file of ``path``: ``.NAME.lock`` in the same directory."""
    path = Path(path)
    return path.with_name(f".{path.name}.lock")


class FileLock:
    """``with FileLock(path): ...`` holds an exclusive lock on ``path`` for the block.

    Parameters
    ----------
    path : path-like
        The file to protect (it need not exist; its directory is created).
    timeout : float, optional
        Seconds to wait for another holder; None waits as long as it takes.
        Raises :class:`LockTimeout` (naming the file and the holder's pid) when it expires.
    poll : float
        Seconds between two attempts while waiting.
    """

    def __init__(self, path, *, timeout: float | None = None, poll: float = 0.02):
        self.path = Path(path)
        self.lock_file = lock_path(self.path)
        self.timeout = timeout
        self.poll = float(poll)
        self._key = str(self.lock_file.resolve() if self.lock_file.parent.exists() else self.lock_file.absolute())

    def __enter__(self) -> "FileLock":
        with _guard:
            entry = _held.setdefault(self._key, [threading.RLock(), 0, None])
        rlock = entry[0]
        deadline = None if self.timeout is None else time.monotonic() + self.timeout
        if not rlock.acquire(timeout=-1 if deadline is None else max(0.0, self.timeout)):
            raise LockTimeout(f"'{self.path}' is locked by another thread of this process for more than "
                              f"{self.timeout} s")
        try:
            if entry[1] == 0:
                entry[2] = self._acquire(deadline)
            entry[1] += 1
        except BaseException:
            rlock.release()
            raise
        return self

    def _acquire(self, deadline) -> int:
        self.lock_file.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.lock_file, os.O_RDWR | os.O_CREAT, 0o666)
        waited = False
        try:
            while True:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    break
                except OSError as exc:
                    if exc.errno not in (errno.EAGAIN, errno.EACCES):
                        raise
                if not waited:
                    log.info("'%s' is locked by process %s: waiting", self.path, self._holder(fd))
                    waited = True
                if deadline is not None and time.monotonic() >= deadline:
                    raise LockTimeout(f"'{self.path}' is locked by process {self._holder(fd)} for more than "
                                      f"{self.timeout} s (lock file '{self.lock_file}')")
                time.sleep(self.poll)
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
            return fd
        except BaseException:
            os.close(fd)
            raise

    @staticmethod
    def _holder(fd: int) -> str:
        try:
            return os.pread(fd, 32, 0).decode().strip() or "?"
        except OSError:
            return "?"

    def __exit__(self, *exc) -> None:
        entry = _held[self._key]
        entry[1] -= 1
        if entry[1] == 0:
            fd, entry[2] = entry[2], None
            try:
                fcntl.flock(fd, fcntl.LOCK_UN)
            finally:
                os.close(fd)
        entry[0].release()
