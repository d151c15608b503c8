"""Names are names: a model, run or cache-kind name never becomes a path of its own.

Everything this package writes or deletes lives under a root it owns (the asset cache, a
run directory) and is addressed there by a *name*. A name with a path separator, ``..``, or
a leading dot could point outside that root or at a hidden temporary file, so it is refused
before any file is touched (see docs/failure-behaviour.md).

A name the user misspelt (a suite, a backend, an option, a flag) is answered with the
closest known one (:func:`did_you_mean`), compared case-insensitively.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable
from pathlib import Path

from beo_bench.errors import InvalidNameError

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._=+-]{0,127}")


def check_name(name: str, what: str = "name") -> str:
    """``name`` if it is a plain name (letters, digits, ``._=+-``, not starting with a dot,
    at most 128 characters, no ``..``); else :class:`InvalidNameError` saying so."""
    if not isinstance(name, str) or not _NAME.fullmatch(name) or ".." in name:
        raise InvalidNameError(
            f"{what} {name!r} is not a plain name: use letters, digits and '._=+-' (no path "
            "separators, no '..', not starting with a dot); it is looked up under the "
            "package's own directory, never as a path"
        )
    return name


def inside(root: Path, name: str, what: str = "name") -> Path:
    """``root / name`` for a plain ``name``, checked to stay inside ``root`` (symlinks
    resolved), so nothing outside ``root`` is ever addressed through it."""
    path = Path(root) / check_name(name, what)
    if not path.resolve().is_relative_to(Path(root).resolve()):
        raise InvalidNameError(f"{what} {name!r} resolves outside {root} (a symbolic link?)")
    return path


def closest(name: str, known: Iterable[str], cutoff: float = 0.6) -> str | None:
    """The name of ``known`` that ``name`` most likely meant, compared case-insensitively
    (``Pose-3DOF`` means ``pose-3dof``; ``--episode`` means ``--episodes``), or None when
    none is close (:func:`difflib.get_close_matches` at ``cutoff``)."""
    by_lower: dict[str, str] = {}
    for k in known:
        by_lower.setdefault(k.lower(), k)
    key = name.lower()
    if key in by_lower:
        return by_lower[key]
    close = difflib.get_close_matches(key, list(by_lower), n=1, cutoff=cutoff)
    return by_lower[close[0]] if close else None


def did_you_mean(name: str, known: Iterable[str], cutoff: float = 0.6) -> str:
    """``"did you mean 'x'? "`` for the closest of ``known`` to ``name`` (:func:`closest`),
    else ``""``: the hint every "unknown name" message puts before its list of names."""
    match = closest(name, known, cutoff)
    return f"did you mean {match!r}? " if match is not None and match != name else ""
