"""Scanning a user's dataset folder safely: symbolic links that lead out of the dataset's
root are skipped with a warning and never followed, and every scan is bounded.

A dataset folder is input the user may not have made: a link ``ROOT/evil -> /`` made a scan
that followed links walk the whole file system (438 meshes from elsewhere as class "evil",
4.9 GB in 180 s), and a file link to ``/etc/passwd`` was opened and parsed. So a file link
is taken only when its target resolves inside the root (a dataset may link its own files);
a folder link below a category folder is never taken, with a warning (``bowl/up -> ..``
made every other category's files bowls; a link to a folder inside the category is reached
by the scan anyway, so following it would scan it twice); a directory reached twice is
walked once, folders deeper than
:data:`MAX_DEPTH` below a category are not searched, and a scan that visits more than
:func:`max_files` entries stops with :class:`~beo_bench.errors.DatasetTooLargeError`.
"""

from __future__ import annotations

import functools
import os
import warnings
from collections.abc import Iterator
from pathlib import Path

from beo_bench.errors import DatasetTooLargeError

MAX_DEPTH = 16
"""Folders below a category folder that a scan descends into (robotics packages nest
meshes 3-5 deep); deeper ones are skipped with a :class:`DatasetScanWarning`."""

MAX_FILES = 1_000_000
"""Files and folders one scan of a category folder may visit (ShapeNetCore v2's largest
synset holds about 8,000 models; its whole tree, textures included, about 700,000 entries)
before it stops with :class:`~beo_bench.errors.DatasetTooLargeError`; ``$BEO_BENCH_MAX_FILES``
raises it."""

MAX_FILES_ENV = "BEO_BENCH_MAX_FILES"


class DatasetScanWarning(UserWarning):
    """A part of a dataset folder that a scan skipped: a link out of the root, a folder link
    below a category folder, a folder beyond :data:`MAX_DEPTH`, a name that is not valid
    UTF-8."""


def max_files() -> int:
    """The scan bound: ``$BEO_BENCH_MAX_FILES`` when it is a positive whole number, else
    :data:`MAX_FILES`."""
    text = os.environ.get(MAX_FILES_ENV, "").strip()
    return int(text) if text.isdigit() and int(text) > 0 else MAX_FILES


def inside(path: Path, root: Path) -> bool:
    """Whether ``path``, its links resolved, lies in ``root`` (its links resolved too)."""
    try:
        return Path(os.path.realpath(path)).is_relative_to(os.path.realpath(root))
    except (OSError, ValueError):
        return False


@functools.lru_cache(maxsize=4096)
def warn_outside(path: str, root: str) -> None:
    """Warn once per process about a link out of the root (lru_cache: a dataset is scanned
    by several layouts and commands, and one line per link is enough)."""
    try:
        target = os.readlink(path)
    except OSError:
        target = "?"
    warnings.warn(
        f"{path} is a symbolic link to {target}, outside the dataset root {root}: skipped "
        f"(links out of the root are never followed; copy the files in to use them)",
        DatasetScanWarning,
        stacklevel=2,
    )


def walk_files(top: Path, root: Path, suffixes: tuple[str, ...]) -> Iterator[Path]:
    """The files under ``top`` (a folder of the dataset at ``root``, resolved) whose suffix
    is one of ``suffixes`` (lower case), hidden files and folders skipped, in sorted order,
    without following links out of ``root`` (see the module docstring)."""
    limit = max_files()
    visited = 0
    seen: set[str] = set()
    stack: list[tuple[Path, int]] = [(top, 0)]
    found: list[Path] = []
    while stack:
        folder, depth = stack.pop()
        real = os.path.realpath(folder)
        if real in seen:  # a link loop, or a folder linked twice: its files once
            continue
        seen.add(real)
        try:
            entries = sorted(os.scandir(folder), key=lambda e: e.name)
        except OSError:
            continue  # unreadable: as before, a folder that cannot be listed has no files
        for e in entries:
            visited += 1
            if visited > limit:
                raise DatasetTooLargeError(
                    f"{top}: more than {limit:,} files and folders in one category folder "
                    f"(the dataset scan's limit): point --objects at the dataset's own folder, "
                    f"or set {MAX_FILES_ENV}=N to raise the limit"
                )
            if e.name.startswith(".") or not valid_name(e.path):
                continue
            path = Path(e.path)
            if e.is_symlink() and not inside(path, root):
                warn_outside(e.path, str(root))
                continue
            try:
                is_dir = e.is_dir()
            except OSError:
                continue
            if is_dir and e.is_symlink():
                warn_folder_link(e.path, str(top))
                continue
            if is_dir:
                if depth + 1 > MAX_DEPTH:
                    _warn_deep(e.path)
                else:
                    stack.append((path, depth + 1))
            elif path.suffix.lower() in suffixes and e.is_file():
                found.append(path)
    return iter(sorted(found))


def printable(path: str | Path) -> str:
    """``path`` as text that can be printed and encoded: bytes that are not valid UTF-8
    (held by Python as lone surrogates) as ``\\xff`` escapes."""
    return os.fsencode(path).decode("utf-8", "backslashreplace")


def valid_name(path: str | Path) -> bool:
    """Whether ``path`` is valid UTF-8 (a name that is not cannot be a key, hashed or
    printed); warns once, with the name escaped (:func:`printable`), when it is not."""
    try:
        str(path).encode("utf-8")
    except UnicodeEncodeError:
        _warn_undecodable(printable(path))
        return False
    return True


def subdirs(path: Path) -> list[str]:
    """Names of the visible sub-folders of ``path``, sorted ([] if it cannot be listed); a
    name that is not valid UTF-8 is skipped with a warning."""
    try:
        names = [e.name for e in os.scandir(path) if e.is_dir() and not e.name.startswith(".")]
    except OSError:
        return []
    return sorted(n for n in names if valid_name(path / n))


@functools.lru_cache(maxsize=1024)
def _warn_undecodable(shown: str) -> None:
    warnings.warn(
        f"{shown} has a name that is not valid UTF-8: skipped (rename it, e.g. with `convmv` "
        "or by hand, to use it)",
        DatasetScanWarning,
        stacklevel=3,
    )


@functools.lru_cache(maxsize=4096)
def warn_folder_link(path: str, top: str) -> None:
    """Warn once per process about a folder link inside the root, which a scan skips."""
    try:
        target = os.readlink(path)
    except OSError:
        target = "?"
    real = os.path.realpath(path)
    where = (
        "inside its category folder, whose own scan reaches it"
        if Path(real).is_relative_to(os.path.realpath(top))
        else f"outside its category folder {top}"
    )
    warnings.warn(
        f"{path} is a symbolic link to the folder {target} ({where}): skipped (folder links "
        f"are never followed inside a dataset, so no file is scanned twice or counted in "
        f"another category; copy or move the files in to use them)",
        DatasetScanWarning,
        stacklevel=2,
    )


@functools.lru_cache(maxsize=1024)
def _warn_deep(path: str) -> None:
    warnings.warn(
        f"{path} is more than {MAX_DEPTH} folders below its category folder: not searched "
        f"(the dataset scan's depth limit; move its meshes up)",
        DatasetScanWarning,
        stacklevel=3,
    )
