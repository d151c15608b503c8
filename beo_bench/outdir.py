"""Output directories the package may write into: empty ones, or ones it marked.

A command given an existing directory as ``--out`` writes there only when the directory is
empty or carries the command's marker file (written here, atomically, when the command
first uses the directory). A non-empty directory without it is the user's: the command
refuses it and touches nothing, whatever names its files have (a user's ``README.md`` or
``summary.json`` looks like ours but is not).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
from collections.abc import Callable, Iterator
from pathlib import Path

from beo_bench.atomic import atomic_write_bytes

__all__ = ["foreign_files", "locked", "mark", "shown"]


def foreign_files(d: Path, marker: str) -> list[str] | None:
    """None when ``d`` carries ``marker`` (a plain file: a symbolic link is not ours), else
    the names ``d`` holds (empty for an empty directory). The temporary files of writing
    the marker are left out: a second process marking the same new directory at the same
    moment does not make it foreign. ``OSError`` for an unreadable ``d``."""
    p = d / marker
    if p.is_file() and not p.is_symlink():
        return None
    return sorted(
        n
        for n in os.listdir(d)
        if n != marker and not (n.startswith(f".{marker}.") and n.endswith(".tmp"))
    )


def mark(d: Path, marker: str, text: str) -> None:
    """Write ``d``'s marker file (atomically: a reader never sees half of it)."""
    atomic_write_bytes(d / marker, text)


def shown(names: list[str]) -> str:
    """A few of ``names``, for a message."""
    return ", ".join(names[:3]) + (", ..." if len(names) > 3 else "")


@contextlib.contextmanager
def locked(path: Path, busy: Callable[[str], Exception]) -> Iterator[None]:
    """Hold an exclusive ``flock`` on ``path`` (created if missing, never through a symbolic
    link, with this PID written in it) for the ``with`` block. When another process holds
    it, ``busy(pid)`` is raised (the holder's PID as the file says, or ``unknown``). The
    kernel releases the lock when the holder exits, however it exits, so a lock file left
    behind blocks nothing; it is never deleted (the next writer reuses it)."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = (os.pread(fd, 64, 0).decode(errors="replace").split() or ["unknown"])[0]
            raise busy(holder) from None
        pid = f"{os.getpid()}\n".encode()
        os.pwrite(fd, pid, 0)  # write, then cut: a reader never finds the file empty
        os.ftruncate(fd, len(pid))
        yield
    finally:
        os.close(fd)  # releases the lock
