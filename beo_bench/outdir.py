"""Output directories the package may write into: empty ones, or ones it marked.

A command given an existing directory as ``--out`` writes there only when the directory is
empty or carries the command's marker file (written here, atomically, when the command
first uses the directory). A non-empty directory without it is the user's: the command
refuses it and touches nothing, whatever names its files have (a user's ``README.md`` or
``summary.json`` looks like ours but is not).
"""

from __future__ import annotations

import os
from pathlib import Path

from beo_bench.atomic import atomic_write_bytes

__all__ = ["foreign_files", "mark", "shown"]


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
