"""A backend's code digest: what every run records (``run.json``, ``code_digest``) so that
``run --resume`` and ``all`` notice a plugin whose code or options changed since its results
were scored (issue 47)."""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.util
import json
import sys
from pathlib import Path
from typing import Any

from beo_bench.backend import IN_TREE, BackendSpec, entry_point, get_spec

_INSTALL_RECORDS = frozenset({"RECORD", "INSTALLER", "REQUESTED", "direct_url.json"})
"""A distribution's files that say how it was installed, not what it runs (``pip`` writes
them; ``direct_url.json`` holds the path it was installed from): left out of its digest."""


def code_digest(name: str, options: Any) -> str | None:
    """The SHA-256 of the code backend ``name`` runs and of its parsed ``options``, which
    every run records (``run.json``, ``code_digest``) so that ``run --resume`` and ``all``
    notice a plugin that changed since its results were scored (issue 47). Its code is:

    - a plugin's: every file of the distribution that provides its entry point
      (``importlib.metadata``, its ``RECORD``; byte-code and the install records left out),
      and every file of the top-level package (or module) its entry point imports, found
      where Python imports it from: that covers an editable install, whose ``RECORD`` lists
      only a ``.pth`` file, and a distribution with no ``RECORD``;
    - a backend registered in-process, without a distribution (a notebook, a test, a
      script's ``register``): the source file of the module that defines its class; None
      when it has none (defined at an interactive prompt), and nothing can be checked;
    - an in-tree backend's: None. Its code is the package's, which the run's provenance
      names (version and git commit), and its trained model has its own digest
      (``model_digest``).

    Files are hashed by their content and their path inside the distribution or package,
    so the same code installed elsewhere has the same digest."""
    spec = get_spec(name)
    if name in IN_TREE and spec.origin == "in-tree":
        return None
    files = _code_files(name, spec)
    if not files:
        return None
    h = hashlib.sha256()
    for label, path in sorted(files.items()):
        h.update(label.encode() + b"\0")
        try:
            h.update(hashlib.sha256(path.read_bytes()).digest())
        except OSError as e:  # a listed file that is gone or unreadable changes the digest
            h.update(f"unreadable: {type(e).__name__}".encode())
    text = _options_text(options)
    h.update(b"options\0" + text.encode())
    return h.hexdigest()


def _options_text(options: Any) -> str:
    """Parsed options as canonical JSON (a dataclass's fields; anything else by repr)."""
    is_instance = dataclasses.is_dataclass(options) and not isinstance(options, type)
    value = dataclasses.asdict(options) if is_instance else options
    return json.dumps(value, sort_keys=True, default=repr)


def _code_files(name: str, spec: BackendSpec) -> dict[str, Path]:
    """The files whose content is backend ``name``'s code (:func:`code_digest`), by a label
    that does not depend on where they are installed."""
    out: dict[str, Path] = {}
    ep = entry_point(name)
    if ep is None:  # registered in-process: the module that registered it
        where = getattr(sys.modules.get(spec.module), "__file__", None)
        return {f"module {spec.module}": Path(where)} if where else {}
    dist = getattr(ep, "dist", None)
    dist_name = str(getattr(dist, "name", ""))
    for f in (dist.files if dist is not None else None) or []:
        parts = Path(str(f)).parts
        if "__pycache__" in parts or f.name.endswith(".pyc"):
            continue
        if len(parts) > 1 and parts[0].endswith(".dist-info") and f.name in _INSTALL_RECORDS:
            continue
        out[f"dist {dist_name}:{Path(str(f)).as_posix()}"] = Path(str(f.locate()))
    top = ep.module.split(".")[0]
    try:
        found = importlib.util.find_spec(top)
    except (ImportError, ValueError):
        found = None
    if found is not None:
        roots = list(found.submodule_search_locations or [])
        if roots:
            for root in map(Path, roots):
                for p in sorted(root.rglob("*")):
                    if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc":
                        out[f"package {top}:{p.relative_to(root).as_posix()}"] = p
        elif found.origin and Path(found.origin).is_file():
            out[f"module {top}"] = Path(found.origin)
    return out
