"""Atomic file and directory writes: a reader sees the old content or the new, never half.

Every file the package stores (cache entries, dataset shards, model directories,
checkpoints, run records, summaries, recordings) is written through this module:

- the new content goes to a temporary sibling (same directory, so the same file system and
  the final step is a rename, which POSIX makes atomic), named
  ``.<name>.<random>.<pid>.tmp``: hidden, recognisably ours (``modeldir.TEMP_FILE``), and
  created with ``O_EXCL | O_NOFOLLOW``, so a file or symbolic link someone put at that name
  is never written through;
- the temporary is flushed and ``fsync``-ed before the rename (see :func:`atomic_write`),
  then ``os.replace``-d onto the target (the directory itself is not ``fsync``-ed: a crash
  can then undo the rename, which leaves the old, whole file: still all or nothing); a
  symbolic link at the target is replaced by the new file, never followed, so nothing
  outside the package's own paths is overwritten;
- on any exception (a full disk, a failing serialiser, ``KeyboardInterrupt``) the temporary
  is removed and the target is left as it was. Only a process killed outright can leave a
  temporary behind, and the target is then still whole.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Literal

Mode = Literal["wb", "w"]


def _create_temp(path: Path, perms: int) -> tuple[int, Path]:
    """An exclusively created, empty temporary file beside ``path`` and its descriptor."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
    for _ in range(100):
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.{os.getpid()}.tmp")
        try:
            # the umask applies to ``perms``, as for a plain open(): a stored file keeps the
            # permissions the user's other files get
            return os.open(tmp, flags, perms), tmp
        except FileExistsError:
            continue  # a name clash (or something planted there): draw another name
    raise FileExistsError(f"no free temporary name beside {path}")  # pragma: no cover


@contextlib.contextmanager
def atomic_write(
    path: Path | str, mode: Mode = "wb", *, durable: bool = True, perms: int = 0o666
) -> Iterator[IO]:
    """Open a temporary file to write ``path``'s new content into (``mode`` ``"wb"``, or
    ``"w"`` for UTF-8 text) and, when the block ends without an exception, rename it onto
    ``path``. An exception in the block removes the temporary and leaves ``path`` as it was.

    ``durable`` (the default) ``fsync``-s the data before the rename: without it a crash
    of the machine soon after can leave the rename on disk but not the data (ext4's delayed
    allocation, XFS), i.e. an empty or truncated file where a complete one was, which is
    what writing atomically is meant to exclude. Only a file that is cheap to rebuild and
    written often may pass ``durable=False``. ``perms``: the new file's permission bits
    (before the umask); ``0o600`` keeps it private to the user.
    """
    if mode not in ("wb", "w"):
        raise ValueError(f"atomic_write mode {mode!r}: use 'wb' (bytes) or 'w' (UTF-8 text)")
    path = Path(path)
    fd, tmp = _create_temp(path, perms)
    try:
        with os.fdopen(fd, mode, encoding="utf-8" if mode == "w" else None) as f:
            yield f
            f.flush()
            if durable:
                os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)  # our own temporary file, never the target
        raise


@contextlib.contextmanager
def atomic_path(path: Path | str) -> Iterator[Path]:
    """For a library that writes a file by name (a figure, a rerun recording): a new,
    empty temporary file beside ``path`` for it to write, renamed onto ``path`` when the
    block ends without an exception, removed otherwise; as :func:`atomic_write` in every
    other respect."""
    path = Path(path)
    fd, tmp = _create_temp(path, 0o666)
    os.close(fd)
    try:
        yield tmp
        _fsync(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)  # our own temporary file, never the target
        raise


def atomic_write_bytes(path: Path | str, data: bytes | str, *, durable: bool = True) -> None:
    """Write ``data`` (``str`` as UTF-8) to ``path`` atomically (:func:`atomic_write`)."""
    with atomic_write(path, "wb", durable=durable) as f:
        f.write(data.encode() if isinstance(data, str) else data)


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_files(root: Path) -> None:
    for p in root.rglob("*"):
        if p.is_file() and not p.is_symlink():
            _fsync(p)


@contextlib.contextmanager
def atomic_dir(
    path: Path | str, install: Callable[[Path, Path], object] | None = None
) -> Iterator[Path]:
    """A new, empty temporary directory beside ``path`` to write a whole directory into;
    when the block ends without an exception its files are ``fsync``-ed (as in
    :func:`atomic_write`) and ``install(tmp, path)`` moves it into place (default: a plain
    rename, which fails when ``path`` is a non-empty directory). An exception in the block or
    in ``install`` removes the temporary directory and leaves ``path`` as it was.

    ``install`` is where a caller puts its rules for replacing what is at ``path``: model
    directories use :func:`beo_bench.perception.modeldir.install`, which refuses a
    directory the package did not write and keeps the old model until the new one is in
    place."""
    path = Path(path)
    tmp = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp"))
    try:
        yield tmp
        _fsync_files(tmp)
        if install is None:
            os.replace(tmp, path)
        else:
            install(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)  # our own temporary directory
        raise
