"""Model directories: replaced only when this package wrote them, never emptied blindly.

A trained model is a directory of a few known files (``config.json`` naming its ``kind``,
and its arrays or weights). Saving writes the new model to a temporary sibling directory and
renames it into place; the model there before is moved aside first and removed only after
the new one is in place, file by known file. A directory that is not a model this package
wrote (a user's folder reached through a mistaken name, a symbolic link, anything holding
other files) is refused with :class:`CheckpointError` and left as it was.
"""

from __future__ import annotations

import json
import os
import re
import secrets
from pathlib import Path

from beo_bench.errors import CheckpointError

TEMP_FILE = re.compile(r"\.[A-Za-z0-9._-]+\.\d+\.tmp")
"""Temporary files this package writes inside a model directory
(``.<file>.<random>.<pid>.tmp``, :mod:`beo_bench.atomic`; older versions wrote
``.<file>.<pid>.tmp``): a killed writer can leave one behind, and it is ours to replace or
remove."""


def _kind(path: Path) -> str | None:
    """The ``kind`` field of the JSON file ``path``, or None when it has none or is no JSON
    object."""
    try:
        meta = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return meta.get("kind") if isinstance(meta, dict) else None


def not_ours(path: Path, files: frozenset[str], kinds: tuple[str, ...]) -> str | None:
    """Why the existing ``path`` is not a model directory this package wrote, or None when it
    is one: a real directory holding only ``files`` (and our temporary files), that is empty
    or whose ``config.json`` (else ``checkpoint.json``, a training in progress) names one of
    ``kinds``."""
    if path.is_symlink() or not path.is_dir():
        return "it is not a directory" if not path.is_symlink() else "it is a symbolic link"
    names = {p.name for p in path.iterdir()}
    foreign = sorted(n for n in names if n not in files and not TEMP_FILE.fullmatch(n))
    if foreign:
        return f"it holds files no model has ({', '.join(foreign[:5])})"
    stamped = [n for n in ("config.json", "checkpoint.json") if n in names and n in files]
    if names and not stamped:
        return "it has no config.json"
    if stamped and _kind(path / stamped[0]) not in kinds:
        return f"its {stamped[0]} does not name a {' or '.join(kinds)} model"
    return None


def check_replaceable(path: Path, files: frozenset[str], kinds: tuple[str, ...]) -> None:
    """Raise :class:`CheckpointError` unless ``path`` is missing or a model directory this
    package wrote (see :func:`not_ours`), which may then be replaced."""
    if not path.exists() and not path.is_symlink():
        return
    why = not_ours(path, files, kinds)
    if why is not None:
        raise CheckpointError(
            f"refusing to write a model into {path}: {why}, so it is not a {kinds[0]} model "
            "this package wrote and nothing there was changed; choose another model name, "
            "or move that directory away yourself"
        )


def remove_model_dir(path: Path, files: frozenset[str]) -> None:
    """Remove the model directory ``path``, unlinking only ``files`` and our temporary files:
    if anything else appeared in it, that and the directory stay."""
    for p in path.iterdir():
        if (p.name in files or TEMP_FILE.fullmatch(p.name)) and not p.is_dir():
            p.unlink(missing_ok=True)
    try:
        path.rmdir()
    except OSError:
        pass  # not empty: something we did not write is there, so it is not ours to delete


def install(tmp: Path, path: Path, files: frozenset[str], kinds: tuple[str, ...]) -> Path:
    """Move the finished model directory ``tmp`` to ``path``, replacing the model there (if
    :func:`check_replaceable` allows): the old one is renamed aside first and removed only
    once the new one is in place, so a crash leaves one complete model at ``path`` or a
    hidden ``.<name>.*.old`` copy of the previous one beside it."""
    check_replaceable(path, files, kinds)
    old = None
    if path.exists():
        old = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.old")
        os.replace(path, old)
    os.replace(tmp, path)
    if old is not None:
        remove_model_dir(old, files)
    return path
